"""A simulated STS servo bus, byte-faithful, that the real ``scservo_sdk`` (or any client) talks to.

Two layers:

`SimBus`
    The servos on the wire: it takes the bytes the host sends, finds instruction packets in
    them byte by byte, applies them to `SimServo` control tables and returns the status
    packets the servos would send, with checksums, error bits and injected faults. It knows
    nothing about time except the instant each packet finished arriving.
`SimSerial`
    An object with pyserial's ``Serial`` interface (``write``, ``read``, ``in_waiting``,
    ``flush``, ...) that the driver sets as ``PortHandler.ser``. It charges wire time at the
    baud rate (10 bits a byte) and each servo's return delay against a `Clock`, so a read
    returns only the bytes that have arrived by now; with a `VirtualClock`, waiting for them
    advances virtual time instead of sleeping.

`pinarray.hardware.feetech.serve` puts the same `SimBus` behind a pseudo-terminal instead.

Who answers what (Feetech communication protocol manual V1.01): PING always answers, also at
the broadcast id; READ and SYNC READ answer with data; WRITE, REG WRITE, ACTION and RESET
answer only at status return level 1 and never at the broadcast id. The answer carries the
id the instruction addressed, also when the instruction changed that id. A request a servo
cannot carry out (an unknown instruction, parameters missing, a READ whose answer would be
longer than the longest packet the firmware sends) gets no answer: the STS error byte has no
bit for it.

Past 400 lines on purpose: the simulated wire (packet framing, faults, replies) and its
pyserial face are one device as a client sees it.
"""

from __future__ import annotations

import random
from bisect import bisect_right, insort
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from operator import itemgetter

import serial

from pinarray.clock import Clock
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.models import FACTORY_RETURN_DELAY_US, servo_model
from pinarray.hardware.feetech.packets import MAX_PACKET_BYTES, status_size
from pinarray.hardware.feetech.registers import (
    BAUD_RATE_BY_CODE,
    BROADCAST_ID,
    WRITE_INSTRUCTIONS,
    Instruction,
    StatusError,
    checksum,
)
from pinarray.hardware.feetech.sim_servo import SimServo
from pinarray.hardware.feetech.sim_wire import (
    StatusReply,
    Transmission,
    byte_time_ns,
    schedule,
)

# Instructions that only ask: no servo's id can change by them.
ASKING = frozenset({Instruction.PING, Instruction.READ, Instruction.SYNC_READ})
# Instruction codes as plain ints, for the comparisons every packet makes.
_PING, _READ = int(Instruction.PING), int(Instruction.READ)
_SYNC_READ, _SYNC_WRITE = int(Instruction.SYNC_READ), int(Instruction.SYNC_WRITE)
# The longest READ answer one status packet can carry, in data bytes.
_LONGEST_READ = MAX_PACKET_BYTES - status_size(0)
# How long a read on an empty line waits before returning nothing; the SDK polls in a loop.
POLL_NS = 500_000
# The port keeps the last this many writes for a test to look at (a log, bounded: a long
# batch writes hundreds of thousands of packets).
WRITE_LOG = 1024
# Bytes read are dropped from the incoming queue once there are this many.
COMPACT_BYTES = 4096

__all__ = ["InstructionPacket", "SimBus", "SimSerial", "StatusReply", "status_packet"]


@dataclass(frozen=True)
class InstructionPacket:
    """One well-formed instruction packet as it arrived at the servos.

    ``end_ns`` is when its last byte arrived; ``delivered`` is False when an injected fault
    lost it on the wire.
    """

    end_ns: int
    servo_id: int
    instruction: int
    params: bytes
    delivered: bool


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """``FF FF id len err params chk`` with ``len = len(params) + 2``."""
    body = bytes((servo_id, len(params) + 2, error)) + params
    return b"\xff\xff" + body + bytes((checksum(body),))


def _fits(length: int) -> bool:
    """Whether an answer of ``length`` data bytes fits in one packet the servos can send."""
    return length <= _LONGEST_READ


