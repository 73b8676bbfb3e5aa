"""The stimulator a session drives: a connected servo bus (real or simulated) and its clock.

One place decides hardware vs simulation and real vs virtual time for `play`, `batch` and the
TUI. However a `Rig` is left (normal close, exception, Ctrl-C), pins go to rest and torque
goes off where the bus still answers.
"""

from __future__ import annotations

from pinarray.clock import Clock, MonotonicClock, ScaledClock, VirtualClock
from pinarray.errors import PinArrayError
from pinarray.protocol import NS_PER_S, Protocol

SIM_DEFAULT = "sim://"


def choose_clock(port: str | None, time_scale: float | None) -> Clock:
    """Real servos run in real time; simulated ones in virtual time (scale 0/None) or scaled."""
    if port:
        if time_scale not in (None, 1.0):
            raise PinArrayError("real servos play in real time: --time-scale must be 1")
        return MonotonicClock()
    if not time_scale:
        return VirtualClock()
    return ScaledClock(time_scale)


def sim_url_for(url: str | None, servo_ids: tuple[int, ...]) -> str:
    """A ``sim://`` URL that simulates exactly the protocol's servo ids unless it names its own."""
    from pinarray.bus.faults import is_sim_url

    url = url or SIM_DEFAULT
    if not is_sim_url(url):
        raise PinArrayError(f"--sim expects a sim:// URL, found {url!r}")
    if "ids=" not in url:
        url += ("&" if "?" in url else "?") + "ids=" + ",".join(map(str, servo_ids))
    return url


class Rig:
    """A connected pin array for one protocol's device.

    Parameters
    ----------
    protocol : Protocol
        Its device section gives servo ids, rest positions, limits, speed and baud rate.
    port : str or None
        A serial device of real servos; None for the simulator.
    sim_url : str or None
        A ``sim://`` URL (faults etc.) when ``port`` is None.
    clock : Clock
        Shared by the bus, the player and the session.
    """

    def __init__(self, protocol: Protocol, port: str | None, sim_url: str | None, clock: Clock):
        from pinarray.bus.base import servo_setup_from_device
        from pinarray.bus.transport import open_bus

        self.protocol = protocol
        self.clock = clock
        self.setup = servo_setup_from_device(protocol.device)
        self.url = port or sim_url_for(sim_url, self.setup.servo_ids)
        self.bus = open_bus(self.url, self.setup, clock, baud_rate=protocol.device.servo.baud_rate)
        self.warnings = list(self.bus.warnings)
        self.reports: list = []
        self._released = False
        try:
            self.bus.move_to_rest()
        except BaseException:
            self.close()  # torque is on by now: nobody else holds this rig to release it
            raise

    def present(self, schedule) -> int:
        """Play one trial and return its onset (clock ns); pins then hold at rest."""
        from pinarray.player import play_trial

        if self._released:
            # A fault released torque; the handshake turns it back on, checking every servo.
            self.bus.connect(self.setup)
            self._released = False
        try:
            report = play_trial(self.bus, schedule.targets, self.clock, release_at_end=False)
        except PinArrayError:
            self._released = True
            raise
        self.reports.append(report)
        return report.onset_ns

    def test_pin(self, pin: int, cycles: int = 3, frequency_hz: int = 2) -> None:
        """Wiggle one pin (its calibrated widths, the seed's pulse shape) to check the hardware."""
        from fractions import Fraction

        from pinarray.protocol import PinDrive, Train
        from pinarray.schedule import compile_drives

        calibration = self.protocol.device.calibration(pin)
        widths = sorted(w for w, _ in calibration.positions_by_width_ns)
        train = Train(Fraction(frequency_hz), cycles * NS_PER_S // frequency_hz,
                      up_width_ns=widths[-1], down_width_ns=widths[0])
        self.present(compile_drives([PinDrive(pin, train)], self.protocol.device))

    def telemetry(self):
        return self.bus.read_telemetry(self.setup.servo_ids)

    def close(self):
        """Pins to rest, torque off, port closed. Returns the `SafeStopReport`."""
        try:
            return self.bus.rest_and_release()
        finally:
            self.bus.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
