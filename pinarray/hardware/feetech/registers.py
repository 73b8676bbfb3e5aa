"""The STS3215 control table as data, and the sign-magnitude encodings its registers use.

Pure data and arithmetic: no I/O and no vendor SDK, so the simulator, the driver and the
tests all read the same table. Addresses and sizes follow ``REFERENCE.md`` (Feetech STS
series, protocol end 0, little-endian).
"""

from __future__ import annotations

from enum import Enum, IntEnum, IntFlag

STS3215_MODEL_NUMBER = 777
# LeRobot's Feetech model table (src/lerobot/motors/feetech/tables.py, MODEL_NUMBER_TABLE).
STS3250_MODEL_NUMBER = 2825
BROADCAST_ID = 0xFE
MAX_SERVO_ID = 0xFC

# Addresses below this live in EEPROM; writing them wears the flash and survives power-off,
# so the driver never does it without being asked.
FIRST_RAM_ADDRESS = 40

POSITION_SIGN_BIT = 15
SPEED_SIGN_BIT = 15
LOAD_SIGN_BIT = 10
# Position correction (address 31): "Bit11 is the direction bit" (STS3215 memory table v3.6).
OFFSET_SIGN_BIT = 11

# Baud-rate register (address 6) codes, from Feetech's STS3215 memory table v3.6 ("0-7 represents
# baud rate as follows: 1000000, 500000, 250000, 128000, 115200, 76800, 57600, 38400"), the same
# order as FTServo_Python's sms_sts.py constants SMS_STS_1M .. SMS_STS_38400.
BAUD_RATE_BY_CODE = (1_000_000, 500_000, 250_000, 128_000, 115_200, 76_800, 57_600, 38_400)


class Register(Enum):
    """An STS control-table register: ``.address`` and ``.size`` in bytes.

    Addresses, sizes and units follow Feetech's STS3215 memory table v3.6 (the spreadsheet
    Feetech gave matthieuvigne/STS_servos, ``extras/STS3215 Memory Table.xlsx``).
    """

    # Members are singletons: hashed by identity, a dict keyed by a register (a request
    # kept for the next sample) costs no Python call (Enum's own hash is its name's).
    __hash__ = object.__hash__

    FIRMWARE_MAJOR = (0, 1)
    FIRMWARE_MINOR = (1, 1)
    MODEL_NUMBER = (3, 2)
    ID = (5, 1)
    BAUD_RATE = (6, 1)  # a code into BAUD_RATE_BY_CODE
    RETURN_DELAY_TIME = (7, 1)  # 2 us units
    STATUS_RETURN_LEVEL = (8, 1)  # 0: only READ and PING answer; 1: every instruction does
    MIN_ANGLE_LIMIT = (9, 2)
    MAX_ANGLE_LIMIT = (11, 2)
    MAX_TEMPERATURE_LIMIT = (13, 1)  # degC
    MAX_VOLTAGE_LIMIT = (14, 1)  # 0.1 V
    MIN_VOLTAGE_LIMIT = (15, 1)  # 0.1 V
    MAX_TORQUE = (16, 2)  # 0.1 % of stall torque; copied into TORQUE_LIMIT at power-on
    PHASE = (18, 1)  # special-function bits (speed unit, feedback mode, ...)
    UNLOADING_CONDITION = (19, 1)
    LED_ALARM_CONDITION = (20, 1)
    P_GAIN = (21, 1)
    D_GAIN = (22, 1)
    I_GAIN = (23, 1)
    MIN_STARTUP_FORCE = (24, 2)
    CW_DEAD_ZONE = (26, 1)
    CCW_DEAD_ZONE = (27, 1)
    PROTECTION_CURRENT = (28, 2)  # 6.5 mA units
    ANGULAR_RESOLUTION = (30, 1)
    POSITION_OFFSET = (31, 2)  # sign-magnitude, sign bit 11; present = actual - offset
    OPERATING_MODE = (33, 1)  # 0 = position servo
    PROTECTIVE_TORQUE = (34, 1)
    PROTECTION_TIME = (35, 1)  # 10 ms units
    OVERLOAD_TORQUE = (36, 1)
    SPEED_P_GAIN = (37, 1)
    OVERCURRENT_TIME = (38, 1)  # 10 ms units
    SPEED_I_GAIN = (39, 1)
    TORQUE_ENABLE = (40, 1)
    ACCELERATION = (41, 1)  # 100 step/s^2 units; 0 = the servo's maximum
    GOAL_POSITION = (42, 2)  # sign-magnitude, sign bit 15
    GOAL_TIME = (44, 2)
    GOAL_SPEED = (46, 2)  # step/s; 0 = the servo's maximum
    TORQUE_LIMIT = (48, 2)  # 0.1 % of stall torque
    LOCK = (55, 1)  # 0 = EEPROM writable
    PRESENT_POSITION = (56, 2)
    PRESENT_SPEED = (58, 2)
    PRESENT_LOAD = (60, 2)  # sign bit 10, 0.1 % of stall torque
    PRESENT_VOLTAGE = (62, 1)  # 0.1 V
    PRESENT_TEMPERATURE = (63, 1)  # degC
    REG_WRITE_PENDING = (64, 1)  # "asynchronous write flag": a REG_WRITE awaits ACTION
    SERVO_STATUS = (65, 1)  # the error bits, as in a status packet
    MOVING = (66, 1)
    PRESENT_CURRENT = (69, 2)  # 6.5 mA units

    @property
    def address(self) -> int:
        return self.value[0]

    @property
    def size(self) -> int:
        return self.value[1]

    @property
    def in_eeprom(self) -> bool:
        return self.address < FIRST_RAM_ADDRESS

    @classmethod
    def at(cls, address: int) -> Register | None:
        """The register that starts at ``address``, or None."""
        return _BY_ADDRESS.get(address)


