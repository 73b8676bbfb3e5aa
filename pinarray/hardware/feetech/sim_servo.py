"""One simulated STS servo: its control table, what each instruction does to it, and its horn.

The table starts at the model's factory values (`pinarray.hardware.feetech.models`). What a real STS3215
does and this one copies (sources in Feetech's STS3215 memory table v3.6 and communication
protocol manual V1.01, both in ``extras/`` of github.com/matthieuvigne/STS_servos):

- EEPROM (addresses 0-39) takes a written value at once, whatever the Lock register (55)
  says: Lock 0 makes it survive a power cycle, Lock 1 keeps it only until then ("Write 1 opens
  the write lock, and the value written to EPROM address is not saved after power failure").
  A new ID or baud rate is therefore in force from the next instruction on.
- A goal outside the angle limits (9/11) is clamped into them, a negative (sign-magnitude)
  goal included; with both limits 0 the servo is in multi-turn mode and only +-30719 applies.
  The Goal Position register keeps what was written.
- Writing a goal while torque is off turns torque on and the servo moves: the vendor's own
  position examples (FTServo_Python ``sms_sts/write.py``, "tested with STS/SMS") and other
  STS libraries (matthieuvigne/STS_servos ``SimpleMotion.ino``) never write Torque Enable.
- After power-on Torque Enable and Goal Position read 0 wherever the horn is; enabling torque
  before writing a goal sends the horn to that stale goal (drivers write goal = present first).
- Goal speed 0 and acceleration 0 mean "the servo's maximum" (phase bit 3); the speed unit is
  1 step/s (phase bit 2; 50 step/s when cleared).
- Present position = actual position - position correction (31), as LeRobot's calibration
  assumes; writing 128 to Torque Enable makes the present position read 2048.

Past 400 lines on purpose: one servo's control table and what every instruction does to it,
as Feetech's memory table describes it, register by register.
"""

from __future__ import annotations

from dataclasses import dataclass

from pinarray.hardware.feetech.models import (
    FACTORY_RETURN_DELAY_US,
    STS3215_C001,
    ServoModel,
    factory_table,
)
from pinarray.hardware.feetech.registers import (
    BAUD_RATE_BY_CODE,
    FIRST_RAM_ADDRESS,
    OFFSET_SIGN_BIT,
    POSITION_SIGN_BIT,
    Register,
    StatusError,
    decode_position,
    decode_sign_magnitude,
    encode_sign_magnitude,
    from_bytes,
    to_bytes,
)
from pinarray.hardware.feetech.sim_motion import Drive, MotionState, Move, at_rest, plan_move

