"""One simulated STS3215: its control table in memory and how its horn moves.

The servo moves toward its goal with a trapezoidal speed profile: it accelerates at the
acceleration register's rate up to the goal speed and brakes so that it stops on the goal.
Motion is integrated lazily, in fixed steps, only when someone looks at the servo, so an
idle servo costs nothing and virtual time can jump.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pinarray.bus.registers import (
    STS3215_MODEL_NUMBER,
    Register,
    StatusError,
    decode_position,
    encode_position,
    encode_sign_magnitude,
    from_bytes,
    to_bytes,
)

# About 0.2 s per 60 degrees at 7.4 V (REFERENCE.md: 0.19-0.22 s), i.e. ~50 rpm.
MAX_SPEED_STEPS_PER_S = 3400
# The register holds at most 254 x 100 step/s^2; 0 means "as fast as the servo can".
MAX_ACCELERATION_STEPS_PER_S2 = 254 * 100
STEP_NS = 250_000
TABLE_SIZE = 256
NOMINAL_VOLTAGE_DV = 74  # 7.4 V in 0.1 V units
NOMINAL_TEMPERATURE_C = 31


@dataclass(frozen=True)
class TrajectorySample:
    """Where a simulated horn was at one instant."""

    time_ns: int
    position_steps: float


class SimServo:
    """A simulated STS3215 answering reads and writes on its control table.

    Parameters
    ----------
    servo_id : int
        Bus id, 0-252.
    start_ns : int
        Clock time at power-on, in nanoseconds.
    position_steps : int
        Where the horn starts.
    return_delay_us : int
        Delay before the servo answers an instruction, in microseconds (factory: 500).
    model_number : int
        What the model-number register reads (777 for an STS3215).
    """

    def __init__(
        self,
        servo_id: int,
        start_ns: int = 0,
        position_steps: int = 2048,
        return_delay_us: int = 500,
        model_number: int = STS3215_MODEL_NUMBER,
    ):
        self.servo_id = servo_id
        self.table = bytearray(TABLE_SIZE)
        self.error_bits = StatusError(0)
        self.eeprom_writes: list[tuple[Register | int, bytes]] = []
        self.trajectory: list[TrajectorySample] | None = None
        self._position = float(position_steps)
        self._speed = 0.0
        self._time_ns = start_ns
        self._set(Register.MODEL_NUMBER, model_number)
        self._set(Register.ID, servo_id)
        self._set(Register.RETURN_DELAY_TIME, return_delay_us // 2)
        self._set(Register.MAX_ANGLE_LIMIT, 4095)
        self._set(Register.LOCK, 1)
        self._set(Register.GOAL_POSITION, encode_position(position_steps))
        self._refresh_present()

    # -- control table -------------------------------------------------------------------

    def get(self, register: Register) -> int:
        """Raw register value (no sign decoding)."""
        return from_bytes(self.table[register.address : register.address + register.size])

    def _set(self, register: Register, value: int) -> None:
        self.table[register.address : register.address + register.size] = to_bytes(
            value, register.size
        )

    @property
    def return_delay_ns(self) -> int:
        return self.get(Register.RETURN_DELAY_TIME) * 2_000

    @property
    def torque_enabled(self) -> bool:
        return bool(self.get(Register.TORQUE_ENABLE))

    @property
    def goal_steps(self) -> int:
        return decode_position(self.get(Register.GOAL_POSITION))

    @property
    def position_steps(self) -> float:
        """Where the horn is now (after the last `advance_to`), in steps."""
        return self._position

    def read(self, address: int, length: int, now_ns: int) -> bytes:
        """Answer a read instruction: ``length`` bytes of the table from ``address``."""
        self.advance_to(now_ns)
        self._refresh_present()
        return bytes(self.table[address : address + length])

    def write(self, address: int, data: bytes, now_ns: int) -> None:
        """Apply a write instruction; EEPROM writes are remembered so tests can forbid them."""
        self.advance_to(now_ns)
        if address < Register.TORQUE_ENABLE.address:
            self.eeprom_writes.append((Register.at(address) or address, bytes(data)))
        self.table[address : address + len(data)] = data
        if not self.torque_enabled:
            self._speed = 0.0

    # -- motion --------------------------------------------------------------------------

    def start_recording(self) -> None:
        """Keep every integration step's position in `trajectory` from now on."""
        self.trajectory = [TrajectorySample(self._time_ns, self._position)]

    def advance_to(self, now_ns: int) -> None:
        """Integrate the horn's motion up to ``now_ns``."""
        if now_ns <= self._time_ns:
            return
        goal = float(self.goal_steps)
        if not self.torque_enabled or (self._speed == 0.0 and self._position == goal):
            self._time_ns = now_ns  # nothing moves; jump
            return
        top_speed = self.get(Register.GOAL_SPEED) or MAX_SPEED_STEPS_PER_S
        top_speed = min(top_speed, MAX_SPEED_STEPS_PER_S)
        acceleration = self.get(Register.ACCELERATION) * 100 or MAX_ACCELERATION_STEPS_PER_S2
        while self._time_ns < now_ns:
            dt_ns = min(STEP_NS, now_ns - self._time_ns)
            self._step(goal, top_speed, acceleration, dt_ns / 1e9)
            self._time_ns += dt_ns
            if self.trajectory is not None:
                self.trajectory.append(TrajectorySample(self._time_ns, self._position))
            if self._speed == 0.0 and self._position == goal:
                self._time_ns = now_ns
                break

    def _step(self, goal: float, top_speed: float, acceleration: float, dt_s: float) -> None:
        distance = goal - self._position
        if abs(distance) < 0.5 and abs(self._speed) <= acceleration * dt_s:
            self._position, self._speed = goal, 0.0
            return
        # Fastest speed from which the servo can still brake to a stop on the goal.
        braking_speed = math.sqrt(2.0 * acceleration * abs(distance))
        wanted = math.copysign(min(top_speed, braking_speed), distance)
        change = max(-acceleration * dt_s, min(acceleration * dt_s, wanted - self._speed))
        self._speed += change
        moved = self._speed * dt_s
        if abs(moved) >= abs(distance) and math.copysign(1.0, moved) == math.copysign(
            1.0, distance
        ):
            self._position, self._speed = goal, 0.0
        else:
            self._position += moved

    def _refresh_present(self) -> None:
        self._set(Register.PRESENT_POSITION, encode_position(round(self._position)))
        self._set(Register.PRESENT_SPEED, encode_sign_magnitude(round(self._speed), 15))
        moving = self._speed != 0.0 or self._position != self.goal_steps
        self._set(Register.MOVING, int(moving and self.torque_enabled))
        # Faults show in the telemetry as they would on the bench.
        load = 1000 if StatusError.OVERLOAD in self.error_bits else 0
        self._set(Register.PRESENT_LOAD, load)
        voltage = 45 if StatusError.VOLTAGE in self.error_bits else NOMINAL_VOLTAGE_DV
        self._set(Register.PRESENT_VOLTAGE, voltage)
        hot = StatusError.OVERHEAT in self.error_bits
        self._set(Register.PRESENT_TEMPERATURE, 75 if hot else NOMINAL_TEMPERATURE_C)
