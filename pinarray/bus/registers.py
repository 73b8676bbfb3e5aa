"""The STS3215 control table as data, and the sign-magnitude encodings its registers use.

Pure data and arithmetic: no I/O and no vendor SDK, so the simulator, the driver and the
tests all read the same table. Addresses and sizes follow ``REFERENCE.md`` (Feetech STS
series, protocol end 0, little-endian).
"""

from __future__ import annotations

from enum import Enum, IntFlag

STS3215_MODEL_NUMBER = 777
BROADCAST_ID = 0xFE
MAX_SERVO_ID = 0xFC

# Addresses below this live in EEPROM; writing them wears the flash and survives power-off,
# so the driver never does it without being asked.
FIRST_RAM_ADDRESS = 40

POSITION_SIGN_BIT = 15
SPEED_SIGN_BIT = 15
LOAD_SIGN_BIT = 10


class Register(Enum):
    """An STS control-table register: ``.address`` and ``.size`` in bytes."""

    MODEL_NUMBER = (3, 2)
    ID = (5, 1)
    BAUD_RATE = (6, 1)
    RETURN_DELAY_TIME = (7, 1)  # 2 us units
    MIN_ANGLE_LIMIT = (9, 2)
    MAX_ANGLE_LIMIT = (11, 2)
    TORQUE_ENABLE = (40, 1)
    ACCELERATION = (41, 1)  # 100 step/s^2 units; 0 = the servo's maximum
    GOAL_POSITION = (42, 2)  # sign-magnitude, sign bit 15
    GOAL_TIME = (44, 2)
    GOAL_SPEED = (46, 2)  # step/s; 0 = the servo's maximum
    LOCK = (55, 1)  # 0 = EEPROM writable
    PRESENT_POSITION = (56, 2)
    PRESENT_SPEED = (58, 2)
    PRESENT_LOAD = (60, 2)  # sign bit 10, 0.1 % of stall torque
    PRESENT_VOLTAGE = (62, 1)  # 0.1 V
    PRESENT_TEMPERATURE = (63, 1)  # degC
    MOVING = (66, 1)

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


class StatusError(IntFlag):
    """Error bits a servo reports in the error byte of every status packet."""

    VOLTAGE = 1
    ANGLE_SENSOR = 2
    OVERHEAT = 4
    OVERCURRENT = 8
    OVERLOAD = 32

    def describe(self) -> str:
        """Lower-case names joined by '+', or 'none'."""
        names = [flag.name.lower() for flag in StatusError if flag in self and flag.name]
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
    return decode_sign_magnitude(raw, POSITION_SIGN_BIT)


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