TABLE_SIZE = 256
# Addresses as plain ints: the hot paths below run for every packet of every servo.
_ID = Register.ID.address
_BAUD = Register.BAUD_RATE.address
_RETURN_DELAY = Register.RETURN_DELAY_TIME.address
_STATUS_LEVEL = Register.STATUS_RETURN_LEVEL.address
_MIN_ANGLE = Register.MIN_ANGLE_LIMIT.address
_MAX_ANGLE = Register.MAX_ANGLE_LIMIT.address
_MAX_VOLTAGE = Register.MAX_VOLTAGE_LIMIT.address
_MIN_VOLTAGE = Register.MIN_VOLTAGE_LIMIT.address
_PHASE = Register.PHASE.address
_OFFSET = Register.POSITION_OFFSET.address
_MODE = Register.OPERATING_MODE.address
_TORQUE = Register.TORQUE_ENABLE.address
_ACCEL = Register.ACCELERATION.address
_GOAL = Register.GOAL_POSITION.address
_SPEED = Register.GOAL_SPEED.address
_LOCK = Register.LOCK.address
_PRESENT_POSITION = Register.PRESENT_POSITION.address
_PRESENT_SPEED = Register.PRESENT_SPEED.address
_PRESENT_LOAD = Register.PRESENT_LOAD.address
_PRESENT_VOLTAGE = Register.PRESENT_VOLTAGE.address
_PRESENT_TEMPERATURE = Register.PRESENT_TEMPERATURE.address
_SERVO_STATUS = Register.SERVO_STATUS.address
_MOVING = Register.MOVING.address
_OFFSET_SIGN = 1 << OFFSET_SIGN_BIT
_OFFSET_MAGNITUDE = _OFFSET_SIGN - 1
_POSITION_SIGN = 1 << POSITION_SIGN_BIT
_VOLTAGE_BIT = int(StatusError.VOLTAGE)
_BAUD_CODES = len(BAUD_RATE_BY_CODE)
# The feedback block (present position .. present current), refreshed when read.
FEEDBACK_START, FEEDBACK_END = 56, 71
# Addresses a write cannot change: version and model (0-4), and the feedback block.
READ_ONLY = frozenset(range(0, 5)) | frozenset(range(FEEDBACK_START, FEEDBACK_END))
# Writes here change where or how the horn goes: limits (9-12), phase (18), offset and mode
# (31-33), torque, acceleration, goal, time and speed (40-47).
STEERING = frozenset((*range(9, 13), 18, *range(31, 34), *range(40, 48)))
MULTI_TURN_LIMIT_STEPS = 30719  # "Multi loop control: -30719~+30719" (memory table v3.6)
PHASE_SPEED_UNIT_STEP = 0x04  # bit 2: speed in 1 step/s (else 50 step/s)
PHASE_SPEED_ZERO_IS_MAX = 0x08  # bit 3: goal speed 0 means full speed (else stop)
PHASE_FULL_ANGLE_FEEDBACK = 0x10  # bit 4: present position not folded into one turn
TORQUE_CALIBRATE_2048 = 128  # Torque Enable value: "current position correction is 2048"
NOMINAL_TEMPERATURE_C = 31
MAX_SPEED_STEPS_PER_S = STS3215_C001.speed_steps_per_s  # the default model's top speed
STEP_NS = 250_000  # sampling period of the `trajectory` compatibility view


@dataclass(frozen=True)
class TrajectorySample:
    """Where a simulated horn was at one instant."""

    time_ns: int
    position_steps: float


def baud_code(baud_rate: int) -> int:
    """Baud-rate register value for ``baud_rate`` bit/s (ValueError if the servo has none)."""
    return BAUD_RATE_BY_CODE.index(baud_rate)


