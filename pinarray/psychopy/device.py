"""The pin array as a PsychoPy device: opened through the public API, a stimulus presented at
once or armed to start on the window's next flip, and what was delivered handed back as a
`Touch` for the experiment's data and log.

Defining the class registers it with PsychoPy's `DeviceManager` (`BaseDevice.__init_subclass__`:
its class path and the alias ``"pinarray"``); PsychoPy's plugin manager imports it through the
entry point ``psychopy.hardware: PinArrayDevice`` of pinarray's package.
"""

from __future__ import annotations

from os import PathLike
from types import TracebackType
from typing import Any, ClassVar

from psychopy import clock, logging
from psychopy.hardware.base import BaseDevice

import pinarray
from pinarray.psychopy.timeline import NS_PER_S, Timeline
from pinarray.psychopy.touch import Touch

__all__ = ["PinArrayDevice"]

SIMULATED = "sim://"
"""The simulated array, as `getAvailableDevices` offers it (``sim://?...`` URLs add faults)."""

# Arming compiles the stimulus first (a few ms): the flip chosen lies this much beyond the
# array's lead, so the onset is still `PinArray.lead_ns` ahead once compiled.
COMPILE_MARGIN_S = 0.010
# A flip that passed out of reach while the stimulus was armed (the host stalled) is chosen
# again this many times in all.
ARMING_ATTEMPTS = 3


