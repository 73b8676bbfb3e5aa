"""Timed exchanges with the servos: bytes out, validated status packets back, within a deadline.

A `Wire` moves bytes: `FdWire` over a serial device's file descriptor (a USB adapter or a
pseudo-terminal; it waits with ``select``, never by spinning, so a servo emulator sharing the
machine is not starved), and `PolledWire` over any object with pyserial's interface (the
in-process simulator, pyserial URL handlers), which waits on the clock.

`Link.exchange` is one request and its replies, done the way the issue of late and stale
replies demands: input left over from earlier exchanges is drained first; a reply is accepted
only when its id, its length and its checksum fit the request; anything else is counted as a
stale or mismatched reply and skipped; and the wait ends at a deadline computed from the wire
time at the baud rate, the servos' return delay and the adapter's latency. Nothing here
retries: the caller decides (`pinarray.hardware.feetech.feetech`).

Past 400 lines on purpose: the wires, the latency model and the exchange are the three
halves of one job (a request and its validated replies, on time) and are read together.
"""

from __future__ import annotations

import errno
import os
import select
import termios
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from pinarray.clock import Clock
from pinarray.hardware.descriptors import readable, writable
from pinarray.hardware.feetech.packets import StatusPacket, StatusReader
from pinarray.units import NS_PER_MS

# Bits on the wire per byte: start, 8 data, stop.
BITS_PER_BYTE = 10
# The longest return delay the register can hold (254 x 2 us), assumed until read.
MAX_RETURN_DELAY_NS = 508_000
# How often a polled wire looks for bytes while it waits, in clock nanoseconds (a port that
# says when its bytes arrive, the in-process simulator, is not polled).
POLL_NS = 20_000
# A device that takes no bytes for this long is treated as gone (a full queue nobody drains).
WRITE_TIMEOUT_NS = 500_000_000
READ_CHUNK = 4096
# Draining stale input stops after this much, so a device that never stops talking cannot
# hold up a request (a bus can carry 100 kB a second at 1 Mbps).
MAX_DRAIN_BYTES = 65_536


class WireLost(OSError):
    """The device under the wire went away (USB unplugged, pseudo-terminal closed)."""


class Wire(Protocol):
    """Bytes to and from the servos."""

    name: str

    def write(self, data: bytes) -> None:
        """Hand all of ``data`` to the device in one call."""
        ...

    def read_some(self, deadline_ns: int) -> bytes:
        """Wait until some bytes have arrived or the clock reaches ``deadline_ns``; return them."""
        ...

    def discard_input(self) -> int:
        """Throw away whatever has arrived and not been read; return how many bytes."""
        ...

    def close(self) -> None: ...


class SerialPort(Protocol):
    """What a polled wire needs of a pyserial port (or the simulator's stand-in for one)."""

    @property
    def in_waiting(self) -> int: ...

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes) -> int | None: ...

    def close(self) -> None: ...


class FdWire:
    """A serial device by file descriptor, in real (monotonic) time.

    Parameters
    ----------
    fd : int
        An open, non-blocking descriptor of a tty configured for raw bytes (pyserial opens
        devices that way); a player process gets it from its parent.
    clock : Clock
        A clock on ``time.monotonic_ns``'s time base.
    name : str
        The device, for messages.
    on_close : callable, optional
        Closes the object that owns ``fd`` (e.g. the pyserial port), instead of ``os.close``.
    """

    def __init__(self, fd: int, clock: Clock, name: str, on_close: Callable[[], None] | None = None,
                 write_timeout_ns: int = WRITE_TIMEOUT_NS):
        self.fd = fd
        self.clock = clock
        self.name = name
        self.write_timeout_ns = write_timeout_ns
        self._on_close = on_close

    def write(self, data: bytes) -> None:
        try:
            written = os.write(self.fd, data)  # the usual case: one call, nothing allocated
        except BlockingIOError:
            written = 0
        except OSError as error:
            raise WireLost(error.errno, f"write failed: {error.strerror}") from None
        if written == len(data):
            return
        give_up_ns = self.clock.now_ns() + self.write_timeout_ns
        view = memoryview(data)[written:]
        while view:
            remaining_ns = give_up_ns - self.clock.now_ns()
            if remaining_ns <= 0:
                raise WireLost(errno.ETIMEDOUT, f"write failed: the device took no data for "
                                                f"{self.write_timeout_ns / 1e9:g} s")
            writable(self.fd, remaining_ns)  # the output queue is full
            try:
                written = os.write(self.fd, view)
            except BlockingIOError:
                continue
            except OSError as error:
                raise WireLost(error.errno, f"write failed: {error.strerror}") from None
            view = view[written:]

    def _read(self) -> bytes:
        """What is there to read now (maybe nothing); `WireLost` if the device is gone."""
        try:
            data = os.read(self.fd, READ_CHUNK)
        except BlockingIOError:
            return b""
        except OSError as error:
            raise WireLost(error.errno, f"read failed: {error.strerror}") from None
        if not data:
            # A tty with VMIN 0 (as pyserial sets it) reads nothing also when there is
            # nothing: the device is gone only if it no longer answers termios.
            try:
                termios.tcgetattr(self.fd)
            except (termios.error, OSError):
                raise WireLost(errno.EIO, "read failed: the device is gone") from None
        return data

    def read_some(self, deadline_ns: int) -> bytes:
        while True:
            remaining_ns = deadline_ns - self.clock.now_ns()
            if readable(self.fd, remaining_ns):  # select's microseconds where it can
                data = self._read()
                if data:
                    return data
                # readable but empty: do not spin on it
                select.select([], [], [], min(max(0, remaining_ns), POLL_NS) / 1e9)
            if remaining_ns <= 0:
                return b""

    def discard_input(self) -> int:
        dropped = 0
        while dropped < MAX_DRAIN_BYTES and readable(self.fd, 0):
            data = self._read()
            if not data:
                break
            dropped += len(data)
        return dropped

    def close(self) -> None:
        try:
            if self._on_close is not None:
                self._on_close()
            else:
                os.close(self.fd)
        except OSError:
            pass


