"""A simulated pin array for a lab's own tests, and the assertions such a test needs.

With pinarray installed, pytest loads its plugin (`pinarray.testing.plugin`, registered by
entry point) and every test may ask for the ``simulated_array`` fixture: an `ArrayOpener`
that opens a protocol's array on simulated servos, in virtual time (a 10 s stimulus plays in
a fraction of a second), with faults as ``sim://`` URLs say (``drop=0.1``, ``speed=1500``,
``vanish_after=400``, ``missing=6``), and closes it after the test::

    from pinarray import find_condition
    from pinarray.testing import assert_every_goal_confirmed, assert_pin_moved

    def test_pin_6_makes_its_stroke_at_10_hz(simulated_array):
        array = simulated_array("protocols/localisation.yaml")
        delivery = array.present(find_condition(array.protocol, pin=6, frequency_hz=10))
        assert_every_goal_confirmed(delivery)
        assert_pin_moved(delivery, pin=6, steps=65)

The same array can be opened the way real servos are: ``simulated_array(protocol,
over_serial=True)`` serves the simulated bus on a pseudo-terminal and opens the array on that
serial port, in real time, its stimuli played by a player process of their own, as on a lab's
``/dev/ttyUSB0``: a test then covers the whole path to the pins.

Outside pytest, `ArrayOpener` works as a context manager. Loading this module (as pytest does
at start-up) imports nothing heavy: the array is imported when one is opened.
"""

from __future__ import annotations

from os import PathLike
from types import TracebackType
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from pinarray.api.array import Clock, PinArray
    from pinarray.api.delivery import Delivery
    from pinarray.api.protocols import Protocol
    from pinarray.hardware.feetech.serve import PtyServer

__all__ = ["ArrayOpener", "assert_delivered", "assert_every_goal_confirmed", "assert_left_safe",
           "assert_not_delivered", "assert_pin_moved"]

# How far a measured stroke may lie from the one a test expects, in steps: a pin has arrived
# at its goal within this many steps (pinarray.hardware.motion.ARRIVAL_STEPS).
STROKE_TOLERANCE_STEPS = 3


class ArrayOpener:
    """Opens protocols' arrays on simulated servos and closes every one it opened.

    The ``simulated_array`` fixture is one, closed after its test; elsewhere use it as a
    context manager.
    """

    def __init__(self) -> None:
        self._opened: list[PinArray] = []
        self._servers: list[PtyServer] = []

    def __call__(self, protocol: Protocol | str | PathLike[str], url: str | None = None, *,
                 clock: Clock | None = None, over_serial: bool = False) -> PinArray:
        """Open ``protocol``'s array on simulated servos, pins at rest.

        Parameters
        ----------
        protocol : Protocol, str or path-like
            A protocol, or the path of its file.
        url : str or None
            A ``sim://`` URL with faults (``sim://?drop_writes=0.1&seed=3``: a tenth of the
            goal writes lost; ``sim://?speed=1500``: slow servos; ``sim://?vanish_after=400``:
            the adapter pulled out after 400 packets; ``sim://pca9685?nack_at=20`` for a PWM
            board). None: the protocol's simulated array without faults.
        clock : Clock or None
            None: virtual time (over a serial port: real time, the only time a port has).
        over_serial : bool
            Serve the simulated bus (faults included) on a pseudo-terminal and open the array
            on that serial port, as real servos are opened: in real time, played by a player
            process, the port held. Bus servos only (a PWM board is not on a serial port).

        Returns
        -------
        PinArray
            Closed (pins to rest, torque off) when the opener closes.

        Raises
        ------
        PinArrayError
            A wrong argument (named, as `open_array` names them), a protocol that cannot be
            read, a URL that cannot, a clock given over a serial port, a PWM board's protocol
            over a serial port.
        """
        from pinarray.api import arguments
        from pinarray.api.array import VirtualClock, open_array
        from pinarray.api.protocols import Protocol, load_protocol
        from pinarray.errors import PinArrayError
        from pinarray.protocol.model import HobbyServos

        call = "simulated_array"
        if isinstance(protocol, str | PathLike):
            protocol = load_protocol(protocol)
        if not isinstance(protocol, Protocol):
            arguments.refuse(call, "protocol", "a Protocol (pinarray.load_protocol) or a "
                                               "protocol file's path", protocol)
        over_serial = arguments.flag(call, "over_serial", over_serial)
        url = arguments.sim_for(call, protocol, url, "url")  # as written, before the ids
        clock = arguments.clock(call, clock)
        if not over_serial:
            array = open_array(protocol, sim=url,
                               clock=clock if clock is not None else VirtualClock())
        elif clock is not None:
            raise PinArrayError(f"{call}: over_serial: a serial port plays in real time: give "
                                "no clock")
        elif isinstance(protocol.device.servo, HobbyServos):
            raise PinArrayError(f"{call}: over_serial: protocol {protocol.name!r} drives hobby "
                                "servos on a PCA9685 board, which sits on an I2C bus, not a "
                                "serial port: open it without over_serial")
        else:
            array = open_array(protocol, port=self._serve(protocol, url))
        self._opened.append(array)
        return array

    def _serve(self, protocol: Protocol, url: str | None) -> str:
        """The simulated bus behind a pseudo-terminal: its path."""
        from pinarray.hardware.feetech.faults import parse_sim_url
        from pinarray.hardware.feetech.serve import PtyServer
        from pinarray.player.families import bus_setup, sim_url_for

        config = parse_sim_url(sim_url_for(url, bus_setup(protocol.device).servo_ids))
        server = PtyServer(config).start()
        self._servers.append(server)
        return server.path

    def close(self) -> None:
        """Close every array opened, last first (each rests its pins, however the test went),
        then the simulated buses served for them."""
        try:
            while self._opened:
                self._opened.pop().close()
        finally:
            while self._servers:
                self._servers.pop().stop()

    def __enter__(self) -> ArrayOpener:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()


