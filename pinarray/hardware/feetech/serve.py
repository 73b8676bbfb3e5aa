"""Simulated servos behind a pseudo-terminal, usable as if they were ``/dev/ttyUSB0``.

Any client (the vendor SDK's examples, LeRobot, ``pinarray play --port``) opens the printed
path with pyserial. The wire is charged as on a real bus: an instruction's last byte arrives
``10 x bytes / baud`` after the client wrote it, at the speed the client set on the port (or
the URL's ``baud``); each status packet is written to the pseudo-terminal when its last byte
would have arrived (`pinarray.hardware.feetech.sim_wire`), never before. A pseudo-terminal itself delivers
at once, so the only extra is the server's wake-up latency. Servos listen at their baud-rate
register (factory 1000000): a client at another speed gets no answer, as on hardware.
"""

from __future__ import annotations

import fcntl
import heapq
import os
import select
import struct
import termios
import threading
import time
import tty
from dataclasses import dataclass
from typing import IO

from pinarray.clock import Clock, MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.registers import Instruction
from pinarray.hardware.feetech.sim import InstructionPacket, SimBus
from pinarray.hardware.feetech.sim_levels import Fidelity
from pinarray.hardware.feetech.sim_wire import byte_time_ns, schedule
from pinarray.stop import signals_wake

DEFAULT_BAUD = 1_000_000
# Linux: read a non-standard speed (pyserial sets 128000 or 250000 with BOTHER + TCSETS2).
_TCGETS2 = 0x802C542A
_BOTHER = 0o010000
_TERMIOS2_SIZE = 44
_TERMIOS2_OSPEED_OFFSET = 40
_SPEED_CODES = {
    getattr(termios, f"B{rate}"): rate
    for rate in (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600,
                 1000000, 1152000, 1500000, 2000000)
    if hasattr(termios, f"B{rate}")
}
_ADDRESSED = frozenset({
    Instruction.READ, Instruction.WRITE, Instruction.REG_WRITE,
    Instruction.SYNC_READ, Instruction.SYNC_WRITE,
})
ARRIVALS_COLUMNS = ("arrival_ns", "servo_id", "instruction", "address", "data_hex", "delivered")


@dataclass(frozen=True)
class Arrival:
    """One instruction packet as the server read it.

    Attributes
    ----------
    arrival_ns : int
        ``time.monotonic_ns()`` when the read holding the packet's last byte returned.
    servo_id : int
        The packet's id (254 for broadcast, e.g. every SYNC WRITE).
    instruction : int
        Instruction code (`pinarray.hardware.feetech.registers.Instruction`).
    params : bytes
        Everything between the instruction and the checksum.
    delivered : bool
        False when an injected fault (``drop``, ``drop_writes``) lost it on the wire.
    """

    arrival_ns: int
    servo_id: int
    instruction: int
    params: bytes
    delivered: bool

    @property
    def address(self) -> int | None:
        """Start address for READ, WRITE, REG_WRITE, SYNC_READ and SYNC_WRITE, else None."""
        return self.params[0] if self.instruction in _ADDRESSED and self.params else None

    @property
    def data(self) -> bytes:
        """The parameters after the address (for SYNC WRITE: length, then id + data each)."""
        return self.params[1:] if self.address is not None else self.params

    def tsv_row(self) -> str:
        address = "" if self.address is None else str(self.address)
        return "\t".join((
            str(self.arrival_ns), str(self.servo_id), Instruction.name_of(self.instruction),
            address, self.data.hex(), str(int(self.delivered)),
        ))


def port_speed(fd: int) -> int | None:
    """The output speed, bit/s, a client set on the terminal ``fd`` (None if unreadable)."""
    try:
        code = termios.tcgetattr(fd)[5]
    except termios.error:
        return None
    if code in _SPEED_CODES:
        return _SPEED_CODES[code]
    if code != _BOTHER:
        return None
    try:
        raw = fcntl.ioctl(fd, _TCGETS2, bytes(_TERMIOS2_SIZE))
    except OSError:
        return None
    (speed,) = struct.unpack_from("I", raw, _TERMIOS2_OSPEED_OFFSET)
    return speed or None


