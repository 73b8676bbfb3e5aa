"""Which driver plays a protocol's device: one entry per family of servo.

Two families: Feetech STS bus servos (`pinarray.hardware.feetech`, a device section with
``servo:`` settings and ``servo_ids``), and hobby PWM servos on a PCA9685 board
(`pinarray.hardware.pca9685`, a device section with ``board:`` and ``channels``). Each
implements `pinarray.hardware.driver.ArrayDriver` in its own package; here is how its setup
follows from the device section, and how it opens a port or its simulator. The rig, the
session, the journal and the UI stay as they are.
"""

from __future__ import annotations

from fractions import Fraction
from typing import TYPE_CHECKING

from pinarray.clock import Clock
from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.driver import ArrayDriver, ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.faults import SIM_DEFAULT, is_sim_url
from pinarray.player.simulators import SimulatedArrays
from pinarray.protocol import (
    Device,
    HobbyServos,
    Pca9685Board,
    Protocol,
    ServoSettings,
)
from pinarray.protocol.device import SIMULATED_BOARD_PORT
from pinarray.units import NS_PER_US

if TYPE_CHECKING:
    from pinarray.hardware.pca9685.driver import Pca9685Array
    from pinarray.hardware.pca9685.i2c import I2cLink
    from pinarray.hardware.pca9685.timing import PwmSetup


def sts_servos(device: Device) -> ServoSettings:
    """The STS settings of a device of bus servos; a PWM device is refused, saying so."""
    if isinstance(device.servo, HobbyServos):
        raise PinArrayError(
            "this protocol's device is hobby servos on a PCA9685 board (device: board:), not "
            "STS bus servos: use `pinarray pwm ...`")
    return device.servo


def servo_setups(device: Device) -> tuple[ServoSetup, ...]:
    """Each pin's servo (bus id or board channel), rest and calibrated limits."""
    return tuple(
        ServoSetup(servo_id=c.servo_id, pin=c.pin, rest_steps=c.rest_steps,
                   min_steps=c.min_steps, max_steps=c.max_steps)
        for c in device.pins
    )


def bus_setup(device: Device) -> BusSetup:
    """What the STS handshake checks and sets, from a protocol's device section."""
    from pinarray.hardware.feetech.models import servo_model

    settings = sts_servos(device)
    servos = servo_setups(device)
    try:
        model = servo_model(settings.model)
    except PinArrayError as error:
        raise BusError(f"device: {error}") from None
    return BusSetup(servos=servos, model_number=model.model_number,
                    speed_steps_per_s=settings.speed_steps_per_s,
                    acceleration_register=settings.acceleration_register)


def sim_url_for(url: str | None, servo_ids: tuple[int, ...]) -> str:
    """A ``sim://`` URL that simulates exactly the protocol's servo ids unless it names its own."""
    url = url or SIM_DEFAULT
    if not is_sim_url(url):
        raise PinArrayError(f"--sim expects a sim:// URL, found {url!r}")
    if "ids=" not in url:
        url += ("&" if "?" in url else "?") + "ids=" + ",".join(map(str, servo_ids))
    return url


def pwm_setup(device: Device) -> PwmSetup:
    """What a PCA9685 array plays with, from a protocol's device section."""
    from pinarray.hardware.pca9685.timing import PwmSetup

    servos = device.servo
    if not isinstance(servos, HobbyServos):
        raise PinArrayError("this protocol's device is STS bus servos, not a PWM board")
    board = servos.board
    return PwmSetup(servo_setups(device), board.address, board.osc_hz, board.pwm_hz,
                    device.delivery_tolerance_ns)


def board_refusals(protocol: Protocol) -> tuple[str, ...]:
    """What a PWM board would refuse to play of the protocol's conditions (none for bus
    servos): each condition compiled and planned on the board as playing it would
    (`pinarray.hardware.pca9685.timing.plan_trial`: drift past the tolerance, two changes of
    a pin in one period, a width the period cannot hold). One line per stimulus refused, with
    the pins it was refused on and the first pin's reason. Pure: no I/O."""
    if not isinstance(protocol.device.servo, HobbyServos):
        return ()
    from pinarray.hardware.pca9685.registers import COUNTS, period_ns, prescale_for
    from pinarray.hardware.pca9685.timing import plan_trial
    from pinarray.protocol.drives import trial_drives
    from pinarray.schedule import compile_drives

    setup = pwm_setup(protocol.device)
    hold_ns = period_ns(setup.osc_hz, prescale_for(setup.osc_hz, Fraction(setup.pwm_hz)))
    too_wide = [s.pin for s in setup.servos
                if max(s.max_steps, s.rest_steps) * NS_PER_US >= hold_ns * (COUNTS - 1) / COUNTS]
    if too_wide:  # the board holds rest at pwm_hz between trials: no pulse may fill a period
        return (f"device: board: pwm_hz {setup.pwm_hz} gives a period of "
                f"{float(hold_ns) / 1e6:.3f} ms, too short for the widths of pins "
                f"{_pin_list(too_wide)} (their rest or limits_us); lower pwm_hz",)
    refused: dict[str, tuple[list[int], str]] = {}  # stimulus -> (pins, first reason)
    for condition in protocol.design.conditions:
        schedule = compile_drives(trial_drives(protocol, condition), protocol.device)
        try:
            plan_trial(setup, schedule.targets, schedule.pulses)
        except PinArrayError as refusal:
            name, pin = protocol.design.paradigm.grouped(condition)
            pins, _ = refused.setdefault(name, ([], str(refusal)))
            if pin is not None:
                pins.append(pin)
    return tuple(f"{name}{f' on pins {_pin_list(pins)}' if len(pins) > 1 else ''}: {reason}"
                 for name, (pins, reason) in refused.items())