def assert_delivered(delivery: Delivery) -> None:
    """The stimulus was delivered as scheduled and specified (else: what went wrong)."""
    __tracebackhide__ = True  # pytest shows the test's line, not this one
    _check_delivery("assert_delivered", delivery)
    if not delivery.delivered:
        raise AssertionError(f"expected the stimulus delivered as scheduled, found "
                             f"{delivery.record.summary()}")


def assert_every_goal_confirmed(delivery: Delivery) -> None:
    """Every goal change of the stimulus was confirmed on its servo (as sent, or healed)."""
    __tracebackhide__ = True
    _check_delivery("assert_every_goal_confirmed", delivery)
    record = delivery.record
    if record.missing or record.confirmed + record.healed != record.scheduled:
        raise AssertionError(f"expected all {record.scheduled} goal changes confirmed, found "
                             f"{record.missing} missing: {record.problem}")


def assert_not_delivered(delivery: Delivery, because: str = "") -> None:
    """The stimulus was not delivered as scheduled, for a reason whose words hold ``because``."""
    __tracebackhide__ = True
    _check_delivery("assert_not_delivered", delivery)
    if delivery.delivered:
        raise AssertionError(f"expected the stimulus not delivered, found "
                             f"{delivery.record.summary()}")
    if because not in delivery.problem:
        raise AssertionError(f"expected the stimulus not delivered because {because!r}, found: "
                             f"{delivery.problem}")


def assert_pin_moved(delivery: Delivery, pin: int, steps: int, *,
                     tolerance_steps: int = STROKE_TOLERANCE_STEPS) -> None:
    """``pin`` made a stroke of ``steps`` (its smallest cycle's, as measured), within
    ``tolerance_steps``."""
    __tracebackhide__ = True
    _check_delivery("assert_pin_moved", delivery)
    if isinstance(pin, bool) or not isinstance(pin, int) or isinstance(steps, bool) \
            or not isinstance(steps, int):
        _refuse("assert_pin_moved", "pin and steps", "whole numbers (int)", (pin, steps))
    measured = [s for s in delivery.strokes if s.pin == pin]
    if not measured or measured[0].achieved_steps is None:
        moved = ", ".join(str(s.pin) for s in delivery.strokes if s.measured) or "none"
        raise AssertionError(f"expected pin {pin} to move {steps} steps, found no stroke "
                             f"measured for it (pins measured: {moved})")
    stroke = measured[0]
    achieved = stroke.achieved_steps
    if achieved is None or abs(achieved - steps) > tolerance_steps:
        raise AssertionError(
            f"expected pin {pin} to move {steps} steps (within {tolerance_steps}), found "
            f"{achieved} of {stroke.commanded_steps} commanded (median {stroke.median_steps}, "
            f"{stroke.short_cycles} of {stroke.cycles} cycles short)")


def assert_left_safe(array: PinArray) -> None:
    """Closing ``array`` (or its having been closed) left every servo confirmed at rest and
    released (torque off)."""
    __tracebackhide__ = True
    from pinarray.api.array import PinArray

    if not isinstance(array, PinArray):
        _refuse("assert_left_safe", "array", "a PinArray", array)
    report = array.close()
    if not report.complete or sorted(report.at_rest_ids) != sorted(report.released_ids):
        raise AssertionError(f"expected every servo at rest and released, found "
                             f"{report.describe()}")


def _check_delivery(call: str, value: object) -> None:
    from pinarray.api.delivery import Delivery

    if not isinstance(value, Delivery):
        _refuse(call, "delivery", "a Delivery (what PinArray.present gave)", value)


def _refuse(call: str, name: str, expected: str, value: object) -> NoReturn:
    from pinarray.api.arguments import refuse

    refuse(call, name, expected, value)
