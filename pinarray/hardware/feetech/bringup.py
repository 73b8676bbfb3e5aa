"""Bring-up of new servos: renumber them, lower their return delay, let go (finding them is
`pinarray.hardware.feetech.scan`).

A lab's first hour with new STS servos: each ships answering at id 1, so they are connected
and renumbered one at a time; their return delay (factory 500 us) is lowered so that every
read-back is quicker; and each pin's rest and "up" positions are found by moving its horn in
small steps (`pinarray.hardware.feetech.jog`). Every function here takes a `FeetechBus` opened without
the playback handshake (which would switch torque on everywhere) and returns values; the
commands (`pinarray servos ...`) print them.

EEPROM is written only by `set_id` and by `set_return_delay`, each through the driver's
explicitly named EEPROM methods. On an STS servo a value written to EEPROM is in force at
once; the LOCK register (55) decides whether it survives a power cycle (0: saved, 1: lost at
power-off), so a return delay lowered "until power-off" is written with LOCK at 1.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.driver import PortLost, SafeStopReport
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.feetech import FeetechBus
from pinarray.hardware.feetech.registers import MAX_SERVO_ID, Register

# The return delay register holds 2 us units, 0-254.
RETURN_DELAY_UNIT_US = 2
MAX_RETURN_DELAY_US = 254 * RETURN_DELAY_UNIT_US
# A sweep waits this long for each id's PING answer unless told otherwise: a pseudo-terminal
# or a USB adapter at a 1 ms latency timer answers well within it.
SWEEP_TIMEOUT_NS = 10_000_000


@dataclass(frozen=True)
class ServoFailure:
    """A servo a command could not do its part on (or read, in a scan), and why."""

    servo_id: int
    problem: str


def sweep_timeout_ns(bus: FeetechBus) -> int:
    """How long a sweep waits for each id by default: the adapter's latency timer + 2 ms when it
    can be read (1 ms timer: 3 ms), else `SWEEP_TIMEOUT_NS`."""
    timer_ms = bus.link.latency.timer_ms
    return SWEEP_TIMEOUT_NS if timer_ms is None else (timer_ms + 2) * 1_000_000


# -- renumbering ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Renumbered:
    """A servo that now answers at ``new_id`` (saved in its EEPROM) and no longer at ``old_id``.

    ``acknowledged`` is False when the ID write's status packet did not come back as asked
    (some firmware answers from the new id) and the change was confirmed by pinging instead.
    """

    old_id: int
    new_id: int
    model_number: int
    acknowledged: bool


def check_servo_id(servo_id: int, what: str) -> int:
    """``servo_id`` if a servo can be given it (0-252), else `PinArrayError` naming ``what``."""
    if not 0 <= servo_id <= MAX_SERVO_ID:
        raise PinArrayError(f"{what}: expected a servo id from 0 to {MAX_SERVO_ID}, "
                            f"found {servo_id}")
    return servo_id


def set_id(bus: FeetechBus, old_id: int, new_id: int) -> Renumbered:
    """Give the servo at ``old_id`` the id ``new_id``, for good, and check that it took.

    Torque off, LOCK (55) = 0, ID (5) = ``new_id``, LOCK = 1 at the new id; then the servo
    must answer at ``new_id``, read its ID register as ``new_id`` and LOCK as 1, and nothing
    may answer at ``old_id``. Refused, before anything is written, when ``new_id`` already
    answers: two servos on one id garble each other's answers.

    Raises
    ------
    BusError
        Naming the ids and registers of whatever did not go as described.
    """
    check_servo_id(old_id, "OLD")
    check_servo_id(new_id, "NEW")
    if old_id == new_id:
        raise PinArrayError(f"set-id: OLD and NEW are both {old_id}; nothing to change")
    model = bus.ping(old_id)
    if model is None:
        raise BusError(
            f"set-id: no servo answers at id {old_id} on {bus.port_name}; `pinarray servos "
            "scan` lists who answers (two new servos on the bus both answer at id 1 and garble "
            "each other: connect one at a time)")
    taken = bus.ping(new_id)
    if taken is not None:
        raise BusError(
            f"set-id: servo id {new_id} is already taken (a servo of model {taken} answers "
            f"there); refusing to give servo {old_id} the same id. Choose a free id, or "
            f"renumber servo {new_id} first")
    try:
        # Two servos on one id answer a PING in the same bytes, which reads as one answer;
        # their positions differ, and answers that differ garble each other.
        bus.read(old_id, Register.PRESENT_POSITION)
    except PortLost:
        raise
    except BusError:
        raise BusError(
            f"set-id: a servo answers a PING at id {old_id}, but reading its PRESENT_POSITION "
            f"(address 56) fails: probably several servos share id {old_id} and their answers "
            "garble each other; connect one new servo at a time") from None
    level, _ = bus.read(old_id, Register.STATUS_RETURN_LEVEL)
    if level[0] == 0:
        raise BusError(
            f"servo {old_id}: STATUS_RETURN_LEVEL (address 8) is 0, so it acknowledges no "
            "write and its renumbering could not be checked; set it to 1 with the vendor's "
            "tool first")
    bus.write(old_id, Register.TORQUE_ENABLE, 0)
    bus.unlock_eeprom(old_id)
    try:
        bus.write_eeprom(old_id, Register.ID, new_id)
        acknowledged = True
    except PortLost:
        raise
    except BusError:
        acknowledged = False  # maybe answered from its new id: the pings below tell
    at_new = bus.ping(new_id)
    at_old = bus.ping(old_id)
    if at_new is None:
        if at_old is not None:
            _relock(bus, old_id)
            raise BusError(
                f"servo {old_id}: writing ID (EEPROM address 5) = {new_id} did not take: it "
                f"still answers at id {old_id} and nothing answers at {new_id}")
        raise BusError(
            f"servo {old_id}: after writing ID (EEPROM address 5) = {new_id} nothing answers "
            f"at id {old_id} or {new_id}; power it off and on, then `pinarray servos scan`")
    bus.lock_eeprom(new_id)
    delay_ns = bus.link.return_delay_ns.pop(old_id, None)
    if delay_ns is not None:
        bus.link.return_delay_ns[new_id] = delay_ns
    written, _ = bus.read(new_id, Register.ID)
    lock, _ = bus.read(new_id, Register.LOCK)
    if written[0] != new_id or lock[0] != 1:
        raise BusError(
            f"servo {new_id}: expected ID (address 5) = {new_id} and LOCK (address 55) = 1 "
            f"after renumbering, found ID {written[0]} and LOCK {lock[0]}")
    if at_old is not None:
        raise BusError(
            f"servo {old_id} now answers at id {new_id}, but something still answers at id "
            f"{old_id}: another servo shares that id (connect one new servo at a time)")
    return Renumbered(old_id, new_id, at_new, acknowledged)


# Writes of RETURN_DELAY_TIME whose acknowledgement was lost, tried again after a read-back.
RETURN_DELAY_WRITES = 3


def _write_return_delay(bus: FeetechBus, servo_id: int, delay_us: int) -> bytes:
    """Write RETURN_DELAY_TIME and read it back: the register's value after the write.

    A write whose acknowledgement was lost (a busy host) may have been taken: the read-back
    tells, and the same value is written again only if it was not (the write is idempotent).
    """
    register = Register.RETURN_DELAY_TIME
    for attempt in range(1, RETURN_DELAY_WRITES + 1):
        try:
            bus.write_eeprom(servo_id, register, delay_us // RETURN_DELAY_UNIT_US)
        except PortLost:
            raise
        except BusError:
            if attempt == RETURN_DELAY_WRITES:
                raise
        # The servo answers the read-back after its new delay: plan for it.
        bus.note_return_delay(servo_id, delay_us)
        after, _ = bus.read(servo_id, register)
        if after[0] * RETURN_DELAY_UNIT_US == delay_us:
            break
    return after


def _relock(bus: FeetechBus, servo_id: int) -> None:
    try:
        bus.lock_eeprom(servo_id)
    except PortLost:
        raise
    except BusError:
        pass  # the error being raised says more than this one would


# -- return delay -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ReturnDelayChange:
    """One servo's return delay before and after, and whether the new one survives power-off."""

    servo_id: int
    before_us: int
    after_us: int
    saved: bool