class PinArrayDevice(BaseDevice, aliases=["pinarray"]):  # type: ignore[call-arg]  # PsychoPy is untyped
    """A protocol's pin array, open: real bus servos on a serial port, or the simulated array.

    Open it directly, as a context manager, or through PsychoPy's device manager
    (``DeviceManager.addDevice("pinarray", "touch", protocol=..., port=...)``), which closes
    it when the experiment ends. Closing rests the pins and switches torque off, however the
    experiment ends.

    Parameters
    ----------
    protocol : str, path-like or pinarray.Protocol
        The protocol file (or one read with `pinarray.load_protocol`): its device section names
        the servos, their calibration and the delivery tolerance; its stimuli are what can be
        presented.
    port : str or None
        The serial device of real bus servos (``/dev/ttyUSB0``), or the I2C bus of a PWM board.
    sim : str or None
        A ``sim://`` URL (faults included: ``sim://?drop=0.01&seed=3``). With neither ``port``
        nor ``sim``: the simulated array. Simulated servos play in real time here, on the
        clock real ones play on, so that their onsets and the screen's flips share one line.
    """

    _ports_in_use: ClassVar[set[str]] = set()

    def __init__(self, protocol: str | PathLike[str] | pinarray.Protocol, port: str | None = None,
                 sim: str | None = None) -> None:
        if not isinstance(protocol, pinarray.Protocol):
            protocol = pinarray.load_protocol(protocol)
        if port is None and sim is None:
            sim = SIMULATED
        self._asked_for = port if port is not None else sim  # as a profile names it
        self._clock = pinarray.MonotonicClock()
        self.array: pinarray.PinArray = pinarray.open_array(protocol, port=port, sim=sim,
                                                            clock=self._clock)
        """The open array (`pinarray.PinArray`): everything the library offers."""
        if port is not None:
            self.portString = port  # where PsychoPy's device manager looks for ports in use
            PinArrayDevice._ports_in_use.add(port)
        for warning in self.array.warnings:
            logging.warning(f"pinarray {self.url}: {warning}")
        logging.exp(f"pinarray {self.url}: open for protocol {protocol.name!r}, pins at rest")

    @property
    def protocol(self) -> pinarray.Protocol:
        """The protocol the array was opened for."""
        return self.array.protocol

    @property
    def url(self) -> str:
        """The serial device of real servos, or the ``sim://`` URL of the simulated array."""
        return self.array.url

    # -- what PsychoPy's device manager asks ------------------------------------------------

    def isSameDevice(self, other: object) -> bool:
        """Whether ``other`` (a device, or a profile from `getAvailableDevices`) is this array:
        the same serial port or ``sim://`` URL."""
        if isinstance(other, PinArrayDevice):
            return other.url == self.url
        if isinstance(other, dict):
            return bool({self.url, self._asked_for} & {other.get("port"), other.get("sim")})
        return False

    @staticmethod
    def getAvailableDevices() -> list[dict[str, Any]]:
        """The arrays this machine can open: each serial port on which bus servos answer a
        PING (`pinarray.find_servo_ports`; ports open in this session are not asked), then the
        simulated array.

        Returns
        -------
        list of dict
            Each a profile PsychoPy's device manager shows: ``deviceName``, and ``port`` or
            ``sim`` (keyword arguments of this class, beside the protocol).
        """
        from psychopy.hardware.manager import DeviceManager
        from serial.tools.list_ports import comports

        busy = PinArrayDevice._ports_in_use | {
            getattr(device, "portString", None) for device in DeviceManager.devices.values()}
        free = [info.device for info in comports() if info.device not in busy]
        profiles: list[dict[str, Any]] = [
            {"deviceName": f"pin array@{found.port}", "port": found.port}
            for found in pinarray.find_servo_ports(free)]
        profiles.append({"deviceName": f"pin array@{SIMULATED}", "sim": SIMULATED})
        return profiles

    # -- presenting ----------------------------------------------------------------------------

    def present(self, stimulus: pinarray.Presentable) -> Touch:
        """Play ``stimulus`` now (`pinarray.PinArray.lead_ns` from the call) and wait until it
        has played.

        Parameters
        ----------
        stimulus : pinarray.PlannedTrial or pinarray.Condition (any paradigm's)
            A trial of the protocol's plan or a condition of its design
            (``pinarray.find_condition(device.protocol, stimulus="rightwards")``).
        """
        timeline = self._timeline()
        delivery = self.array.present(stimulus)
        return Touch(stimulus, delivery.onset_ns, timeline, delivery, _clock_zero_s())

    def armOnFlip(self, stimulus: pinarray.Presentable, win: Any) -> Touch:
        """Arm ``stimulus`` to start on the window's next flip, and return just before it.

        The pins need the stimulus `pinarray.PinArray.lead_ns` (20 ms) ahead, more than a
        frame: so the flip chosen is the first the window will make at least that long (and
        half a frame) from now, as `win.getFutureFlipTime` predicts it, the stimulus is armed
        for that time, and the call returns half a frame before it. Draw the frame that goes
        with the touch and call ``win.flip()`` at once: it is that flip (within half a frame
        of drawing). PsychoPy's stamp of the flip (`win.timeOnFlip`) is kept, so the touch
        tells how far its onset lay from the flip that was actually made.

        Parameters
        ----------
        stimulus : pinarray.PlannedTrial or pinarray.Condition (any paradigm's)
            As for `present`.
        win : psychopy.visual.Window
            The window whose next flip starts the stimulus; its frame period must be known
            (measured when it opened, as PsychoPy does unless ``checkTiming=False``).

        Returns
        -------
        Touch
            Its `Touch.wait` (or `Touch.addData`) gives what was delivered, once played.

        Raises
        ------
        pinarray.PinArrayError
            A stimulus the protocol does not hold, another one still playing, a closed
            device, or a window whose frame period is unknown.
        """
        period_s = win.monitorFramePeriod
        if not period_s:
            raise pinarray.PinArrayError(
                "armOnFlip: the window's frame period is unknown (was it opened with "
                "checkTiming=False?): set win.monitorFramePeriod to 1 / its refresh rate")
        timeline = self._timeline()
        ahead_s = self.array.lead_ns / NS_PER_S + period_s / 2 + COMPILE_MARGIN_S
        for attempt in range(1, ARMING_ATTEMPTS + 1):
            flip_ns = timeline.to_array_ns(win.getFutureFlipTime(targetTime=ahead_s, clock="ptb"))
            try:
                armed = self.array.arm(stimulus, at_ns=flip_ns)
                break
            except pinarray.PinArrayError:
                # The host stalled between choosing the flip and arming for it (a busy
                # machine): choose again; any other refusal is raised as it is.
                still_reachable = flip_ns - self.array.now_ns() >= self.array.lead_ns
                if attempt == ARMING_ATTEMPTS or still_reachable:
                    raise
        touch = Touch(stimulus, flip_ns, timeline, armed, _clock_zero_s())
        win.timeOnFlip(touch._flip_stamp, "flip")
        win.callOnFlip(touch._flipped)
        self._clock.sleep_until_ns(flip_ns - round(period_s / 2 * NS_PER_S))
        return touch

    # -- leaving -------------------------------------------------------------------------------

    def close(self) -> pinarray.SafeStopReport:
        """Wait for a stimulus still playing, then pins to rest, torque off, port closed.
        Safe to call more than once (PsychoPy's device manager calls it at exit)."""
        report = self.array.close()
        PinArrayDevice._ports_in_use.discard(self._asked_for or "")
        logging.exp(f"pinarray {self.url}: closed: {report.describe()}")
        return report

    def __enter__(self) -> PinArrayDevice:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.array.__exit__(kind, error, traceback)  # an error cuts a playing stimulus short
        self.close()

    def _timeline(self) -> Timeline:
        return Timeline.measure(clock.getTime, self.array.now_ns)


def _clock_zero_s() -> float:
    """Where PsychoPy's flip and log clock (`logging.defaultClock`) stands at zero, on its
    time base, in s."""
    return float(logging.defaultClock.getLastResetTime())
