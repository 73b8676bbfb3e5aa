"""The simulated bus's pyserial face: `SimSerial`, bytes charged wire time against a clock.

An object with pyserial's ``Serial`` interface (``write``, ``read``, ``in_waiting``,
``flush``, ...) in front of a `pinarray.hardware.feetech.sim.SimBus`. A write reaches the
servos when its last byte has crossed the wire at the baud rate (10 bits a byte); their
answers come back byte by byte, each byte at its own arrival time, after each servo's return
delay (`pinarray.hardware.feetech.sim_wire`), so a read returns only the bytes that have
arrived by now; with a `VirtualClock`, waiting for them advances virtual time instead of
sleeping.

Bytes on their way are queued a transmission at a time (a status packet, or garbled ones
merged): its bytes and their arrival times, which for the round baud rates are a `range`
(one byte every whole number of ns), so a packet costs the same at any length. Transmissions
that overlap in time (an answer made late, overtaking or overlapping others) are merged into
one, byte by byte in time order, as they reach the host.
"""

from __future__ import annotations

from bisect import bisect_right, insort
from collections import deque
from collections.abc import Sequence
from operator import itemgetter
from typing import TYPE_CHECKING

import serial

from pinarray.clock import Clock
from pinarray.hardware.feetech.sim_wire import (
    Answer,
    StatusReply,
    Transmission,
    byte_time_ns,
    schedule,
    status_packet,
)

if TYPE_CHECKING:
    from pinarray.hardware.feetech.sim import SimBus

# How long a read on an empty line waits before returning nothing; the SDK polls in a loop.
POLL_NS = 500_000
# The port keeps the last this many writes for a test to look at (a log, bounded: a long
# batch writes hundreds of thousands of packets).
WRITE_LOG = 1024

# One transmission on its way: each byte's arrival time (rising) and the bytes.
Arrivals = tuple[Sequence[int], bytes]


