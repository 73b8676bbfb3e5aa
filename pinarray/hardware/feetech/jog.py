"""Jogging one pin: its servo held by torque and moved in small steps while a person watches.

Calibration (`pinarray servos calibrate`) finds a pin's rest and "up" positions this way. The
servo is opened without the playback handshake; goals stay within the servo's own angle
limits; however jogging ends, `Jog.release` puts the pin at rest and its torque off.
"""

from __future__ import annotations

from dataclasses import dataclass

from pinarray.clock import Clock
from pinarray.errors import BusError
from pinarray.hardware.driver import GoalOutOfRange, SafeStopReport, ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.feetech import FeetechBus
from pinarray.hardware.feetech.registers import (
    Register,
    StatusError,
    decode_position,
    encode_position,
    from_bytes,
)
from pinarray.hardware.feetech.safety import MOTION_LENGTH, REST_POLL_NS, REST_TOLERANCE_STEPS
from pinarray.units import NS_PER_S

# One-turn encoder range of an STS servo, in steps.
FULL_RANGE_STEPS = (0, 4095)
# How fast a jogged horn moves, at most: slow enough to watch, fast enough not to wait.
JOG_SPEED_STEPS_PER_S = 600
# Time a jog may take beyond its travel at jog speed before it is reported as not arrived.
JOG_SLACK_NS = 1_000_000_000


@dataclass(frozen=True)
class JogReading:
    """Where a jogged horn was sent and where it stopped, in steps."""

    goal_steps: int
    present_steps: int
    arrived: bool  # stopped within a few steps of the goal in the time the jog allows
    errors: StatusError


class Jog:
    """One pin's servo, held by torque and moved in small steps while a person watches.

    Goals are kept within the servo's own angle limits (MIN/MAX_ANGLE_LIMIT, EEPROM 9/11),
    which it would clamp anyway, not within the pin's calibrated limits: finding where the pin
    should go is what jogging is for.

    Parameters
    ----------
    bus : FeetechBus
        Opened without the handshake.
    servo : ServoSetup
        The pin, its servo id and its calibrated rest (where `release` sends it).
    model_number : int
        What the servo must report (777 for an STS3215).
    speed_steps_per_s : int
        Goal speed while jogging, capped at `JOG_SPEED_STEPS_PER_S`.
    clock : Clock, optional
        What waiting for the horn to settle waits on (default the bus's): a
        `pinarray.stop.StoppableClock` ends a wait on a stop request.
    """

    def __init__(self, bus: FeetechBus, servo: ServoSetup, model_number: int,
                 speed_steps_per_s: int = JOG_SPEED_STEPS_PER_S, clock: Clock | None = None):
        self.bus = bus
        self.clock = clock or bus.clock
        self.servo = servo
        self.model_number = model_number
        self.speed_steps_per_s = max(1, min(speed_steps_per_s, JOG_SPEED_STEPS_PER_S))
        self.bounds = FULL_RANGE_STEPS
        self.goal_steps: int | None = None

    @property
    def name(self) -> str:
        return f"pin {self.servo.pin} (servo {self.servo.servo_id})"

    def start(self) -> JogReading:
        """Check the servo, then hold the horn where it is, torque on, at jog speed."""
        bus, servo_id = self.bus, self.servo.servo_id
        model = bus.ping(servo_id)
        if model is None:
            raise BusError(f"{self.name} does not answer on {bus.port_name}")
        if model != self.model_number:
            raise BusError(f"{self.name}: expected model {self.model_number}, found {model}")
        span = Register.MAX_ANGLE_LIMIT.address + 2 - Register.MIN_ANGLE_LIMIT.address
        data, _ = bus.read(servo_id, Register.MIN_ANGLE_LIMIT, span)
        low, high = from_bytes(data[0:2]), from_bytes(data[-2:])
        if low or high:  # both 0: multi-turn mode, where only the encoder's range applies
            self.bounds = (max(FULL_RANGE_STEPS[0], low), min(FULL_RANGE_STEPS[1], high))
        present, _ = bus.read(servo_id, Register.PRESENT_POSITION)
        here = min(max(decode_position(from_bytes(present)), self.bounds[0]), self.bounds[1])
        # Hold where the horn is before torque comes on, so that nothing jumps.
        bus.write(servo_id, Register.GOAL_POSITION, encode_position(here))
        bus.write(servo_id, Register.ACCELERATION, 0)
        bus.write(servo_id, Register.GOAL_SPEED, self.speed_steps_per_s)
        bus.write(servo_id, Register.TORQUE_ENABLE, 1)
        self.goal_steps = here
        return self._settle(here, 0)

    def move_by(self, steps: int) -> JogReading:
        """Move the goal ``steps`` steps (negative: the other way)."""
        assert self.goal_steps is not None, "start() first"
        return self.move_to(self.goal_steps + steps)

    def move_to(self, goal_steps: int) -> JogReading:
        """Send the horn to ``goal_steps`` and wait until it stops there (or time is up)."""
        assert self.goal_steps is not None, "start() first"
        low, high = self.bounds
        if not low <= goal_steps <= high:
            raise GoalOutOfRange(
                f"{self.name}: GOAL_POSITION {goal_steps} steps is outside the servo's angle "
                f"limits {low}..{high} (MIN/MAX_ANGLE_LIMIT, EEPROM addresses 9, 11)")
        travel = abs(goal_steps - self.goal_steps)
        self.bus.write(self.servo.servo_id, Register.GOAL_POSITION, encode_position(goal_steps))
        self.goal_steps = goal_steps
        return self._settle(goal_steps, travel)

    def read(self) -> JogReading:
        """Where the horn is now, without moving it."""
        assert self.goal_steps is not None, "start() first"
        return self._settle(self.goal_steps, 0)

    def _settle(self, goal_steps: int, travel_steps: int) -> JogReading:
        bus, clock, servo_id = self.bus, self.clock, self.servo.servo_id
        deadline_ns = (clock.now_ns() + travel_steps * NS_PER_S // self.speed_steps_per_s
                       + JOG_SLACK_NS)
        while True:
            data, errors = bus.read(servo_id, Register.PRESENT_POSITION, MOTION_LENGTH)
            present = decode_position(from_bytes(data[0:2]))
            arrived = data[-1] == 0 and abs(present - goal_steps) <= REST_TOLERANCE_STEPS
            if arrived or clock.now_ns() >= deadline_ns:
                return JogReading(goal_steps, present, arrived, errors)
            clock.sleep_until_ns(clock.now_ns() + REST_POLL_NS)

    def release(self, rest_steps: int) -> SafeStopReport:
        """The pin to ``rest_steps``, then torque off; never raises (see `rest_and_release`)."""
        low, high = min(self.bounds[0], rest_steps), max(self.bounds[1], rest_steps)
        self.bus.setup = BusSetup(
            (ServoSetup(self.servo.servo_id, self.servo.pin, rest_steps, low, high),),
            model_number=self.model_number, speed_steps_per_s=self.speed_steps_per_s)
        return self.bus.rest_and_release()