class PolledWire:
    """Any object with pyserial's ``write`` / ``in_waiting`` / ``read`` / ``close``.

    The in-process simulator (`pinarray.hardware.feetech.sim.SimSerial`) is one: its bytes
    arrive on the clock, and it says when the next ones will have arrived
    (``readable_at_ns``), so a read waits on the clock until then: in virtual time one jump,
    whatever the wire's speed. A port that cannot say (a pyserial URL handler) is polled every
    `POLL_NS` of clock time.
    """

    def __init__(self, port: SerialPort, clock: Clock, name: str):
        self.port = port
        self.clock = clock
        self.name = name
        self._readable_at_ns: Callable[[], int | None] | None = getattr(
            port, "readable_at_ns", None)
        # The simulator's port does the wait below in one call: the same bytes at the same
        # times, for a fraction of the calls (this runs for every exchange of a batch).
        self._read_arrived: Callable[[int], bytes] | None = getattr(port, "read_arrived", None)

    def write(self, data: bytes) -> None:
        try:
            self.port.write(data)
        except OSError as error:  # serial.SerialException is an OSError
            raise WireLost(errno.EIO, str(error)) from None

    def read_some(self, deadline_ns: int) -> bytes:
        read_arrived = self._read_arrived
        try:
            if read_arrived is not None:
                return read_arrived(deadline_ns)
            port, clock, readable_at_ns = self.port, self.clock, self._readable_at_ns
            while True:
                waiting = port.in_waiting
                if waiting:
                    return bytes(port.read(waiting))
                now_ns = clock.now_ns()
                if now_ns >= deadline_ns:
                    return b""
                if readable_at_ns is None:
                    clock.sleep_until_ns(min(deadline_ns, now_ns + POLL_NS))
                    continue
                next_ns = readable_at_ns()
                clock.sleep_until_ns(deadline_ns if next_ns is None else min(deadline_ns, next_ns))
        except OSError as error:
            raise WireLost(errno.EIO, str(error)) from None

    def discard_input(self) -> int:
        try:
            waiting = self.port.in_waiting
            return len(self.port.read(waiting)) if waiting else 0
        except OSError as error:
            raise WireLost(errno.EIO, str(error)) from None

    def close(self) -> None:
        try:
            self.port.close()
        except OSError:
            pass


@dataclass(frozen=True)
class Expected:
    """A reply a request asks for: from which servo, carrying how many data bytes."""

    servo_id: int
    params_length: int = 0


@dataclass
class LinkCounters:
    """What went over the link since it was opened."""

    bytes_written: int = 0
    bytes_read: int = 0
    exchanges: int = 0
    stale_bytes: int = 0  # drained before a request: late answers to earlier ones
    mismatched_replies: int = 0  # well-formed status packets that did not fit the request
    timeouts: int = 0


