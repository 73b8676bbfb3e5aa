"""A simulated STS servo bus, byte-faithful, that the real ``scservo_sdk`` talks to.

Two layers:

`SimBus`
    The servos on the wire: it takes the bytes the host sends, finds instruction packets in
    them byte by byte, applies them to `SimServo` control tables and returns the status
    packets the servos would send, with checksums, error bits and injected faults. It knows
    nothing about time except the instant a packet finished arriving.
`SimSerial`
    An object with pyserial's ``Serial`` interface (``write``, ``read``, ``in_waiting``,
    ``flush``, ...) that the driver sets as ``PortHandler.ser``. It charges wire time at the
    baud rate (10 bits a byte) and each servo's return delay against a `Clock`, so a read
    returns only the bytes that have arrived by now; with a `VirtualClock`, waiting for them
    advances virtual time instead of sleeping.

`pinarray.bus.serve` puts the same `SimBus` behind a pseudo-terminal instead.
"""

from __future__ import annotations

import random
from collections import deque
from dataclasses import dataclass

import serial

from pinarray.bus.faults import SimConfig
from pinarray.bus.registers import BROADCAST_ID, StatusError, checksum
from pinarray.bus.sim_servo import SimServo
from pinarray.clock import Clock

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83

# How long a read on an empty line waits before returning nothing; the SDK polls in a loop.
POLL_NS = 500_000


@dataclass(frozen=True)
class StatusReply:
    """A status packet a servo sends ``delay_ns`` after the instruction finished arriving."""

    delay_ns: int
    packet: bytes


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """``FF FF id len err params chk`` with ``len = len(params) + 2``."""
    body = bytes([servo_id, len(params) + 2, error]) + params
    return b"\xff\xff" + body + bytes([checksum(body)])


class SimBus:
    """The servos on a simulated wire, with fault injection.

    Parameters
    ----------
    config : SimConfig
        Which ids answer, their return delay, and the faults to inject.
    clock : Clock
        Time source the servos' motion is integrated against.
    """

    def __init__(self, config: SimConfig, clock: Clock):
        self.config = config
        self.clock = clock
        start_ns = clock.now_ns()
        self.servos: dict[int, SimServo] = {
            servo_id: SimServo(servo_id, start_ns, return_delay_us=config.return_delay_us)
            for servo_id in config.answering_ids
        }
        for servo_id, bits in config.faults.error_bits:
            if servo_id in self.servos:
                self.servos[servo_id].error_bits = StatusError(bits)
        self.drop_rate = config.faults.drop_rate
        self.corrupt_rate = config.faults.corrupt_rate
        self.vanish_after_packets = config.faults.vanish_after_packets
        self.drop_next = 0
        self.corrupt_next = 0
        self.packets_received = 0
        self.packets_rejected = 0
        self._random = random.Random(config.faults.seed)
        self._buffer = bytearray()

    @property
    def vanished(self) -> bool:
        """True once the port has "disappeared" (see ``vanish_after``)."""
        limit = self.vanish_after_packets
        return limit is not None and self.packets_received >= limit

    def advance_all(self, now_ns: int) -> None:
        """Bring every servo's motion up to ``now_ns`` (e.g. before reading trajectories)."""
        for servo in self.servos.values():
            servo.advance_to(now_ns)

    def receive(self, data: bytes, at_ns: int) -> list[StatusReply]:
        """Bytes from the host, the last of which arrived at ``at_ns``; returns the answers."""
        self._buffer.extend(data)
        replies: list[StatusReply] = []
        while (packet := self._next_packet()) is not None:
            servo_id, instruction, params = packet
            self.packets_received += 1
            if self.drop_next > 0:
                self.drop_next -= 1
                continue
            if self.drop_rate and self._random.random() < self.drop_rate:
                continue
            replies.extend(self._execute(servo_id, instruction, params, at_ns))
        return replies

    def _next_packet(self) -> tuple[int, int, bytes] | None:
        buffer = self._buffer
        while True:
            # Hunt for the FF FF header one byte at a time, as the servo's UART does.
            while len(buffer) >= 2 and not (buffer[0] == 0xFF and buffer[1] == 0xFF):
                del buffer[0]
            while len(buffer) >= 3 and buffer[2] == 0xFF:
                del buffer[0]  # FF FF FF: the first FF was noise
            if len(buffer) < 4:
                return None
            total = buffer[3] + 4
            if buffer[3] < 2:
                del buffer[:2]
                continue
            if len(buffer) < total:
                return None
            packet = bytes(buffer[:total])
            del buffer[:total]
            if checksum(packet[2:-1]) != packet[-1]:
                self.packets_rejected += 1  # a servo silently ignores a bad checksum
                continue
            return packet[2], packet[4], packet[5:-1]

    def _execute(self, servo_id: int, instruction: int, params: bytes, at_ns: int):
        if instruction == INST_SYNC_WRITE and servo_id == BROADCAST_ID and len(params) >= 2:
            address, length = params[0], params[1]
            body = params[2:]
            for offset in range(0, len(body) - length, length + 1):
                target = self.servos.get(body[offset])
                if target is not None:
                    target.write(address, body[offset + 1 : offset + 1 + length], at_ns)
            return []
        if instruction == INST_SYNC_READ and servo_id == BROADCAST_ID and len(params) >= 2:
            address, length = params[0], params[1]
            return [
                self._reply(self.servos[i], self.servos[i].read(address, length, at_ns))
                for i in params[2:]
                if i in self.servos
            ]
        servo = self.servos.get(servo_id)
        if servo_id == BROADCAST_ID and instruction == INST_WRITE and len(params) >= 1:
            for each in self.servos.values():
                each.write(params[0], params[1:], at_ns)
            return []
        if servo is None:
            return []
        if instruction == INST_PING:
            return [self._reply(servo)]
        if instruction == INST_READ and len(params) == 2:
            return [self._reply(servo, servo.read(params[0], params[1], at_ns))]
        if instruction == INST_WRITE and len(params) >= 1:
            servo.write(params[0], params[1:], at_ns)
            return [self._reply(servo)]
        return []

    def _reply(self, servo: SimServo, params: bytes = b"") -> StatusReply:
        packet = bytearray(status_packet(servo.servo_id, int(servo.error_bits), params))
        corrupt = self.corrupt_next > 0 or (
            self.corrupt_rate and self._random.random() < self.corrupt_rate
        )
        if corrupt:
            self.corrupt_next = max(0, self.corrupt_next - 1)
            packet[-1] ^= 0x5A  # a flipped bit pattern the checksum cannot miss
        return StatusReply(servo.return_delay_ns, bytes(packet))


