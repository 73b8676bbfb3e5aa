"""The STS connect handshake: every servo checked before anything moves, then torque on.

`check` only reads (ids, models, angle limits, return delays), so that the player process
that guards the servos can be started before `hold` gives them torque.

`hold_again` turns torque back on after a safe stop (a stop, a cut stimulus) in a few
exchanges of the whole bus instead of the handshake's per-servo ones: the next stimulus after
a stop starts when it is due. The handshake runs again only where those exchanges say it must.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinarray.errors import BusError
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech import packets
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.link import Expected, WireLost
from pinarray.hardware.feetech.registers import (
    Register,
    decode_position,
    encode_position,
    from_bytes,
    to_bytes,
)
from pinarray.units import NS_PER_US

if TYPE_CHECKING:
    from pinarray.hardware.feetech.feetech import FeetechBus


# Torque enable (40) .. goal speed (46-47): what holding a pin sets, read back in one piece.
HELD_LENGTH = Register.GOAL_SPEED.address + Register.GOAL_SPEED.size - Register.TORQUE_ENABLE.address


def check(bus: FeetechBus, setup: BusSetup) -> None:
    """Ping every expected id, check models, angle limits and return delays. Reads only.

    Nothing moves and torque stays as it was, so a process that must guard the servos
    (the player process) can be started between this and `hold`.

    Raises
    ------
    BusError
        Naming every missing id and every id with the wrong model, in one message.
    """
    bus.setup = setup
    found = _ping_all(bus, setup.servo_ids)
    missing = sorted(i for i, model in found.items() if model is None)
    wrong = sorted(
        (i, model) for i, model in found.items() if model not in (None, setup.model_number)
    )
    if missing or wrong:
        problems = []
        if missing:
            ids = ", ".join(map(str, missing))
            problems.append(f"no answer from servo id(s) {ids}")
        if wrong:
            found_text = ", ".join(f"id {i} reports model {m}" for i, m in wrong)
            problems.append(f"expected model {setup.model_number}, but {found_text}")
        answered = sorted(set(found) - set(missing))
        raise BusError(
            f"servo handshake on {bus.port_name}: " + "; ".join(problems)
            + f" (answered: {', '.join(map(str, answered)) or 'none'})"
        )
    for servo in setup.servos:
        delay, _ = bus.read(servo.servo_id, Register.RETURN_DELAY_TIME)
        bus.link.return_delay_ns[servo.servo_id] = delay[0] * 2 * NS_PER_US
        _check_angle_limits(bus, servo)


def _ping_all(bus: FeetechBus, servo_ids: tuple[int, ...]) -> dict[int, int | None]:
    """Each id's model number, None for a servo that never answered.

    In rounds, each waiting longer than the one before (`FeetechBus.ping_attempt`), asking
    only those still silent: a reply lost once is asked for again, as the vendor's SDK
    users learnt to. Where nothing has answered after two rounds, no servo is there (power
    off, the wrong adapter): the error comes within seconds, naming them all, rather than
    after every id's longest wait.
    """
    found: dict[int, int | None] = dict.fromkeys(servo_ids)
    for attempt in range(bus.retries + 1):
        silent = [i for i, model in found.items() if model is None]
        if not silent or (attempt >= 2 and len(silent) == len(servo_ids)):
            break
        for servo_id in silent:
            found[servo_id] = bus.ping_attempt(servo_id, attempt)
    return found


def hold(bus: FeetechBus) -> None:
    """Torque on for every checked servo, holding where its horn is; speed, acceleration.

    A servo that fails half-way leaves none holding torque.
    """
    enabled: list[int] = []
    try:
        for servo in bus.setup.servos:
            # Hold where the horn is before torque comes on, so it cannot jerk a pin.
            data, _ = bus.read(servo.servo_id, Register.PRESENT_POSITION)
            # An STS servo switches torque on when it is given a goal: from here on this
            # one must be released if anything fails.
            enabled.append(servo.servo_id)
            bus.write(servo.servo_id, Register.GOAL_POSITION, from_bytes(data))
            bus.write(servo.servo_id, Register.ACCELERATION, bus.setup.acceleration_register)
            bus.write(servo.servo_id, Register.GOAL_SPEED, bus.setup.speed_steps_per_s)
            bus.write(servo.servo_id, Register.TORQUE_ENABLE, 1)
            bus.assume_goals({servo.servo_id: decode_position(from_bytes(data))})
    except BaseException:
        # A half-finished handshake must not leave some servos holding torque.
        for servo_id in enabled:
            try:
                bus.write(servo_id, Register.TORQUE_ENABLE, 0)
            except BusError:
                pass
        raise


def hold_again(bus: FeetechBus) -> None:
    """Torque on again for every servo after a safe stop, holding where its horn is.

    The light way: one SYNC READ of where the horns are (every servo answering, none with an
    error bit, is what the handshake's pings would have found: ids, models and EEPROM limits
    cannot have changed under a port this array holds), then the registers `hold` writes, in
    three SYNC WRITEs, read back in one SYNC READ: for 16 servos some 8 ms where they answer
    at once (return delay 0), 24 ms at the factory's 500 us (`make bench`: bench_ways_out),
    against the handshake's 100-170 ms, every servo asked in turn. Wherever that falls short (a servo silent or reporting an error, a
    value not taken, a bus without SYNC READ), the whole handshake (`check`, `hold`), which
    names what is wrong.
    """
    try:
        if _hold_again_lightly(bus):
            return
    except BusError:
        pass  # the handshake below says what is wrong, servo by servo
    bus.connect(bus.setup)


def _hold_again_lightly(bus: FeetechBus) -> bool:
    setup = bus.setup
    ids = setup.servo_ids
    if len(ids) < 2:
        return False  # one servo: the handshake is as short
    horns = _sync_read(bus, Register.PRESENT_POSITION, Register.PRESENT_POSITION.size, ids)
    if horns is None:
        return False
    positions = {i: decode_position(from_bytes(data)) for i, data in horns.items()}
    speed = to_bytes(setup.speed_steps_per_s, Register.GOAL_SPEED.size)
    # As `hold`: hold where the horn is (an STS servo takes torque with a goal), then speed
    # and acceleration, then torque enable.
    writes = (
        packets.sync_write(Register.ACCELERATION.address, 3, (
            (i, bytes((setup.acceleration_register,)) + to_bytes(encode_position(p), 2))
            for i, p in positions.items())),
        packets.sync_write(Register.GOAL_SPEED.address, 2, ((i, speed) for i in ids)),
        packets.sync_write(Register.TORQUE_ENABLE.address, 1, ((i, b"\x01") for i in ids)),
    )
    try:
        for packet in writes:
            bus.link.send(packet)
    except WireLost as error:
        raise bus._lost("holding the pins again", error) from None
    held = _sync_read(bus, Register.TORQUE_ENABLE, HELD_LENGTH, ids)
    if held is None:
        return False
    goal = Register.GOAL_POSITION.address - Register.TORQUE_ENABLE.address
    accel = Register.ACCELERATION.address - Register.TORQUE_ENABLE.address
    at_speed = Register.GOAL_SPEED.address - Register.TORQUE_ENABLE.address
    if any(data[0] != 1 or data[accel] != setup.acceleration_register
           or decode_position(from_bytes(data[goal:goal + 2])) != positions[i]
           or data[at_speed:at_speed + 2] != speed for i, data in held.items()):
        return False
    bus.assume_goals(positions)
    return True


def _sync_read(bus: FeetechBus, register: Register, length: int,
               ids: tuple[int, ...]) -> dict[int, bytes] | None:
    """``length`` bytes from ``register`` of every servo in one SYNC READ (asked again once,
    waiting longer, for those that were silent); None unless all answered without an error
    bit."""
    found: dict[int, bytes] = {}
    for patience in (1, 4):
        asked = tuple(i for i in ids if i not in found)
        packet = packets.sync_read(register.address, length, asked)
        expected = tuple(Expected(i, length) for i in asked)
        try:
            replies = bus.link.exchange(packet, expected, patience=patience)
        except WireLost as error:
            raise bus._lost(f"reading {register.name} of every servo", error) from None
        if any(reply.error for reply in replies.values()):
            return None
        found.update((i, reply.params) for i, reply in replies.items())
        if len(found) == len(ids):
            return found
    return None


def _check_angle_limits(bus: FeetechBus, servo: ServoSetup) -> None:
    """Refuse a pin whose calibrated stroke the servo would clamp (its angle limits).

    A clamped goal would still read back as written: the read-back could not tell.
    """
    span = Register.MAX_ANGLE_LIMIT.address + 2 - Register.MIN_ANGLE_LIMIT.address
    data, _ = bus.read(servo.servo_id, Register.MIN_ANGLE_LIMIT, span)
    low, high = from_bytes(data[0:2]), from_bytes(data[-2:])
    if not low <= servo.min_steps <= servo.max_steps <= high:
        raise BusError(
            f"pin {servo.pin} (servo {servo.servo_id}): its angle limits MIN_ANGLE_LIMIT "
            f"{low} .. MAX_ANGLE_LIMIT {high} (EEPROM addresses 9, 11) would clamp the "
            f"calibrated stroke {servo.min_steps}..{servo.max_steps}; widen them with the "
            "vendor's tool or recalibrate the pin"
        )