class SimServo:
    """A simulated STS servo answering instructions on its control table.

    Parameters
    ----------
    servo_id : int
        Bus id, 0-252.
    start_ns : int
        Clock time at power-on, in nanoseconds.
    position_steps : int
        Where the horn is at power-on, in steps.
    return_delay_us : int
        Return delay in microseconds (register 7 holds half of it).
    model_number : int
        What the model-number register reads (the model's own by default).
    model : ServoModel
        Speed, voltage, backlash and factory table (`pinarray.hardware.feetech.models`).
    baud_rate : int
        Wire speed the servo listens at, bit/s (one of `BAUD_RATE_BY_CODE`).
    supply_v : float, optional
        Supply voltage in volts; the model's nominal voltage by default.
    backlash_steps : float, optional
        Free play of the horn in steps; the model's measured backlash by default.
    load_fraction : float
        Steady external load as a fraction of stall torque: > 0 presses the horn toward lower
        step counts (slowing motion up), < 0 toward higher ones.
    top_speed_steps_per_s : float, optional
        The horn's top speed in steps/s, below the model's (a worn, hot or under-volted servo).
    """

    def __init__(
        self,
        servo_id: int,
        start_ns: int = 0,
        position_steps: int = 2048,
        return_delay_us: int = FACTORY_RETURN_DELAY_US,
        model_number: int | None = None,
        *,
        model: ServoModel = STS3215_C001,
        baud_rate: int = 1_000_000,
        supply_v: float | None = None,
        backlash_steps: float | None = None,
        load_fraction: float = 0.0,
        top_speed_steps_per_s: float | None = None,
    ):
        self.model = model
        self.table = bytearray(TABLE_SIZE)
        for register, value in factory_table(model).items():
            self._set(register, value)
        self._set(Register.MODEL_NUMBER, model_number or model.model_number)
        self._set(Register.ID, servo_id)
        self._set(Register.BAUD_RATE, baud_code(baud_rate))
        self._set(Register.RETURN_DELAY_TIME, return_delay_us // 2)
        self._saved_eeprom = bytes(self.table[:FIRST_RAM_ADDRESS])
        self.error_bits = StatusError(0)  # injected faults, reported in every status packet
        self.eeprom_writes: list[tuple[Register | int, bytes]] = []
        self.supply_v = supply_v or model.nominal_voltage_v
        self.backlash_steps = model.backlash_steps if backlash_steps is None else backlash_steps
        self.load_fraction = load_fraction
        self.top_speed_steps_per_s = top_speed_steps_per_s
        self._max_accel = model.max_acceleration_steps_per_s2
        self._pending: tuple[int, bytes] | None = None  # a REG_WRITE awaiting ACTION
        start = MotionState(float(position_steps), 0.0, float(position_steps))
        self._move: Move = at_rest(start_ns, start, self._drive())
        self._history: list[Move] | None = None
        # Moves planned since someone asked (`log_moves`): the motion level's samples.
        self._move_log: list[Move] | None = None
        self._recording_from_ns: int | None = None
        self._last_ns = start_ns

    # -- control table -------------------------------------------------------------------

    def get(self, register: Register) -> int:
        """Raw register value (no sign decoding)."""
        return from_bytes(self.table[register.address : register.address + register.size])

    def _set(self, register: Register, value: int) -> None:
        self.table[register.address : register.address + register.size] = to_bytes(
            value, register.size
        )

    def _word(self, address: int) -> int:
        return self.table[address] | self.table[address + 1] << 8

    def _put_word(self, address: int, value: int) -> None:
        self.table[address] = value & 0xFF
        self.table[address + 1] = value >> 8 & 0xFF

    @property
    def servo_id(self) -> int:
        return self.table[_ID]

    @property
    def return_delay_ns(self) -> int:
        return self.table[_RETURN_DELAY] * 2_000

    @property
    def status_return_level(self) -> int:
        return self.table[_STATUS_LEVEL]

    @property
    def torque_enabled(self) -> bool:
        return bool(self.table[_TORQUE])

    @property
    def goal_steps(self) -> int:
        """The Goal Position register as written (before clamping), in steps."""
        return decode_position(self._word(_GOAL))

    @property
    def offset_steps(self) -> int:
        return decode_sign_magnitude(self._word(_OFFSET), OFFSET_SIGN_BIT)

    @property
    def target_steps(self) -> int:
        """Where the horn is sent: the goal clamped into the angle limits, in steps."""
        low, high = self._word(_MIN_ANGLE), self._word(_MAX_ANGLE)
        if low == 0 and high == 0:
            low, high = -MULTI_TURN_LIMIT_STEPS, MULTI_TURN_LIMIT_STEPS
        return min(max(self.goal_steps, low), high)

    @property
    def baud_rate(self) -> int | None:
        """The wire speed the servo listens at, bit/s (None for a code it does not know)."""
        code = self.table[_BAUD]
        return BAUD_RATE_BY_CODE[code] if code < _BAUD_CODES else None

    def set_up_baud(self, baud_rate: int) -> None:
        """Make the servo listen at ``baud_rate`` as if it had been set up so (saved EEPROM)."""
        self._set(Register.BAUD_RATE, baud_code(baud_rate))
        self._saved_eeprom = bytes(self.table[:FIRST_RAM_ADDRESS])

    def hears(self, baud_rate: int | None) -> bool:
        """Whether bytes sent at ``baud_rate`` reach this servo as bytes (None: unknown, yes)."""
        return baud_rate is None or baud_rate == self.baud_rate

    @property
    def error_bits(self) -> StatusError:
        """Injected faults, reported in every status packet."""
        return self._error_bits

    @error_bits.setter
    def error_bits(self, bits: StatusError) -> None:
        self._error_bits = StatusError(bits)
        self._error_byte = int(bits)  # what every status packet carries, worked out once

    @property
    def status_error(self) -> StatusError:
        """Error bits of the next status packet: injected faults and a supply out of limits."""
        return StatusError(self.status_error_byte)

    @property
    def status_error_byte(self) -> int:
        """`status_error` as the byte a status packet carries."""
        table = self.table
        if table[_MIN_VOLTAGE] <= self.supply_v * 10 <= table[_MAX_VOLTAGE]:
            return self._error_byte
        return self._error_byte | _VOLTAGE_BIT

    # -- instructions --------------------------------------------------------------------

    def read(self, address: int, length: int, now_ns: int) -> bytes:
        """Answer a READ: ``length`` bytes of the table from ``address``."""
        if now_ns > self._last_ns:
            self._last_ns = now_ns
        if address == _PRESENT_POSITION and length == 2:  # a motion sample: the usual read
            word = self.present_position_word(now_ns)
            table = self.table
            table[_PRESENT_POSITION] = word & 0xFF
            table[_PRESENT_POSITION + 1] = word >> 8
            return word.to_bytes(2, "little")
        end = address + length
        if address < FEEDBACK_END and end > FEEDBACK_START:
            self._refresh_feedback(now_ns, address, end)  # only then does the motion matter
        if end <= TABLE_SIZE:
            return bytes(self.table[address:end])
        data = bytes(self.table[address:end])
        return data + bytes(length - len(data))

    def write(self, address: int, data: bytes, now_ns: int) -> None:
        """Apply a WRITE; writes to EEPROM addresses are remembered so tests can forbid them."""
        now_ns = self._touch(now_ns)
        if address < FIRST_RAM_ADDRESS:
            self.eeprom_writes.append((Register.at(address) or address, bytes(data)))
        table = self.table
        torque_before = table[_TORQUE]
        written = range(address, min(address + len(data), TABLE_SIZE))
        for index in written:
            if index not in READ_ONLY:
                table[index] = data[index - address]
        if _TORQUE in written and table[_TORQUE] == TORQUE_CALIBRATE_2048:
            self._calibrate_to_2048(now_ns)
            table[_TORQUE] = 1 if torque_before else 0
        goal_written = _GOAL in written or _GOAL + 1 in written
        if goal_written and _TORQUE not in written and table[_MODE] == 0:
            table[_TORQUE] = 1
        if address < FIRST_RAM_ADDRESS and table[_LOCK] == 0:
            self._saved_eeprom = bytes(table[:FIRST_RAM_ADDRESS])
        if not STEERING.isdisjoint(written):
            self._replan(now_ns)

    def reg_write(self, address: int, data: bytes) -> None:
        """REG_WRITE: keep the write until ACTION (a later one replaces it)."""
        self._pending = (address, bytes(data))
        self._set(Register.REG_WRITE_PENDING, 1)

    def action(self, now_ns: int) -> None:
        """ACTION: carry out the pending REG_WRITE, if any."""
        if self._pending is not None:
            address, data = self._pending
            self._pending = None
            self._set(Register.REG_WRITE_PENDING, 0)
            self.write(address, data, now_ns)

    def factory_reset(self, now_ns: int) -> None:
        """RESET (0x06): EEPROM back to factory values except the ID, and saved."""
        now_ns = self._touch(now_ns)
        servo_id = self.servo_id
        for register, value in factory_table(self.model).items():
            if register.address < FIRST_RAM_ADDRESS:
                self._set(register, value)
        self._set(Register.ID, servo_id)
        self._set(Register.BAUD_RATE, 0)
        self._set(Register.RETURN_DELAY_TIME, FACTORY_RETURN_DELAY_US // 2)
        self._saved_eeprom = bytes(self.table[:FIRST_RAM_ADDRESS])
        self._replan(now_ns)

    def power_cycle(self, now_ns: int) -> None:
        """Power off and on (or REBOOT): unsaved EEPROM values and all of RAM are lost."""
        now_ns = self._touch(now_ns)
        self.table[:FIRST_RAM_ADDRESS] = self._saved_eeprom
        for register, value in factory_table(self.model).items():
            if register.address >= FIRST_RAM_ADDRESS:
                self._set(register, value)
        self._set(Register.TORQUE_LIMIT, self.get(Register.MAX_TORQUE))
        self._pending = None
        self._replan(now_ns)

    # -- motion --------------------------------------------------------------------------

    @property
    def position_steps(self) -> float:
        """Where the horn was when the servo was last addressed, in steps."""
        return self._move.state_at(self._last_ns).horn_steps

    def position_at_ns(self, time_ns: int) -> float:
        """Where the horn is (or was) at ``time_ns``, in steps (the encoder's own frame).

        Any time from the current move on works; earlier times need `start_recording` before
        them. Sampling does not change the servo.
        """
        move = self._move
        if time_ns < move.start_ns:
            move = self._move_at(time_ns)
        return move.state_at(time_ns).horn_steps

    def start_recording(self) -> None:
        """Keep every planned move from now on, so `position_at_ns` can look back."""
        self._history = [self._move]
        self._recording_from_ns = self._last_ns

    @property
    def trajectory(self) -> list[TrajectorySample] | None:
        """The horn every 0.25 ms since `start_recording` (a view sampled from the moves)."""
        if self._recording_from_ns is None:
            return None
        start, end = self._recording_from_ns, self._last_ns
        return [
            TrajectorySample(t, self.position_at_ns(t)) for t in range(start, end + 1, STEP_NS)
        ]

    def log_moves(self) -> list[Move]:
        """The move in force now and every move planned from now on, in a list that grows
        until `stop_logging_moves`."""
        self._move_log = [self._move]
        return self._move_log

    def stop_logging_moves(self) -> None:
        self._move_log = None

    @property
    def folds_position(self) -> bool:
        """Whether Present Position is folded into one turn (phase bit 4 clear)."""
        return not self.table[_PHASE] & PHASE_FULL_ANGLE_FEEDBACK

    def carry_on_at(self, now_ns: int) -> None:
        """Go on from ``now_ns`` on another clock's time line, as if time had passed with
        nobody talking to the servo: a move in progress has ended, the table is as it was."""
        self._move = at_rest(now_ns, self._move.state_at(self._move.end_ns), self._drive())
        self._last_ns = now_ns
        if self._history is not None:
            self.start_recording()  # the old time line's moves mean nothing on the new one

    def advance_to(self, now_ns: int) -> None:
        """Note that time has reached ``now_ns`` (motion needs no stepping)."""
        self._touch(now_ns)

    def _move_at(self, time_ns: int) -> Move:
        if not self._history or time_ns < self._history[0].start_ns:
            raise ValueError(
                f"servo {self.servo_id}: no record of {time_ns} ns; call start_recording() first"
            )
        for move in reversed(self._history):
            if move.start_ns <= time_ns:
                return move
        return self._history[0]

    def _touch(self, now_ns: int) -> int:
        if now_ns > self._last_ns:
            self._last_ns = now_ns
        start_ns = self._move.start_ns
        return now_ns if now_ns > start_ns else start_ns

    def _drive(self) -> Drive:
        top = self.model.speed_at(self.supply_v)
        if self.top_speed_steps_per_s is not None:
            top = min(top, self.top_speed_steps_per_s)
        phase = self.table[_PHASE]
        speed = self._word(_SPEED) & 0x7FFF
        if speed:
            top = min(top, speed * (1 if phase & PHASE_SPEED_UNIT_STEP else 50))
        elif not phase & PHASE_SPEED_ZERO_IS_MAX:
            top = 0.0
        accel = self.table[_ACCEL] * 100 or self._max_accel
        load = self.load_fraction
        direction = -1 if load > 0 else (1 if load < 0 else 0)
        against = top * max(0.0, 1.0 - abs(load))  # a DC motor's torque-speed line
        up = against if direction < 0 else top
        down = against if direction > 0 else top
        return Drive(up, down, float(accel), self.backlash_steps, direction)

    def _replan(self, now_ns: int) -> None:
        state = self._move.state_at(now_ns)
        drive = self._drive()
        if self.table[_TORQUE] and self.table[_MODE] == 0:
            goal = self.target_steps + self.offset_steps
            self._move = plan_move(now_ns, state, float(goal), drive)
        else:
            self._move = at_rest(now_ns, state, drive)  # limp: the horn stays where it is
        if self._history is not None:
            self._history.append(self._move)
        if self._move_log is not None:
            self._move_log.append(self._move)

    def _calibrate_to_2048(self, now_ns: int) -> None:
        actual = round(self._move.state_at(now_ns).horn_steps)
        offset = (actual - 2048 + 2048) % 4096 - 2048  # into the register's +-2047
        offset = max(-2047, min(2047, offset))
        self._set(Register.POSITION_OFFSET, encode_sign_magnitude(offset, OFFSET_SIGN_BIT))
        self._set(Register.GOAL_POSITION, 2048)  # hold still: the goal follows the new frame

    def present_position_word(self, now_ns: int) -> int:
        """What the Present Position register (56) reads at ``now_ns``: where the horn is,
        less the position correction, folded into one turn unless phase bit 4 says not,
        sign-magnitude (bit 15)."""
        table = self.table
        raw = table[_OFFSET] | table[_OFFSET + 1] << 8
        magnitude = raw & _OFFSET_MAGNITUDE
        offset = -magnitude if raw & _OFFSET_SIGN else magnitude
        present = round(self._move.horn_at(now_ns)) - offset
        if not table[_PHASE] & PHASE_FULL_ANGLE_FEEDBACK:
            present %= 4096
        if present < 0:
            return min(32767, -present) | _POSITION_SIGN
        return min(32767, present)

    def _refresh_feedback(self, now_ns: int, start: int = FEEDBACK_START,
                          end: int = FEEDBACK_END) -> None:
        """Bring the feedback registers within ``start .. end - 1`` up to ``now_ns`` (the
        others are not read: working them out would cost a sampled bus its every exchange)."""
        table, move = self.table, self._move
        if start < _PRESENT_POSITION + 2 and end > _PRESENT_POSITION:
            word = self.present_position_word(now_ns)
            table[_PRESENT_POSITION] = word & 0xFF
            table[_PRESENT_POSITION + 1] = word >> 8
            if end <= _PRESENT_POSITION + 2:  # a motion sample: nothing else is read
                return
        if start < _PRESENT_SPEED + 2 and end > _PRESENT_SPEED:
            speed = max(-32767, min(32767, round(move.horn_speed_at(now_ns))))
            self._put_word(_PRESENT_SPEED, encode_sign_magnitude(speed, 15))
        if start <= _MOVING < end:
            table[_MOVING] = 1 if table[_TORQUE] and now_ns < move.end_ns else 0
        if end <= _PRESENT_LOAD:
            return
        # Faults show in the telemetry as they would on the bench.
        injected = self.error_bits
        if StatusError.OVERLOAD in injected:
            load = 1000
        else:
            load = round(min(1.0, abs(self.load_fraction)) * 1000) if table[_TORQUE] else 0
        self._put_word(_PRESENT_LOAD, encode_sign_magnitude(load, 10))
        voltage_dv = 45 if StatusError.VOLTAGE in injected else round(self.supply_v * 10)
        table[_PRESENT_VOLTAGE] = max(0, min(255, voltage_dv))
        hot = StatusError.OVERHEAT in injected
        table[_PRESENT_TEMPERATURE] = 75 if hot else NOMINAL_TEMPERATURE_C
        table[_SERVO_STATUS] = int(self.status_error)