_BY_ADDRESS = {register.address: register for register in Register}


class Instruction(IntEnum):
    """Instruction codes of the Feetech SCS/STS protocol.

    From Feetech's "Communication Protocol Manual" V1.01 (extras/ of matthieuvigne/STS_servos)
    and FTServo_Python's scservo_def.py: 0x06 RESET restores the control table's factory
    values, while 0x0A (FTServo's ``reSet``) only clears a multi-turn count and status.
    """

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x06
    REBOOT = 0x08
    CLEAR_STATUS = 0x0A
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83

    @classmethod
    def name_of(cls, code: int) -> str:
        """``"SYNC_WRITE"`` for 0x83; ``"0x0B"`` for a code this table does not name."""
        try:
            return cls(code).name
        except ValueError:
            return f"0x{code:02X}"


WRITE_INSTRUCTIONS = frozenset({Instruction.WRITE, Instruction.REG_WRITE, Instruction.SYNC_WRITE})


class StatusError(IntFlag):
    """Error bits a servo reports in the error byte of every status packet."""

    VOLTAGE = 1
    ANGLE_SENSOR = 2
    OVERHEAT = 4
    OVERCURRENT = 8
    OVERLOAD = 32

    def describe(self) -> str:
        """Lower-case names joined by '+' (bits with no name as hex), or 'none'."""
        names = [flag.name.lower() for flag in StatusError if flag in self and flag.name]
        unnamed = int(self) & ~sum(StatusError)
        if unnamed:
            names.append(f"unknown bits 0x{unnamed:02X}")
        return "+".join(names) if names else "none"


def encode_sign_magnitude(value: int, sign_bit: int) -> int:
    """Encode a signed integer as magnitude with a sign bit, as the servo stores it.

    Parameters
    ----------
    value : int
        Signed value, e.g. a position in steps; ``|value|`` must fit below ``sign_bit``.
    sign_bit : int
        Bit number that marks a negative value (15 for positions, 10 for load).
    """
    magnitude = abs(value)
    if magnitude >= 1 << sign_bit:
        raise ValueError(f"{value} does not fit in {sign_bit} magnitude bits")
    return magnitude | (1 << sign_bit) if value < 0 else magnitude


def decode_sign_magnitude(raw: int, sign_bit: int) -> int:
    """Inverse of `encode_sign_magnitude`; bits above ``sign_bit`` are ignored."""
    magnitude = raw & ((1 << sign_bit) - 1)
    return -magnitude if raw & (1 << sign_bit) else magnitude


def encode_position(position_steps: int) -> int:
    """Goal/present position in steps -> 16-bit register value (sign bit 15)."""
    return encode_sign_magnitude(position_steps, POSITION_SIGN_BIT)


def decode_position(raw: int) -> int:
    """16-bit register value -> position in steps."""
    # `decode_sign_magnitude` at bit 15, written out: every motion sample decodes one.
    magnitude = raw & _POSITION_MAGNITUDE
    return -magnitude if raw & _POSITION_SIGN else magnitude


_POSITION_SIGN = 1 << POSITION_SIGN_BIT
_POSITION_MAGNITUDE = _POSITION_SIGN - 1


def decode_load(raw: int) -> int:
    """Present-load register -> signed load in 0.1 % of stall torque (sign bit 10)."""
    return decode_sign_magnitude(raw, LOAD_SIGN_BIT)


def to_bytes(value: int, size: int) -> bytes:
    """Register value -> little-endian bytes as they go on the wire."""
    return value.to_bytes(size, "little")


def from_bytes(data: bytes | bytearray | list[int]) -> int:
    """Little-endian wire bytes -> register value."""
    return int.from_bytes(bytes(data), "little")


def checksum(body: bytes | bytearray | list[int]) -> int:
    """Packet checksum over id, length, instruction/error and parameters: ``~sum & 0xFF``."""
    return ~sum(body) & 0xFF