class SimBus:
    """The servos on a simulated wire, with fault injection.

    Parameters
    ----------
    config : SimConfig
        Which ids answer, their wire settings and physics, and the faults to inject.
    clock : Clock
        Time source; the servos power on at its current time.
    follow_host_baud : bool, optional
        With no ``baud`` in the config, let the servos listen at the first speed the host
        uses (one of the STS rates). Default: True in-process; the pseudo-terminal server
        passes False, so its servos sit at the factory 1000000 bit/s.
    """

    def __init__(self, config: SimConfig, clock: Clock, follow_host_baud: bool = True):
        self.config = config
        self.clock = clock
        self.servos: dict[int, SimServo] = {
            servo_id: self._new_servo(servo_id, config.return_delay_us, config.baud_rate)
            for servo_id in config.answering_ids
        }
        for servo_id, bits in config.faults.error_bits:
            if servo_id in self.servos:
                self.servos[servo_id].error_bits = StatusError(bits)
        faults = config.faults
        self.drop_rate = faults.drop_rate
        self.drop_write_rate = faults.drop_write_rate
        self.corrupt_rate = faults.corrupt_rate
        self.late_rate = faults.late_rate
        self.late_ns = faults.late_ns
        self.vanish_after_packets = faults.vanish_after_packets
        self.drop_next = 0
        self.drop_writes_next = 0
        self.corrupt_next = 0
        self.late_next = 0
        self.packets_received = 0
        self.packets_rejected = 0
        self.packet_listener: Callable[[InstructionPacket], None] | None = None
        # The wire the host talks on, set by the port in front of the bus (SimSerial, PtyServer).
        self.byte_ns = 0.0
        self.host_baud_rate: int | None = None
        self._follow_baud = follow_host_baud and config.baud_rate is None
        self._setup_baud_rate = config.baud_rate
        self._shadowed: list[SimServo] = []  # servos renumbered onto an id already taken
        self._random = random.Random(faults.seed)
        self._buffer = bytearray()

    @property
    def vanished(self) -> bool:
        """True once the port has "disappeared" (see ``vanish_after``)."""
        limit = self.vanish_after_packets
        return limit is not None and self.packets_received >= limit

    def receive(
        self, data: bytes, at_ns: int, byte_ns: float | None = None, baud_rate: int | None = None
    ) -> list[StatusReply]:
        """Bytes from the host, the last of which arrived at ``at_ns``; returns the answers.

        Parameters
        ----------
        data : bytes
            What the host sent (any split of packets).
        at_ns : int
            When the last byte of ``data`` arrived, in nanoseconds.
        byte_ns : float, optional
            Wire time of one byte, so packets earlier in ``data`` get earlier arrival times;
            default `byte_ns`, which the port in front of the bus keeps up to date.
        baud_rate : int, optional
            The host's speed in bit/s (default `host_baud_rate`); servos listening at another
            speed hear only noise. None: unknown, every servo hears.
        """
        byte_ns = self.byte_ns if byte_ns is None else byte_ns
        baud_rate = self.host_baud_rate if baud_rate is None else baud_rate
        self._buffer.extend(data)
        if self._follow_baud and baud_rate in BAUD_RATE_BY_CODE:
            self._follow_baud = False
            self._setup_baud_rate = baud_rate
            for servo in self.all_servos():
                servo.set_up_baud(baud_rate)
        replies: list[StatusReply] = []
        if len(self._buffer) < 4:  # the tail of a packet to come: nothing whole yet
            return replies
        while (packet := self._next_packet()) is not None:
            servo_id, instruction, params = packet
            end_ns = at_ns - round(len(self._buffer) * byte_ns)
            self.packets_received += 1
            delivered = not self._lost(instruction)
            if self.packet_listener is not None:
                self.packet_listener(
                    InstructionPacket(end_ns, servo_id, instruction, params, delivered)
                )
            if delivered:
                replies.extend(self._execute(servo_id, instruction, params, end_ns, baud_rate))
                if instruction not in ASKING:
                    self._renumber()
        return replies

    def _lost(self, instruction: int) -> bool:
        if not (self.drop_next or self.drop_rate or self.drop_writes_next
                or self.drop_write_rate):
            return False  # the usual wire: nothing is lost
        if self.drop_next > 0:
            self.drop_next -= 1
            return True
        if self.drop_rate and self._random.random() < self.drop_rate:
            return True
        if instruction in WRITE_INSTRUCTIONS:
            if self.drop_writes_next > 0:
                self.drop_writes_next -= 1
                return True
            if self.drop_write_rate and self._random.random() < self.drop_write_rate:
                return True
        return False

    def _next_packet(self) -> tuple[int, int, bytes] | None:
        buffer = self._buffer
        if not buffer:
            return None
        size = len(buffer)
        if (size >= 6 and buffer[0] == 0xFF and buffer[1] == 0xFF and buffer[2] != 0xFF
                and buffer[3] >= 2 and size == buffer[3] + 4):
            # The usual case, the loop below's first round: one whole packet and nothing else.
            packet = bytes(buffer)
            buffer.clear()
            if checksum(packet[2:-1]) != packet[-1]:
                self.packets_rejected += 1
                return None
            return packet[2], packet[4], packet[5:-1]
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
            if len(buffer) == total:
                buffer.clear()
            else:
                del buffer[:total]
            if checksum(packet[2:-1]) != packet[-1]:
                self.packets_rejected += 1  # a servo silently ignores a bad checksum
                continue
            return packet[2], packet[4], packet[5:-1]

    # -- who is on the bus ---------------------------------------------------------------

    def all_servos(self) -> list[SimServo]:
        """Every servo on the bus, also those renumbered onto an id another one has."""
        return [*self.servos.values(), *self._shadowed]

    def _new_servo(self, servo_id: int, return_delay_us: int, baud_rate: int | None) -> SimServo:
        config = self.config
        model = servo_model(config.model)
        backlash = None if config.backlash_deg is None else (
            config.backlash_deg * model.steps_per_turn / 360.0
        )
        return SimServo(
            servo_id,
            self.clock.now_ns(),
            return_delay_us=return_delay_us,
            model=model,
            baud_rate=baud_rate or 1_000_000,
            supply_v=config.supply_v,
            backlash_steps=backlash,
            load_fraction=config.load_fraction,
            top_speed_steps_per_s=config.speed_steps_per_s,
        )

    def plug_in(self, servo_id: int = 1) -> SimServo:
        """A factory-fresh servo joins the bus (at id 1, as shipped); shares a taken id.

        It listens at the speed the bus was set up with (the URL's ``baud``, or the host's
        first speed in-process, else the factory's 1000000 bit/s).
        """
        servo = self._new_servo(servo_id, FACTORY_RETURN_DELAY_US, self._setup_baud_rate)
        if servo_id in self.servos:
            self._shadowed.append(servo)
        else:
            self.servos[servo_id] = servo
        return servo

    def power_cycle(self) -> None:
        """Switch the servos' supply off and on: unsaved EEPROM values and RAM are lost."""
        now_ns = self.clock.now_ns()
        for servo in self.all_servos():
            servo.power_cycle(now_ns)
        self._renumber()

    def reopen(self, clock: Clock) -> None:
        """A new connection opens the port, on ``clock``: the servos were powered all along.

        Closing a port does nothing to servos, and releasing them only turns torque off: RAM
        and EEPROM stay as they were (a return delay lowered until power-off included). The
        time since the last connection passed with nobody talking: the servos go on from the
        new clock's now (moves ended), and the injected faults count from the new port's
        first packet, as a new bus's would.
        """
        if clock is not self.clock:
            now_ns = clock.now_ns()
            for servo in self.all_servos():
                servo.carry_on_at(now_ns)
            self.clock = clock
        self._buffer.clear()  # half a packet on a closed port never ends
        self.packets_received = 0
        self.packets_rejected = 0

    def _at(self, servo_id: int, baud_rate: int | None) -> list[SimServo]:
        """Every servo answering at ``servo_id`` that hears the host's speed."""
        servo = self.servos.get(servo_id)
        found = [servo] if servo is not None and servo.hears(baud_rate) else []
        if self._shadowed:
            found += [s for s in self._shadowed if s.servo_id == servo_id and s.hears(baud_rate)]
        return found

    def _renumber(self) -> None:
        """Keep `servos` keyed by each servo's current ID register after an ID write."""
        moved = [s for key, s in self.servos.items() if s.servo_id != key]
        if not moved and not self._shadowed:
            return
        for key in [key for key, s in self.servos.items() if s.servo_id != key]:
            del self.servos[key]
        waiting, self._shadowed = [*moved, *self._shadowed], []
        for servo in waiting:
            if servo.servo_id in self.servos:
                self._shadowed.append(servo)  # two servos now share an id: both answer
            else:
                self.servos[servo.servo_id] = servo

    # -- instructions --------------------------------------------------------------------

    def _execute(
        self, servo_id: int, instruction: int, params: bytes, end_ns: int, baud: int | None
    ) -> list[StatusReply]:
        broadcast = servo_id == BROADCAST_ID
        if instruction == _READ and not broadcast:  # the usual request: one servo's bytes
            if len(params) != 2 or not _fits(params[1]):
                return []
            return [self._reply(servo, servo_id, servo.read(params[0], params[1], end_ns), end_ns)
                    for servo in self._at(servo_id, baud)]
        if instruction == _SYNC_WRITE:
            if broadcast and len(params) >= 2:
                self._sync_write(params, end_ns, baud)
            return []
        if instruction == _SYNC_READ:
            if not broadcast or len(params) < 2 or not _fits(params[1]):
                return []
            address, length = params[0], params[1]
            return [
                self._reply(servo, target, servo.read(address, length, end_ns), end_ns, True)
                for target in params[2:]
                for servo in self._at(target, baud)
            ]
        targets = (
            [s for s in self.all_servos() if s.hears(baud)] if broadcast
            else self._at(servo_id, baud)
        )
        replies = []
        for servo in targets:
            answer = self._apply(servo, instruction, params, end_ns)
            if answer is None:
                continue
            if instruction == Instruction.PING:
                # PING answers at the broadcast id too, with the servo's own id.
                replies.append(self._reply(servo, servo.servo_id, b"", end_ns))
            elif not broadcast and (
                instruction == Instruction.READ or servo.status_return_level >= 1
            ):
                replies.append(self._reply(servo, servo_id, answer, end_ns))
        return replies

    def _apply(
        self, servo: SimServo, instruction: int, params: bytes, end_ns: int
    ) -> bytes | None:
        """Carry out one instruction on one servo; its answer's parameters, or None (ignored)."""
        match instruction:
            case Instruction.PING:
                return b""
            case Instruction.READ if len(params) == 2 and _fits(params[1]):
                return servo.read(params[0], params[1], end_ns)
            case Instruction.WRITE if len(params) >= 1:
                servo.write(params[0], params[1:], end_ns)
                return b""
            case Instruction.REG_WRITE if len(params) >= 1:
                servo.reg_write(params[0], params[1:])
                return b""
            case Instruction.ACTION:
                servo.action(end_ns)
                return b""
            case Instruction.RESET:
                servo.factory_reset(end_ns)
                return b""
            case Instruction.CLEAR_STATUS:
                return b""  # nothing to clear in position mode; acknowledged
            case Instruction.REBOOT:
                servo.power_cycle(end_ns)
                return None  # it is busy restarting: no answer
        return None

    def _sync_write(self, params: bytes, end_ns: int, baud: int | None) -> None:
        address, length = params[0], params[1]
        body = params[2:]
        for offset in range(0, len(body) - length, length + 1):
            for servo in self._at(body[offset], baud):
                servo.write(address, body[offset + 1 : offset + 1 + length], end_ns)

    def _reply(
        self, servo: SimServo, reply_id: int, params: bytes, end_ns: int, chained: bool = False
    ) -> StatusReply:
        packet = status_packet(reply_id, servo.status_error_byte, params)
        if not (self.corrupt_next or self.corrupt_rate or self.late_next or self.late_rate):
            return StatusReply(servo.return_delay_ns, packet, end_ns, chained, 0)
        corrupt = self.corrupt_next > 0 or (
            self.corrupt_rate and self._random.random() < self.corrupt_rate
        )
        if corrupt:
            self.corrupt_next = max(0, self.corrupt_next - 1)
            packet = packet[:-1] + bytes((packet[-1] ^ 0x5A,))  # a flip the checksum cannot miss
        late = self.late_next > 0 or (self.late_rate and self._random.random() < self.late_rate)
        if late:
            self.late_next = max(0, self.late_next - 1)
        return StatusReply(
            servo.return_delay_ns, packet, end_ns, chained, self.late_ns if late else 0
        )