class SimSerial:
    """pyserial's ``Serial`` interface over a `SimBus`, charging wire time against a clock.

    Parameters
    ----------
    bus : SimBus
        The simulated servos.
    clock : Clock
        Time source; a `VirtualClock` makes every wait instantaneous and deterministic.
    baud_rate : int
        Bits per second; each byte costs 10 bit times (start, 8 data, stop).
    """

    def __init__(self, bus: SimBus, clock: Clock, baud_rate: int, port: str = "sim://"):
        self.bus = bus
        self.clock = clock
        self.port = port
        self.baudrate = baud_rate
        self.timeout = 0
        self.is_open = True
        self.bytes_written = 0
        self.bytes_read = 0
        self.writes: deque[bytes] = deque(maxlen=100_000)
        self._byte_ns = 10 * 1_000_000_000 / baud_rate
        self._tx_done_ns = 0
        self._wire_free_ns = 0
        self._incoming: deque[tuple[int, int]] = deque()  # (arrival_ns, byte)

    def _check_alive(self, what: str) -> None:
        if not self.is_open:
            raise serial.PortNotOpenError()
        if self.bus.vanished:
            # The words pyserial uses when a USB adapter is pulled out mid-run.
            raise serial.SerialException(f"{what} failed: [Errno 5] Input/output error")

    def write(self, data) -> int:
        self._check_alive("write")
        data = bytes(data)
        start_ns = max(self.clock.now_ns(), self._wire_free_ns)
        end_ns = start_ns + round(len(data) * self._byte_ns)
        self._tx_done_ns = self._wire_free_ns = end_ns
        self.bytes_written += len(data)
        self.writes.append(data)
        for reply in self.bus.receive(data, end_ns):
            # Half duplex: each answer waits for the line to be free, then its return delay.
            first_ns = self._wire_free_ns + reply.delay_ns
            for index, byte in enumerate(reply.packet):
                self._incoming.append((first_ns + round((index + 1) * self._byte_ns), byte))
            self._wire_free_ns = first_ns + round(len(reply.packet) * self._byte_ns)
        return len(data)

    def _arrived(self, now_ns: int) -> int:
        count = 0
        for arrival_ns, _ in self._incoming:
            if arrival_ns > now_ns:
                break
            count += 1
        return count

    @property
    def in_waiting(self) -> int:
        self._check_alive("read")
        return self._arrived(self.clock.now_ns())

    def read(self, size: int = 1) -> bytes:
        self._check_alive("read")
        now_ns = self.clock.now_ns()
        if size > 0 and self._arrived(now_ns) == 0:
            if self._incoming:
                wanted = min(size, len(self._incoming))
                self.clock.sleep_until_ns(self._incoming[wanted - 1][0])
            else:
                self.clock.sleep_until_ns(now_ns + POLL_NS)
            now_ns = self.clock.now_ns()
        count = min(size, self._arrived(now_ns))
        data = bytes(self._incoming.popleft()[1] for _ in range(count))
        self.bytes_read += len(data)
        return data

    def flush(self) -> None:
        """Wait until everything written has left the adapter (pyserial: ``tcdrain``)."""
        self.clock.sleep_until_ns(self._tx_done_ns)

    def reset_input_buffer(self) -> None:
        now_ns = self.clock.now_ns()
        for _ in range(self._arrived(now_ns)):
            self._incoming.popleft()

    def close(self) -> None:
        self.is_open = False
