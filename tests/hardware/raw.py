"""A bare-bytes client for the simulated bus: packets built by hand, as a protocol manual shows.

Nothing here uses pinarray's driver or the vendor SDK, so tests of the simulator see exactly
the bytes a third-party client would.
"""

from __future__ import annotations

from dataclasses import dataclass

from pinarray.clock import VirtualClock
from pinarray.hardware.feetech.faults import parse_sim_url
from pinarray.hardware.feetech.registers import BROADCAST_ID, Instruction, checksum
from pinarray.hardware.feetech.sim import SimBus, SimSerial


def packet(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """``FF FF id len instr params chk``."""
    body = bytes([servo_id, len(params) + 2, instruction]) + bytes(params)
    return b"\xff\xff" + body + bytes([checksum(body)])


@dataclass(frozen=True)
class Status:
    """One status packet as the host received it."""

    servo_id: int
    error: int
    params: bytes


def parse_status(data: bytes) -> tuple[list[Status], int]:
    """Status packets with a good checksum in ``data``, and how many bytes were garbage."""
    found, garbage, index = [], 0, 0
    while index + 6 <= len(data):
        if data[index] != 0xFF or data[index + 1] != 0xFF:
            index, garbage = index + 1, garbage + 1
            continue
        length = data[index + 3]
        end = index + 4 + length
        body = data[index + 2 : end - 1]
        if end > len(data) or length < 2 or checksum(body) != data[end - 1]:
            index, garbage = index + 1, garbage + 1
            continue
        found.append(Status(body[0], body[2], bytes(body[3:])))
        index = end
    return found, garbage + len(data) - index


class RawBus:
    """Simulated servos from a ``sim://`` query, spoken to byte by byte in virtual time."""

    def __init__(self, query: str = "ids=1", baud_rate: int = 1_000_000):
        self.clock = VirtualClock()
        self.sim = SimBus(parse_sim_url(f"sim://?{query}"), self.clock)
        self.port = SimSerial(self.sim, self.clock, baud_rate)
        self.garbage = 0

    def send(self, servo_id: int, instruction: int, params: bytes = b"",
             listen_ns: int = 20_000_000) -> list[Status]:
        """Send one instruction, listen for ``listen_ns``, return the status packets heard."""
        self.port.reset_input_buffer()
        self.port.write(packet(servo_id, instruction, params))
        self.clock.sleep_until_ns(self.clock.now_ns() + listen_ns)
        replies, self.garbage = parse_status(self.port.read(4096))
        return replies

    def ping(self, servo_id: int) -> list[Status]:
        return self.send(servo_id, Instruction.PING)

    def broadcast_ping(self) -> list[Status]:
        return self.send(BROADCAST_ID, Instruction.PING)

    def read(self, servo_id: int, address: int, length: int) -> bytes | None:
        replies = self.send(servo_id, Instruction.READ, bytes([address, length]))
        return replies[0].params if replies else None

    def read_int(self, servo_id: int, address: int, length: int) -> int | None:
        data = self.read(servo_id, address, length)
        return None if data is None else int.from_bytes(data, "little")

    def present_steps(self, servo_id: int) -> int | None:
        """The Present Position register (address 56), in steps."""
        return self.read_int(servo_id, 56, 2)

    def write(self, servo_id: int, address: int, data: bytes) -> list[Status]:
        return self.send(servo_id, Instruction.WRITE, bytes([address]) + bytes(data))

    def wait_ns(self, duration_ns: int) -> None:
        self.clock.sleep_until_ns(self.clock.now_ns() + duration_ns)