class SimSerial:
    """pyserial's ``Serial`` interface over a `SimBus`, charging wire time against a clock.

    Parameters
    ----------
    bus : SimBus
        The simulated servos.
    clock : Clock
        Time source; a `VirtualClock` makes every wait instantaneous and deterministic.
    baud_rate : int
        Bits per second; each byte costs 10 bit times (start, 8 data, stop). Changing
        ``baudrate`` later (as pyserial allows) changes the wire speed.
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
        self.writes: deque[bytes] = deque(maxlen=WRITE_LOG)
        self._tx_done_ns = 0
        self._wire_free_ns = 0
        # Bytes on their way to the host, in arrival order: each byte's arrival time (rising)
        # and value; everything before `_head` has been read.
        self._arrival_ns: list[int] = []
        self._data = bytearray()
        self._head = 0
        # When each transmission queued (a status packet, or garbled ones merged) is whole at
        # the host, rising: what `readable_at_ns` tells a reader that waits for bytes.
        self._ends_ns: list[int] = []

    @property
    def baudrate(self) -> int:
        return self._baud_rate

    @baudrate.setter
    def baudrate(self, baud_rate: int) -> None:
        if not baud_rate > 0:
            raise ValueError(f"baud rate must be positive, found {baud_rate}")
        self._baud_rate = baud_rate
        self._byte_ns = byte_time_ns(baud_rate)

    def _check_alive(self, what: str) -> None:
        if not self.is_open:
            raise serial.PortNotOpenError()
        if self.bus.vanished:
            # The words pyserial uses when a USB adapter is pulled out mid-run.
            raise serial.SerialException(f"{what} failed: [Errno 5] Input/output error")

    def write(self, data: bytes) -> int:
        if not self.is_open or self.bus.vanished:
            self._check_alive("write")
        if type(data) is not bytes:
            data = bytes(data)
        start_ns = max(self.clock.now_ns(), self._wire_free_ns)
        end_ns = start_ns + round(len(data) * self._byte_ns)
        self._tx_done_ns = self._wire_free_ns = end_ns
        self.bytes_written += len(data)
        self.writes.append(data)
        self.bus.byte_ns, self.bus.host_baud_rate = self._byte_ns, self._baud_rate
        replies = self.bus.receive(data, end_ns)
        if replies:
            arriving, self._wire_free_ns = schedule(replies, self._wire_free_ns, self._byte_ns)
            self._queue(arriving, any(reply.late_ns for reply in replies))
        return len(data)

    def _queue(self, arriving: list[Transmission], late: bool) -> None:
        """Put transmissions on their way to the host, every byte at its own arrival time
        (``late``: one of them was made late, and may overlap or overtake the others)."""
        times, data, head = self._arrival_ns, self._data, self._head
        if head == len(times):
            if head:  # everything queued so far was read: start the queue again
                times.clear()
                data.clear()
                self._head = head = 0
        elif head > COMPACT_BYTES and 2 * head > len(times):
            del times[:head], data[:head]
            self._head = head = 0
        in_order = len(times) == head or times[-1] <= arriving[0].arrival_ns(0)
        for sent in arriving:
            start_ns, byte_ns = sent.start_ns, sent.byte_ns  # `Transmission.arrival_ns`, inline
            step_ns = int(byte_ns)
            if step_ns == byte_ns:  # 1 Mbit/s and the other round rates: whole ns a byte
                times.extend(range(start_ns + step_ns, start_ns + step_ns * len(sent.data) + 1,
                                   step_ns))
            else:
                times.extend([start_ns + round(index * byte_ns)
                              for index in range(1, len(sent.data) + 1)])
            data += sent.data
            insort(self._ends_ns, times[-1])
        if late or not in_order:
            # Bytes reach the host in time order; of two arriving together, the one queued
            # first is read first.
            pending = sorted(zip(times[head:], data[head:], strict=True), key=itemgetter(0))
            times[head:] = [arrival_ns for arrival_ns, _ in pending]
            data[head:] = bytes(byte for _, byte in pending)
        ends, now_ns = self._ends_ns, self.clock.now_ns()
        if ends[0] <= now_ns:
            del ends[: bisect_right(ends, now_ns)]

    def _arrived(self, now_ns: int) -> int:
        return bisect_right(self._arrival_ns, now_ns, self._head) - self._head

    @property
    def in_waiting(self) -> int:
        if not self.is_open or self.bus.vanished:
            self._check_alive("read")
        return bisect_right(self._arrival_ns, self.clock.now_ns(), self._head) - self._head

    def readable_at_ns(self) -> int | None:
        """When the next transmission still on its way is whole at the host (None: none is).

        A reader waiting for bytes waits on the clock until then (in virtual time, one jump)
        instead of polling; the bytes and their arrival times are the same either way.
        """
        ends = self._ends_ns
        index = bisect_right(ends, self.clock.now_ns())
        return ends[index] if index < len(ends) else None

    def read(self, size: int = 1) -> bytes:
        if not self.is_open or self.bus.vanished:
            self._check_alive("read")
        now_ns = self.clock.now_ns()
        pending = len(self._arrival_ns) - self._head
        if size > 0 and self._arrived(now_ns) == 0:
            # Nothing yet: wait for the bytes asked for, but at most one poll period, so a
            # late answer stays late and the host's own timeout decides.
            wait_until_ns = now_ns + POLL_NS
            if pending:
                wanted = min(size, pending)
                wait_until_ns = min(wait_until_ns, self._arrival_ns[self._head + wanted - 1])
            self.clock.sleep_until_ns(wait_until_ns)
            now_ns = self.clock.now_ns()
        count = min(size, self._arrived(now_ns))
        head = self._head
        data = bytes(self._data[head : head + count])
        self._head = head + count
        self.bytes_read += count
        return data

    def flush(self) -> None:
        """Wait until everything written has left the adapter (pyserial: ``tcdrain``)."""
        self.clock.sleep_until_ns(self._tx_done_ns)

    def reset_input_buffer(self) -> None:
        self._head += self._arrived(self.clock.now_ns())

    def close(self) -> None:
        self.is_open = False