class PtyServer:
    """A `SimBus` answering on a pseudo-terminal until `stop` is called.

    Parameters
    ----------
    config : SimConfig
        Servo ids, wire settings, physics and faults.
    clock : Clock, optional
        Real time by default; the servos' motion runs on it.
    record_arrivals : bool
        Keep an `Arrival` for every instruction packet (`arrivals`, `write_arrivals`).
    """

    def __init__(
        self, config: SimConfig, clock: Clock | None = None, record_arrivals: bool = False
    ):
        if config.fidelity not in (None, Fidelity.WIRE):
            raise PinArrayError(f"sim URL key fidelity: a pseudo-terminal carries bytes; expected "
                                f"fidelity=wire, found fidelity={config.fidelity}")
        self.sim = SimBus(config, clock or MonotonicClock(), follow_host_baud=False)
        # The pseudo-terminal lives in real time whatever clock the servos' motion runs on.
        self._wall = MonotonicClock()
        self._controller, self._device = os.openpty()
        # Raw mode: no echo, no CR/LF translation, every byte passes through untouched.
        tty.setraw(self._device)
        tty.setraw(self._controller)
        os.set_blocking(self._controller, False)
        self.path = os.ttyname(self._device)
        self._wake_read, self._wake_write = os.pipe()
        os.set_blocking(self._wake_write, False)  # a signal's byte must never block (signals_wake)
        self._stopping = threading.Event()
        # Re-entrant: a signal handler calling request_stop may interrupt _close in this thread.
        self._fd_lock = threading.RLock()
        self._thread: threading.Thread | None = None
        self._due: list[tuple[int, int, bytes]] = []  # (monotonic ns, order, packet)
        self._order = 0
        self._host_free_ns = 0
        self._line_free_ns = 0
        self._read_ns = 0
        self.overruns = 0  # reply bytes the client's full input buffer could not take
        self.arrivals: list[Arrival] | None = [] if record_arrivals else None
        if record_arrivals:
            self.sim.packet_listener = self._log

    def serve_forever(self) -> None:
        """Answer instruction packets until `stop` (or until a ``vanish_after`` fault fires).

        In the main thread, a stop signal wakes the wait at once (`signals_wake`): its handler
        may request the stop only after the wait has begun."""
        try:
            with signals_wake(self._wake_write):
                self._serve()
        finally:
            self._close()

    def _serve(self) -> None:
        while not self._stopping.is_set():
            timeout_s = None
            if self._due:
                timeout_s = max(0.0, (self._due[0][0] - time.monotonic_ns()) / 1e9)
            ready, _, _ = select.select([self._controller, self._wake_read], [], [], timeout_s)
            if self._wake_read in ready:
                os.read(self._wake_read, 64)
            if self._controller in ready:
                try:
                    data = os.read(self._controller, 4096)
                except BlockingIOError:
                    data = b""
                except OSError:
                    # No client attached right now: look again in a millisecond.
                    self._wall.doze_until_ns(self._wall.now_ns() + 1_000_000)
                    continue
                if data:
                    self._take(data, time.monotonic_ns())
                if self.sim.vanished:
                    break  # the "USB adapter" is pulled: clients see I/O errors
            self._send_due()

    def start(self) -> PtyServer:
        """Serve from a background thread (for tests and benchmarks)."""
        self._thread = threading.Thread(target=self.serve_forever, name="sim-pty", daemon=True)
        self._thread.start()
        return self

    def request_stop(self) -> None:
        """Ask `serve_forever` to return soon; safe from a signal handler."""
        self._stopping.set()
        with self._fd_lock:
            if self._wake_write >= 0:
                try:
                    os.write(self._wake_write, b"!")
                except OSError:
                    pass  # closing right now: the loop has ended anyway

    def stop(self, timeout_s: float = 2.0) -> None:
        self.request_stop()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def write_arrivals(self, out: IO[str]) -> int:
        """Write the recorded arrivals as TSV (columns `ARRIVALS_COLUMNS`) to ``out``; returns
        the rows. A failed write raises its `OSError`: the caller knows the file's name."""
        if self.arrivals is None:
            raise PinArrayError("sim-serve: arrivals were not recorded (record_arrivals=False)")
        rows = ["\t".join(ARRIVALS_COLUMNS), *(a.tsv_row() for a in self.arrivals)]
        out.write("\n".join(rows) + "\n")
        return len(self.arrivals)

    def _host_baud(self) -> int:
        configured = self.sim.config.baud_rate
        return configured or port_speed(self._device) or DEFAULT_BAUD

    def _take(self, data: bytes, read_ns: int) -> None:
        self._read_ns = read_ns
        baud = self._host_baud()
        byte_ns = byte_time_ns(baud)
        start_ns = max(read_ns, self._host_free_ns)
        end_ns = start_ns + round(len(data) * byte_ns)
        self._host_free_ns = end_ns
        offset_ns = self.sim.clock.now_ns() - time.monotonic_ns()  # sim clock - real clock
        self.sim.byte_ns, self.sim.host_baud_rate = byte_ns, baud
        replies = self.sim.receive(data, end_ns + offset_ns)
        if not replies:
            return
        line_free_ns = max(self._line_free_ns, end_ns) + offset_ns
        arriving, line_free_ns = schedule(replies, line_free_ns, byte_ns)
        self._line_free_ns = line_free_ns - offset_ns
        for sent in arriving:
            self._order += 1
            heapq.heappush(self._due, (sent.end_ns - offset_ns, self._order, sent.data))

    def _send_due(self) -> None:
        now_ns = time.monotonic_ns()
        while self._due and self._due[0][0] <= now_ns:
            _, _, packet = heapq.heappop(self._due)
            try:
                written = os.write(self._controller, packet)
            except (BlockingIOError, OSError):
                written = 0
            self.overruns += len(packet) - written

    def _log(self, packet: InstructionPacket) -> None:
        assert self.arrivals is not None
        self.arrivals.append(
            Arrival(self._read_ns, packet.servo_id, packet.instruction, packet.params,
                    packet.delivered)
        )

    def _close(self) -> None:
        with self._fd_lock:
            for fd in (self._controller, self._device, self._wake_read, self._wake_write):
                try:
                    os.close(fd)
                except OSError:
                    pass
            self._wake_write = -1  # a late request_stop must not write into a reused fd