class Latency:
    """How long the adapter may hold a reply, learnt from the latency timer or measured.

    A USB-serial adapter passes received bytes to the host when its latency timer runs out
    (FTDI default 16 ms; 1 ms once lowered), plus one USB frame. A pseudo-terminal or an
    adapter whose timer cannot be read starts at the vendor SDK's cautious 16 ms and, once a
    few exchanges have been timed, goes by what was measured.

    Two figures: `allowance_ns`, how long to wait before a reply counts as lost (three times
    the worst latency ever seen: waiting too long costs little), and `expected_ns`, what a
    read-back squeezed between two frames should plan for (twice the 90th percentile of the
    recent ones: one slow reply at connect must not stop every later read-back, and a reply
    that comes later than planned only ends that read-back at its deadline, to be tried again).

    Parameters
    ----------
    timer_ms : int or None
        The adapter's latency timer, if known.
    floor_ns : int
        Never allow less than this (scheduling noise on the host).
    learns : bool
        Go by measured exchanges (False: the in-process simulator, which has no adapter and
        whose replies take no host time; what a busy host made an exchange take on the wall
        clock says nothing about it).
    """

    CAUTIOUS_NS = 2 * 16 * NS_PER_MS + 2 * NS_PER_MS  # what the SDK allows an unknown adapter
    SAMPLES_BEFORE_TRUST = 3
    RECENT = 64

    def __init__(self, timer_ms: int | None = None, floor_ns: int = NS_PER_MS,
                 learns: bool = True):
        self.timer_ms = timer_ms
        self.floor_ns = floor_ns
        self.learns = learns
        self.worst_seen_ns = 0
        self.samples = 0
        self.recent_ns: deque[int] = deque(maxlen=self.RECENT)
        self._p90_ns = 0

    def record(self, latency_ns: int) -> None:
        if not self.learns:
            return
        self.samples += 1
        self.worst_seen_ns = max(self.worst_seen_ns, latency_ns)
        self.recent_ns.append(latency_ns)
        ordered = sorted(self.recent_ns)  # here, not in the slack before a read-back
        self._p90_ns = ordered[min(len(ordered) - 1, 9 * len(ordered) // 10)]

    @property
    def allowance_ns(self) -> int:
        """How long past the wire and return-delay time a reply may still arrive."""
        worst_ns = 3 * self.worst_seen_ns
        timer_ms = self.timer_ms
        if timer_ms is None:
            if self.samples < self.SAMPLES_BEFORE_TRUST:
                return max(self.CAUTIOUS_NS, worst_ns)
            return max(self.floor_ns, worst_ns)
        # The timer and one USB frame, the floor, or worse as seen (every exchange asks).
        return max(self.floor_ns, (timer_ms + 1) * NS_PER_MS, worst_ns)

    @property
    def expected_ns(self) -> int:
        """How long past the wire and return-delay time a read-back should plan to wait."""
        timer_ms = self.timer_ms
        if timer_ms is None:
            if len(self.recent_ns) < self.SAMPLES_BEFORE_TRUST:
                return self.allowance_ns
            return max(self.floor_ns, 2 * self._p90_ns)
        # The timer and one USB frame, the floor, or twice the recent 90th percentile.
        return max(self.floor_ns, (timer_ms + 1) * NS_PER_MS, 2 * self._p90_ns)


class Link:
    """Requests and validated replies over a `Wire`, against a clock.

    Parameters
    ----------
    wire : Wire
        Where the bytes go.
    clock : Clock
        The time base of deadlines (virtual for the in-process simulator).
    baud_rate : int
        Bits per second on the servo bus.
    latency : Latency
        The adapter's latency allowance.
    """

    def __init__(self, wire: Wire, clock: Clock, baud_rate: int, latency: Latency):
        self.wire = wire
        self.clock = clock
        self.baud_rate = baud_rate
        self.latency = latency
        self.reader = StatusReader()
        self.counters = LinkCounters()
        self.return_delay_ns: dict[int, int] = {}
        # Clock ns when the bytes written so far will have left the host: a request written
        # behind a frame still on the wire (a sync write gets no reply) goes out after it.
        self._wire_free_ns = 0
        # The replies the last request asked for, by servo id: a sampled bus asks the same
        # (the very same tuple, which cannot change) every few milliseconds.
        self._wanted: tuple[Sequence[Expected], dict[int, int], int] = ((), {}, 0)

    @property
    def name(self) -> str:
        return self.wire.name

    def wire_ns(self, byte_count: int) -> int:
        """Time ``byte_count`` bytes take on the bus at its baud rate."""
        return byte_count * BITS_PER_BYTE * 1_000_000_000 // self.baud_rate

    def reply_time_ns(self, request_bytes: int, replies: Sequence[Expected],
                      expected: bool = False, patience: int = 1) -> int:
        """Longest a request and its replies may take before the replies count as lost.

        ``expected``: what to plan for instead (`Latency.expected_ns`), e.g. before squeezing
        a read-back between two frames. ``patience``: allow that many times the latency
        allowance (a retry after a silence waits longer: a busy host can hold a reply, or the
        simulator serving it, for more than the allowance learnt while it was quiet).
        """
        reply_bytes = delays = 0
        delay_of = self.return_delay_ns.get
        for reply in replies:
            reply_bytes += 6 + reply.params_length
            delays += delay_of(reply.servo_id, MAX_RETURN_DELAY_NS)
        latency = self.latency.expected_ns if expected else patience * self.latency.allowance_ns
        # `wire_ns` of the request and its replies, written out: every exchange asks.
        wire_ns = (request_bytes + reply_bytes) * BITS_PER_BYTE * 1_000_000_000 // self.baud_rate
        return wire_ns + delays + latency

    def send(self, packet: bytes) -> None:
        """Put a packet that gets no reply (a sync write) on the wire."""
        self.wire.write(packet)
        self.counters.bytes_written += len(packet)
        self._wire_free_ns = max(self.clock.now_ns(), self._wire_free_ns) + self.wire_ns(len(packet))

    def drain(self) -> None:
        """Drop input left from earlier exchanges: late replies must not answer this request."""
        stale = self.wire.discard_input() + self.reader.clear()
        self.counters.stale_bytes += stale

    def exchange(
        self, packet: bytes, expected: Sequence[Expected], deadline_ns: int | None = None,
        patience: int = 1,
    ) -> dict[int, StatusPacket]:
        """Send ``packet`` and collect the replies it asks for, until they are in or time is up.

        Parameters
        ----------
        packet : bytes
            The request (a READ, WRITE, PING or SYNC_READ instruction packet).
        expected : sequence of Expected
            The replies that fit it: one per servo id, each with its data length.
        deadline_ns : int, optional
            Give up at this clock time even if the reply time allows longer (the player's
            next frame); default: the request's reply time from now.
        patience : int
            How many latency allowances the reply time includes (see `reply_time_ns`).

        Returns
        -------
        dict of servo id to StatusPacket
            The replies that arrived and fit; a missing id means no fitting reply in time.
        """
        self.drain()
        asked, wanted, longest = self._wanted
        if asked is not expected:
            wanted = {e.servo_id: e.params_length for e in expected}
            longest = max(wanted.values(), default=0)
            if type(expected) is tuple:
                self._wanted = expected, wanted, longest
        self.reader.longest_params = longest
        start_ns = self.clock.now_ns()
        # Bytes still leaving ahead of the request (a frame just written) hold it back.
        free_ns = self._wire_free_ns
        queued_ns = free_ns - start_ns if free_ns > start_ns else 0
        size = len(packet)
        limit_ns = start_ns + queued_ns + self.reply_time_ns(size, expected, patience=patience)
        if deadline_ns is not None and deadline_ns < limit_ns:
            limit_ns = deadline_ns
        self._wire_free_ns = start_ns + queued_ns + self.wire_ns(size)
        replies = self._send_and_collect(packet, wanted, limit_ns)
        if self.latency.learns and replies and len(replies) == len(wanted):
            # The adapter's part of the exchange: what it took beyond the wire and the servos'
            # return delays.
            used_ns = self.clock.now_ns() - start_ns - queued_ns
            wire_and_delays_ns = self.reply_time_ns(len(packet), expected) - self.latency.allowance_ns
            self.latency.record(max(0, used_ns - wire_and_delays_ns))
        return replies

    def _send_and_collect(self, packet: bytes, wanted: dict[int, int],
                          limit_ns: int) -> dict[int, StatusPacket]:
        """Put the request on the wire, then `collect` its replies until ``limit_ns``."""
        self.wire.write(packet)
        self.counters.bytes_written += len(packet)
        self.counters.exchanges += 1
        return self.collect(wanted, limit_ns, {})

    def collect(self, wanted: dict[int, int], limit_ns: int,
                replies: dict[int, StatusPacket]) -> dict[int, StatusPacket]:
        """Read status packets into ``replies`` until each servo in ``wanted`` (id -> data
        length) has answered, or ``limit_ns``; what does not fit is counted as mismatched."""
        wire, reader, counters = self.wire, self.reader, self.counters
        while len(replies) < len(wanted):
            data = wire.read_some(limit_ns)
            if not data:
                counters.timeouts += 1
                break
            counters.bytes_read += len(data)
            for status in reader.feed(data):
                length = wanted.get(status.servo_id)
                if length is None or length != len(status.params) or status.servo_id in replies:
                    counters.mismatched_replies += 1
                    continue
                replies[status.servo_id] = status
        return replies

    def close(self) -> None:
        self.wire.close()