def _pin_list(pins: list[int]) -> str:
    return ", ".join(map(str, pins))


def board_sim_url(url: str | None, board: Pca9685Board) -> str:
    """A ``sim://pca9685`` URL for the protocol's board: its address, and its oscillator as
    the protocol states it, unless the URL names its own."""
    from pinarray.hardware.pca9685.sim import is_pca9685_url

    if url is None or url == SIM_DEFAULT:
        url = SIMULATED_BOARD_PORT
    if not is_pca9685_url(url):
        raise PinArrayError(f"--sim: a PWM board is simulated by a sim://pca9685 URL (e.g. "
                            f"'sim://pca9685?osc_hz=25300000'), found {url!r}")
    extra = []
    if "address=" not in url:
        extra.append(f"address=0x{board.address:02x}")
    if "osc_hz=" not in url:
        extra.append(f"osc_hz={board.osc_hz}")
    if extra:
        url += ("&" if "?" in url else "?") + "&".join(extra)
    return url


def open_array(device: Device, port: str | None, sim_url: str | None,
               clock: Clock, wire_log: str | None = None,
               simulators: SimulatedArrays | None = None) -> ArrayDriver:
    """The device's servos on ``port`` (or simulated, as ``sim_url`` says), not yet checked.

    ``wire_log``: a file for every message on the wire, as a logic analyser decodes it (PWM
    boards: I2C). ``simulators``: simulated arrays kept from earlier connections; simulated
    bus servos are found there (as they were left) or kept there. The caller runs the
    handshake (`ArrayDriver.check_servos`, then `hold`) and closes the driver if it fails.
    """
    if isinstance(device.servo, HobbyServos):
        return open_board(device, port, sim_url, clock, wire_log)
    if wire_log is not None:
        raise PinArrayError("--i2c-log: this protocol's servos are STS bus servos (serial, no "
                            "I2C); the log is for a PCA9685 board's protocol")
    from pinarray.hardware.feetech.transport import open_bus

    setup = bus_setup(device)
    url = port or sim_url_for(sim_url, setup.servo_ids)
    kept = None
    if simulators is not None and is_sim_url(url):  # only a sim:// URL's simulator is kept
        # Imported for it alone: a real port (or one sim-serve serves) needs no simulator.
        from pinarray.hardware.feetech.sim import SimBus

        kept = simulators.find(url, SimBus)
    bus = open_bus(url, None, clock, baud_rate=sts_servos(device).baud_rate, sim=kept)
    if simulators is not None and bus.sim is not None:
        simulators.keep(url, bus.sim)
    bus.setup = setup
    return bus


def open_board(device: Device, port: str | None, sim_url: str | None, clock: Clock,
               wire_log: str | None = None) -> Pca9685Array:
    """A PWM device's board on the I2C bus ``port`` (or simulated), not yet checked."""
    from pinarray.hardware.pca9685.driver import Pca9685Array

    servos = device.servo
    if not isinstance(servos, HobbyServos):
        raise PinArrayError("this protocol's device is STS bus servos, not a PWM board")

    setup = pwm_setup(device)
    log = None
    if wire_log is not None:
        from pinarray.hardware.pca9685.i2c_log import I2cLog

        log = I2cLog(wire_log)
    try:
        if port:
            from pinarray.hardware.pca9685.smbus_link import SmbusLink

            link: I2cLink = SmbusLink(port, clock)
        else:
            from pinarray.hardware.pca9685.sim import SimI2cLink

            link = SimI2cLink(board_sim_url(sim_url, servos.board), clock)
    except BaseException:
        if log is not None:
            log.close()
        raise
    return Pca9685Array(link, setup, clock, servos.speed_us_per_s, log, wire_log)