def check_return_delay_us(delay_us: int) -> int:
    """``delay_us`` if the register can hold it (0-508 us, even), else `PinArrayError`."""
    if not 0 <= delay_us <= MAX_RETURN_DELAY_US or delay_us % RETURN_DELAY_UNIT_US:
        raise PinArrayError(
            f"return delay: expected an even number of microseconds from 0 to "
            f"{MAX_RETURN_DELAY_US} (RETURN_DELAY_TIME, address 7, counts 2 us), found {delay_us}")
    return delay_us


def set_return_delay(bus: FeetechBus, servo_ids: Sequence[int], delay_us: int, save: bool
                     ) -> tuple[tuple[ReturnDelayChange, ...], tuple[ServoFailure, ...]]:
    """Set RETURN_DELAY_TIME (EEPROM address 7) of each servo, read back.

    Parameters
    ----------
    delay_us : int
        The new delay in microseconds (even, 0-508); 0 answers at once.
    save : bool
        False: LOCK (55) is set to 1 first, so the value is in force at once and lost at
        power-off. True: LOCK 0, write, LOCK 1: the value is saved in EEPROM.

    Returns
    -------
    (changes, failures)
        One `ReturnDelayChange` per servo that took it; a `ServoFailure` per servo that did
        not answer or did not take it (the others are still changed).
    """
    check_return_delay_us(delay_us)
    changes, failures = [], []
    for servo_id in servo_ids:
        try:
            changes.append(_set_return_delay(bus, servo_id, delay_us, save))
        except PortLost:
            raise
        except BusError as problem:
            failures.append(ServoFailure(servo_id, str(problem)))
    return tuple(changes), tuple(failures)