def arrivals(sent: Transmission) -> Arrivals:
    """``sent``'s bytes with their arrival times (`Transmission.arrival_ns`, for every byte)."""
    start_ns, byte_ns, count = sent.start_ns, sent.byte_ns, len(sent.data)
    step_ns = int(byte_ns)
    if step_ns == byte_ns:  # 1 Mbit/s and the other round rates: whole ns a byte
        return range(start_ns + step_ns, start_ns + step_ns * count + 1, step_ns), sent.data
    return [start_ns + round(index * byte_ns) for index in range(1, count + 1)], sent.data


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
        # Transmissions on their way to the host, in arrival order, none overlapping the
        # next; the first `_offset` bytes of the first one have been read.
        self._queued: deque[Arrivals] = deque()
        self._offset = 0
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
        # A byte's whole ns at the round rates (1 Mbit/s: 10 000), else 0 (`arrivals`).
        step_ns = int(self._byte_ns)
        self._step_ns = step_ns if step_ns == self._byte_ns else 0

    @property
    def wire_free_ns(self) -> int:
        """When the line is free of the host's writes and the servos' answers (clock ns)."""
        return self._wire_free_ns

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
        end_ns = self._transmit(data)
        replies = self.bus.receive(data, end_ns)
        if len(replies) == 1 and not replies[0].late_ns and not self._queued:
            self._queue_alone(replies[0], end_ns)
        elif replies:
            arriving, self._wire_free_ns = schedule(replies, end_ns, self._byte_ns)
            self._queue(arriving, any(reply.late_ns for reply in replies))
        return len(data)

    def _queue_alone(self, reply: StatusReply, line_free_ns: int) -> None:
        """`schedule` and `_queue` of one answer on time while nothing else is on its way (the
        usual exchange: a request, its answer), fused: the same start (`schedule`'s one-reply
        case), the same arrival times (`arrivals`), the same line free time and ends, with
        nothing to merge (an empty queue is in order). This runs for every exchange."""
        after_ns = reply.instruction_end_ns
        if reply.chained and after_ns < line_free_ns:
            after_ns = line_free_ns
        start_ns, data, step_ns = after_ns + reply.delay_ns, reply.packet, self._step_ns
        if step_ns:  # `arrivals` at a round rate, the same range written out
            whole_ns = start_ns + step_ns * len(data)
            times: Sequence[int] = range(start_ns + step_ns, whole_ns + 1, step_ns)
        else:
            times, data = arrivals(Transmission(start_ns, data, self._byte_ns))
            whole_ns = times[-1]
        self._wire_free_ns = whole_ns if whole_ns > line_free_ns else line_free_ns
        self._queued.append((times, data))
        ends = self._ends_ns
        insort(ends, whole_ns)
        now_ns = self.clock.now_ns()
        if ends[0] <= now_ns:
            del ends[: bisect_right(ends, now_ns)]

    def _transmit(self, data: bytes) -> int:
        """``data`` onto the wire after whatever is on it; when its last byte has arrived."""
        start_ns = self.clock.now_ns()
        if start_ns < self._wire_free_ns:
            start_ns = self._wire_free_ns
        step_ns = self._step_ns  # at a round rate, the product below is whole: no rounding
        end_ns = start_ns + (len(data) * step_ns if step_ns else round(len(data) * self._byte_ns))
        self._tx_done_ns = self._wire_free_ns = end_ns
        self.bytes_written += len(data)
        self.writes.append(data)
        bus = self.bus
        bus.byte_ns, bus.host_baud_rate = self._byte_ns, self._baud_rate
        return end_ns

    @property
    def byte_ns(self) -> float:
        """Wire time of one byte at the port's speed, in nanoseconds."""
        return self._byte_ns

    def computable(self) -> bool:
        """Whether an exchange written now can be computed whole (the packet level): nothing
        on its way to the host, and nothing at the servos that acts on bytes (a half packet,
        a fault that corrupts or delays answers, a port about to vanish, a speed to learn)."""
        return not self._queued and self.is_open and self.bus.whole_packets

    def write_whole(self, packet: bytes, servo_id: int, instruction: int,
                    params: bytes) -> tuple[int, list[Answer]]:
        """`write` of one whole instruction packet (``servo_id``, ``instruction``,
        ``params``): the same time on the wire, the same answers carried out, returned (with
        when the request was whole at the servos) instead of queued byte by byte. Only when
        `computable`; the caller puts the answers on their way (`answered`, `put_on_wire`)."""
        end_ns = self._transmit(packet)
        return end_ns, self.bus.carry_out(servo_id, instruction, params, end_ns, self._baud_rate)

    def answered(self, line_free_ns: int) -> None:
        """The answers of the last `write_whole` keep the line until ``line_free_ns``."""
        self._wire_free_ns = line_free_ns

    def took(self, byte_count: int) -> None:
        """An answer of `write_whole` was read whole (for the port's count)."""
        self.bytes_read += byte_count

    def put_on_wire(self, answers: Sequence[tuple[int, Answer]]) -> None:
        """Answers of `write_whole` not read whole, each from its start (ns): on their way as
        bytes, each at its own arrival time."""
        if answers:
            byte_ns = self._byte_ns
            self._queue([Transmission(start_ns, status_packet(a.reply_id, a.error, a.params),
                                      byte_ns) for start_ns, a in answers], False)

    def schedule_answers(self, answers: list[Answer], end_ns: int) -> None:
        """Answers of `write_whole` that may collide (several not waiting for the line): on
        their way as `write` puts them."""
        replies = [self.bus.reply(answer, end_ns) for answer in answers]
        arriving, self._wire_free_ns = schedule(replies, end_ns, self._byte_ns)
        self._queue(arriving, False)

    def _queue(self, arriving: list[Transmission], late: bool) -> None:
        """Put transmissions on their way to the host (``late``: one of them was made late,
        and may overlap or overtake the others)."""
        queued, ends = self._queued, self._ends_ns
        in_order = not queued or queued[-1][0][-1] <= arriving[0].arrival_ns(0)
        for sent in arriving:
            times, data = arrivals(sent)
            queued.append((times, data))
            insort(ends, times[-1])
        if late or not in_order:
            # Bytes reach the host in time order; of two arriving together, the one queued
            # first is read first.
            offset = self._offset
            pending = sorted(
                ((arrival_ns, byte) for k, (times, data) in enumerate(queued)
                 for arrival_ns, byte in zip(times[offset if not k else 0:],
                                             data[offset if not k else 0:], strict=True)),
                key=itemgetter(0))
            queued.clear()
            queued.append(([arrival_ns for arrival_ns, _ in pending],
                           bytes(byte for _, byte in pending)))
            self._offset = 0
        now_ns = self.clock.now_ns()
        if ends[0] <= now_ns:
            del ends[: bisect_right(ends, now_ns)]

    def _arrived(self, now_ns: int) -> int:
        """Bytes arrived by ``now_ns`` and not read yet."""
        offset, count = self._offset, 0
        for times, _ in self._queued:
            whole = len(times)
            arrived = bisect_right(times, now_ns, offset)
            count += arrived - offset
            if arrived < whole:
                break
            offset = 0
        return count

    def _pending(self) -> int:
        return sum(len(data) for _, data in self._queued) - self._offset

    def _arrival_ns(self, index: int) -> int:
        """When the ``index``-th byte not read yet arrives."""
        index += self._offset
        for times, _ in self._queued:
            if index < len(times):
                return times[index]
            index -= len(times)
        raise IndexError(index)

    def _take(self, count: int) -> bytes:
        """The next ``count`` bytes (all arrived), out of the queue."""
        self.bytes_read += count
        queued, offset = self._queued, self._offset
        times, data = queued[0]
        if offset + count < len(data):
            self._offset = offset + count
            return data[offset : offset + count]
        if not offset and count == len(data):  # one transmission whole (the usual read)
            queued.popleft()
            return data
        pieces = []
        while count:
            times, data = queued[0]
            taken = min(count, len(data) - offset)
            pieces.append(data[offset : offset + taken])
            count -= taken
            offset += taken
            if offset == len(data):
                queued.popleft()
                offset = 0
        self._offset = offset
        return pieces[0] if len(pieces) == 1 else b"".join(pieces)

    @property
    def in_waiting(self) -> int:
        if not self.is_open or self.bus.vanished:
            self._check_alive("read")
        return self._arrived(self.clock.now_ns()) if self._queued else 0

    def readable_at_ns(self) -> int | None:
        """When the next transmission still on its way is whole at the host (None: none is).

        A reader waiting for bytes waits on the clock until then (in virtual time, one jump)
        instead of polling; the bytes and their arrival times are the same either way.
        """
        ends = self._ends_ns
        index = bisect_right(ends, self.clock.now_ns())
        return ends[index] if index < len(ends) else None

    def read_arrived(self, deadline_ns: int) -> bytes:
        """Wait on the clock until some bytes have arrived or ``deadline_ns``; return them.

        What a reader polling `in_waiting`, waiting until `readable_at_ns` and reading what
        arrived gets, in one call (`pinarray.hardware.feetech.link.PolledWire`).
        """
        clock, ends, queued = self.clock, self._ends_ns, self._queued
        while True:
            if not self.is_open or self.bus.vanished:
                self._check_alive("read")
            now_ns = clock.now_ns()
            if queued:
                times = queued[0][0]
                if len(queued) == 1:
                    if times[-1] <= now_ns:  # one transmission, all here
                        return self._take(len(times) - self._offset)
                    if (len(ends) == 1 and now_ns < times[self._offset]
                            and times[-1] <= deadline_ns):
                        # None of it here yet, and its end the one to come (the usual
                        # wait): what the rest of this round does, without counting.
                        clock.sleep_until_ns(times[-1])
                        if self.is_open and not self.bus.vanished and times[-1] <= clock.now_ns():
                            # The next round's first test, passed: the whole transmission.
                            return self._take(len(times) - self._offset)
                        continue
                count = self._arrived(now_ns)
                if count:
                    return self._take(count)
            if now_ns >= deadline_ns:
                return b""
            index = bisect_right(ends, now_ns)
            clock.sleep_until_ns(min(deadline_ns, ends[index]) if index < len(ends)
                                 else deadline_ns)

    def read(self, size: int = 1) -> bytes:
        if not self.is_open or self.bus.vanished:
            self._check_alive("read")
        now_ns = self.clock.now_ns()
        arrived = self._arrived(now_ns) if self._queued else 0
        if size > 0 and arrived == 0:
            # Nothing yet: wait for the bytes asked for, but at most one poll period, so a
            # late answer stays late and the host's own timeout decides.
            wait_until_ns = now_ns + POLL_NS
            pending = self._pending()
            if pending:
                wait_until_ns = min(wait_until_ns, self._arrival_ns(min(size, pending) - 1))
            self.clock.sleep_until_ns(wait_until_ns)
            arrived = self._arrived(self.clock.now_ns()) if self._queued else 0
        count = min(size, arrived)
        return self._take(count) if count > 0 else b""

    def flush(self) -> None:
        """Wait until everything written has left the adapter (pyserial: ``tcdrain``)."""
        self.clock.sleep_until_ns(self._tx_done_ns)

    def reset_input_buffer(self) -> None:
        arrived = self._arrived(self.clock.now_ns()) if self._queued else 0
        if arrived:
            self._take(arrived)
            self.bytes_read -= arrived  # thrown away, not read

    def close(self) -> None:
        self.is_open = False
