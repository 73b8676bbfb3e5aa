"""The STS connect handshake: every servo checked before anything moves, then torque on.

`check` only reads (ids, models, angle limits, return delays), so that the player process
that guards the servos can be started before `hold` gives them torque.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinarray.errors import BusError
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.registers import Register, decode_position, from_bytes
from pinarray.units import NS_PER_US

if TYPE_CHECKING:
    from pinarray.hardware.feetech.feetech import FeetechBus


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
    found = {servo_id: bus.ping(servo_id) for servo_id in setup.servo_ids}
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