def _set_return_delay(bus: FeetechBus, servo_id: int, delay_us: int, save: bool
                      ) -> ReturnDelayChange:
    register = Register.RETURN_DELAY_TIME
    before, _ = bus.read(servo_id, register)
    if save:
        bus.unlock_eeprom(servo_id)
    else:
        bus.lock_eeprom(servo_id)  # a factory servo powers on unlocked: its writes would stay
    try:
        after = _write_return_delay(bus, servo_id, delay_us)
    finally:
        if save:
            _relock(bus, servo_id)
    if after[0] * RETURN_DELAY_UNIT_US != delay_us:
        raise BusError(f"servo {servo_id}: wrote {register.name} (address {register.address}) "
                       f"= {delay_us} us, read back {after[0] * RETURN_DELAY_UNIT_US} us")
    return ReturnDelayChange(servo_id, before[0] * RETURN_DELAY_UNIT_US, delay_us, save)


# -- who is connected --------------------------------------------------------------------------


def silent_ids(bus: FeetechBus, servo_ids: Sequence[int],
               timeout_ns: int = SWEEP_TIMEOUT_NS) -> tuple[int, ...]:
    """Those of ``servo_ids`` that answer neither of two PINGs: not connected (or not powered,
    or at another baud rate), left out before a command rather than waited for in it.

    The first PING waits at most ``timeout_ns``, the second four times longer (a busy host
    can hold an answer past a quiet host's wait). An exchange with a servo that is not there
    costs the link's every retry, about 3 s on an adapter whose latency is unknown; these
    pings about 50 ms.
    """
    return tuple(servo_id for servo_id in servo_ids
                 if bus.ping_within(servo_id, timeout_ns) is None
                 and bus.ping_within(servo_id, 4 * timeout_ns) is None)


# -- making pins safe -------------------------------------------------------------------------


def torque_off(bus: FeetechBus, servo_ids: Sequence[int]
               ) -> tuple[tuple[int, ...], tuple[ServoFailure, ...]]:
    """TORQUE_ENABLE (40) = 0 on each servo; the ids that acknowledged, and those that did not."""
    released, failures = [], []
    for servo_id in servo_ids:
        try:
            bus.write(servo_id, Register.TORQUE_ENABLE, 0)
            released.append(servo_id)
        except PortLost:
            raise
        except BusError as problem:
            failures.append(ServoFailure(servo_id, str(problem)))
    return tuple(released), tuple(failures)


def rest(bus: FeetechBus, setup: BusSetup) -> SafeStopReport:
    """Every servo of ``setup`` to its rest position at the setup's speed, then torque off.

    Unlike the playback handshake, servos that do not answer do not stop the others: they are
    reported silent. Never raises for a silent servo.
    """
    bus.setup = setup
    for servo in setup.servos:
        try:
            bus.write(servo.servo_id, Register.ACCELERATION, setup.acceleration_register)
            bus.write(servo.servo_id, Register.GOAL_SPEED, setup.speed_steps_per_s)
        except PortLost:
            break  # rest_and_release says so
        except BusError:
            continue
    return bus.rest_and_release()
