"""The STS packet format: instruction packets out, status packets in. Pure; no I/O.

::

    instruction  FF FF id len instruction params... checksum     len = len(params) + 2
    status       FF FF id len error       params... checksum
    checksum = ~(id + len + instruction-or-error + sum(params)) & 0xFF

The bytes are the ones the vendor's ``scservo_sdk`` puts on the wire (a test compares them);
the SDK is not used to send them because its exchange matches a reply to a request by id
only, spins on the port while it waits, and can raise from inside (an ``IndexError`` on a
half-received packet). `StatusReader` is the receiving half: it finds status packets in any
stream of bytes, noise and stale replies included, and checks each one's checksum.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

from pinarray.hardware.feetech.registers import BROADCAST_ID, Instruction, checksum

HEADER = b"\xff\xff"
# The longest packet the servos' firmware (and the vendor SDK) handles, in bytes.
MAX_PACKET_BYTES = 250
# The servos never set bit 7 of a status packet's error byte (the vendor SDK's test too).
MAX_ERROR_BYTE = 0x7F
# A status packet with no parameters: FF FF id len error checksum.
STATUS_OVERHEAD_BYTES = 6
# FF FF id len instruction checksum, before the parameters.
INSTRUCTION_OVERHEAD_BYTES = 6
# A READ instruction packet (address and length), in bytes.
READ_REQUEST_BYTES = INSTRUCTION_OVERHEAD_BYTES + 2


def instruction_packet(servo_id: int, instruction: Instruction, params: bytes = b"") -> bytes:
    """``FF FF id len instruction params checksum``."""
    body = bytes((servo_id, len(params) + 2, instruction)) + params
    if len(body) + 3 > MAX_PACKET_BYTES:
        raise ValueError(f"a packet of {len(body) + 3} bytes exceeds {MAX_PACKET_BYTES}")
    return HEADER + body + bytes((checksum(body),))


def ping(servo_id: int) -> bytes:
    return instruction_packet(servo_id, Instruction.PING)


def read(servo_id: int, address: int, length: int) -> bytes:
    """Ask one servo for ``length`` bytes of its control table from ``address``."""
    return instruction_packet(servo_id, Instruction.READ, bytes((address, length)))


def write(servo_id: int, address: int, data: bytes) -> bytes:
    """Write ``data`` into one servo's control table at ``address``; it answers with a status."""
    return instruction_packet(servo_id, Instruction.WRITE, bytes((address,)) + data)


def sync_write(address: int, length: int, items: Iterable[tuple[int, bytes]]) -> bytes:
    """One packet writing ``length`` bytes at ``address`` of several servos; nobody answers."""
    params = bytearray((address, length))
    for servo_id, data in items:
        if len(data) != length:
            raise ValueError(f"servo {servo_id}: {len(data)} data bytes, expected {length}")
        params.append(servo_id)
        params += data
    return instruction_packet(BROADCAST_ID, Instruction.SYNC_WRITE, bytes(params))


def sync_read(address: int, length: int, servo_ids: Iterable[int]) -> bytes:
    """One packet asking several servos for the same bytes; each answers in turn."""
    return instruction_packet(
        BROADCAST_ID, Instruction.SYNC_READ, bytes((address, length, *servo_ids))
    )


def status_size(params_length: int) -> int:
    """Bytes of a status packet carrying ``params_length`` data bytes."""
    return STATUS_OVERHEAD_BYTES + params_length


class StatusPacket(NamedTuple):
    """One status packet a servo sent: its id, error byte and data."""

    servo_id: int
    error: int
    params: bytes


class StatusReader:
    """Finds whole, checksum-correct status packets in a stream of received bytes.

    Bytes that cannot start a packet (noise, the tail of a packet cut short) are skipped one at
    a time, as the servos' own UART does; a packet whose checksum fails is dropped and the hunt
    for a header resumes one byte after its start, so a corrupt packet cannot hide the next.

    Attributes
    ----------
    skipped_bytes : int
        Bytes thrown away while hunting for a header.
    bad_checksums : int
        Packets dropped for a wrong checksum.
    longest_params : int
        The most data bytes a status packet may carry; the link sets it to the longest reply
        it waits for.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.skipped_bytes = 0
        self.bad_checksums = 0
        # A length byte claiming more data than any awaited reply carries is noise (a flipped
        # bit): waiting for it would swallow the real reply behind it.
        self.longest_params = MAX_PACKET_BYTES - STATUS_OVERHEAD_BYTES

    def clear(self) -> int:
        """Forget a half-received packet; returns how many bytes were dropped."""
        dropped = len(self._buffer)
        self._buffer.clear()
        return dropped

    @property
    def pending_bytes(self) -> int:
        return len(self._buffer)

    def _whole(self, data: bytes) -> StatusPacket | None:
        """``data`` as one status packet and nothing else, when `feed`'s loop, its buffer
        empty, would find just that (the usual read: one answer, whole); else None."""
        size = len(data)
        if size < 6 or data[0] != 0xFF or data[1] != 0xFF:
            return None
        servo_id, length, error = data[2], data[3], data[4]
        if (size != length + 4 or servo_id >= BROADCAST_ID or length - 2 > self.longest_params
                or error > MAX_ERROR_BYTE or checksum(data[2:-1]) != data[-1]):
            return None
        return StatusPacket(servo_id, error, bytes(data[5:-1]))

    def feed(self, data: bytes) -> list[StatusPacket]:
        """Add received bytes; return the status packets they complete, in order."""
        if not self._buffer and (packet := self._whole(data)) is not None:
            return [packet]
        self._buffer += data
        found: list[StatusPacket] = []
        buffer = self._buffer
        while True:
            start = buffer.find(HEADER)
            if start < 0:
                # Keep a trailing FF: it may be the first half of the next header.
                keep = 1 if buffer[-1:] == b"\xff" else 0
                self.skipped_bytes += len(buffer) - keep
                del buffer[: len(buffer) - keep]
                return found
            if start:
                self.skipped_bytes += start
                del buffer[:start]
            if len(buffer) < 4:
                return found
            servo_id, length = buffer[2], buffer[3]
            if servo_id == 0xFF or servo_id == BROADCAST_ID or length < 2 or (
                length - 2 > self.longest_params
            ) or (len(buffer) > 4 and buffer[4] > MAX_ERROR_BYTE):
                # FF FF FF ...: the first FF was noise; a broadcast id, a length or an error
                # byte that cannot be (the vendor SDK rejects the same): not a status packet.
                # Move one byte on and hunt again.
                self.skipped_bytes += 1
                del buffer[0]
                continue
            total = length + 4
            if len(buffer) < total:
                return found
            body = bytes(buffer[2 : total - 1])
            if checksum(body) != buffer[total - 1]:
                self.bad_checksums += 1
                self.skipped_bytes += 1
                del buffer[0]
                continue
            found.append(StatusPacket(servo_id, body[2], body[3:]))
            del buffer[:total]
