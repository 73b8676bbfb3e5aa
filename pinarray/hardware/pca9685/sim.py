"""Simulated PCA9685 boards on a simulated I2C bus, named by a URL like the Feetech ``sim://``::

    sim://pca9685?osc_hz=25300000&address=0x40,0x41&bus_hz=400000&nack=0.01&nack_at=12
                 &power_loss_at=40&slow=2&vanish_after=500&seed=1

Every key is optional:

``osc_hz``          each board's oscillator, Hz (default 25000000; real boards are off by
                    percents: measure yours)
``address``         the boards' 7-bit addresses, hex or decimal, commas (default 0x40);
                    0x40-0x7F, not the All Call address 0x70
``bus_hz``          SCL rate, bit/s (default 400000; 1000 to 1000000)
``nack``            probability that a message is not acknowledged (the address byte)
``nack_at``         the message with this number (1 = the first) is not acknowledged
``power_loss_at``   every board loses power just before this message and comes back at once:
                    registers at their power-up values (SLEEP set, outputs off)
``slow``            every message takes this many times its time at ``bus_hz`` (clock
                    stretching, a slow adapter), 1 to 1000 (default 1)
``vanish_after``    the adapter disappears after this many messages (USB unplugged)
``seed``            random seed for ``nack`` (default 0), so runs are reproducible
``state``           a file that holds the boards, written through after every message, so
                    they outlive the program as real boards do: a player process opens them
                    too (`play` hands the board to one, as for a real i2c-dev bus), and a test
                    reads what the board was last told after the program was killed. A file
                    that exists is taken as the boards were left; it must be one this
                    simulator wrote (data only, `board_file`): any other file, a FIFO or a
                    device is refused and left untouched. Message numbers (``nack_at``,
                    ``power_loss_at``, ``vanish_after``, ``kill_at``) then count every message
                    the boards heard, from every program. Shared boards run in real time.
``kill_at``         (with ``state``) the program that sends message number ``kill_at`` is
                    killed (SIGKILL) as that message begins: a crash, ``kill -9`` or a host
                    losing power at that exact moment of its conversation with the board

A message takes ``START + 9 bits per byte (the address byte included) + STOP`` bit times at
``bus_hz``; the link waits that long on its clock, so a `pinarray.clock.VirtualClock` advances.
"""

from __future__ import annotations

import fcntl
import math
import os
import random
import signal
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from urllib.parse import parse_qsl, urlsplit

from pinarray.clock import Clock, MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.hardware.driver import PortLost
from pinarray.hardware.pca9685 import board_file
from pinarray.hardware.pca9685 import registers as r
from pinarray.hardware.pca9685.board_sim import SimulatedBoard
from pinarray.hardware.pca9685.i2c import I2cMessage, I2cNack, Listener
from pinarray.hardware.sim_urls import sim_query
from pinarray.units import NS_PER_S

SCHEME_PREFIX = "sim://pca9685"
DEFAULT_BUS_HZ = 400_000
MIN_BUS_HZ, MAX_BUS_HZ = 1_000, 1_000_000
MAX_SLOW = 1000.0
MAX_COUNT = 10**12
MAX_SEED = 2**63 - 1
MIN_OSC_HZ, MAX_OSC_HZ = 1_000_000, 50_000_000  # EXTCLK accepts up to 50 MHz (7.3.5)

_KNOWN_KEYS = ("osc_hz", "address", "bus_hz", "nack", "nack_at", "power_loss_at", "slow",
               "vanish_after", "seed", "state", "kill_at")


def is_pca9685_url(url: str) -> bool:
    """Whether ``url`` names simulated PCA9685 boards (``sim://pca9685?...``)."""
    return url == SCHEME_PREFIX or url.startswith(SCHEME_PREFIX + "?")


def is_shared_board_url(url: str | None) -> bool:
    """Whether ``url`` names simulated boards kept in a file (``state=``), shared by processes."""
    return url is not None and is_pca9685_url(url) and "state" in dict(
        parse_qsl(urlsplit(url).query, keep_blank_values=True))


def _number(url: str, key: str, text: str, kind: type[int] | type[float], low: float,
            high: float) -> float:
    try:
        if not text.isascii():  # int() and float() read other scripts' digits (１)
            raise ValueError(text)
        value: float = kind(text)
    except ValueError:
        what = "a whole number" if kind is int else "a number"
        raise PinArrayError(f"{url}: sim URL key {key}: expected {what}, found {text!r}") from None
    if not (math.isfinite(value) and low <= value <= high):
        raise PinArrayError(f"{url}: sim URL key {key}: expected {low:g} to {high:g}, "
                            f"found {text!r}")
    return value


def _swrst_refusal(data: bytes) -> int | None:
    """7.6: only the one byte 0x06 is acknowledged after the general call address."""
    if data and data[0] != r.SWRST_BYTE:
        return 0
    return 1 if len(data) > 1 else None


def _addresses(url: str, text: str) -> tuple[int, ...]:
    found: list[int] = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        try:
            address = int(part, 0) if part.isascii() else -1
        except ValueError:
            address = -1
        if not r.FIRST_ADDRESS <= address <= r.LAST_ADDRESS or address == r.ALL_CALL_ADDRESS:
            raise PinArrayError(
                f"{url}: sim URL key address: expected 7-bit addresses 0x40-0x7f other than the "
                f"All Call address 0x70, found {part!r}")
        found.append(address)
    if not found:
        raise PinArrayError(f"{url}: sim URL key address: expected at least one address, "
                            f"found {text!r}")
    return tuple(dict.fromkeys(found))


class SimI2cLink:
    """An `I2cLink` to simulated boards, timed on ``clock``, with faults from the URL."""

    listener: Listener | None

    def __init__(self, url: str, clock: Clock):
        if not is_pca9685_url(url):
            raise PinArrayError(f"expected a sim://pca9685?... URL, found {url!r}")
        query = sim_query(url, urlsplit(url).query)
        unknown = sorted(set(query) - set(_KNOWN_KEYS))
        if unknown:
            raise PinArrayError(f"{url}: unknown key(s) {', '.join(unknown)}; "
                                f"known: {', '.join(sorted(_KNOWN_KEYS))}")

        def number(key: str, kind: type, low: float, high: float, default: float) -> float:
            return _number(url, key, query[key], kind, low, high) if key in query else default

        self._url = url
        self._clock = clock
        self.listener = None
        osc_hz = int(number("osc_hz", int, MIN_OSC_HZ, MAX_OSC_HZ, r.NOMINAL_OSC_HZ))
        self._bus_hz = int(number("bus_hz", int, MIN_BUS_HZ, MAX_BUS_HZ, DEFAULT_BUS_HZ))
        self._nack_rate = number("nack", float, 0.0, 1.0, 0.0)
        self._nack_at = int(number("nack_at", int, 1, MAX_COUNT, 0))
        self._power_loss_at = int(number("power_loss_at", int, 1, MAX_COUNT, 0))
        self._slow = number("slow", float, 1.0, MAX_SLOW, 1.0)
        self._vanish_after = int(number("vanish_after", int, 0, MAX_COUNT, -1))
        self._random = random.Random(int(number("seed", int, 0, MAX_SEED, 0)))
        self._kill_at = int(number("kill_at", int, 1, MAX_COUNT, 0))
        addresses = _addresses(url, query.get("address", f"{r.FIRST_ADDRESS:#x}"))
        self._boards = {address: SimulatedBoard(osc_hz, address) for address in addresses}
        self._messages = 0
        self._closed = False
        state = query.get("state") or None
        self._state = None if state is None else os.path.realpath(state)
        self._lock_fd: int | None = None
        self._handed_fd: int | None = None
        self._in_message = False
        self._written: bytes | None = None  # what this program last wrote to the state file
        if self._state is None:
            if self._kill_at:
                raise PinArrayError(f"{url}: sim URL key kill_at: expected state=FILE beside "
                                    "it (a board that outlives the killed program)")
            return
        if not isinstance(clock, MonotonicClock):
            raise PinArrayError(f"{url}: a board kept in a state file is shared by processes "
                                "and runs in real time: play it without --speed (or at "
                                "--speed 1)")
        self._load()  # a file that is not ours is refused before anything is created
        try:
            # O_NONBLOCK, O_NOCTTY: a FIFO or a device in the lock's place must neither make
            # the open wait nor be acted on.
            flags = os.O_NONBLOCK | os.O_NOCTTY | os.O_NOFOLLOW
            self._lock_fd = os.open(self._state + ".lock", os.O_RDWR | os.O_CREAT | flags,
                                    0o600)
            # What a player process inherits: its own open file, never locked, so that a lock
            # held by a program killed mid-message dies with it.
            self._handed_fd = os.open(self._state + ".lock", os.O_RDONLY | flags)
            if not stat.S_ISREG(os.fstat(self._lock_fd).st_mode):
                self.close()
                raise PinArrayError(f"{url}: sim URL key state: cannot use {self._state}.lock: "
                                    "expected a regular file")
        except OSError as error:
            self.close()
            raise PinArrayError(f"{url}: sim URL key state: cannot use {self._state}.lock: "
                                f"{error.strerror}") from None
        with self._board_file():
            pass  # taken as left, or written as powered up

    @property
    def name(self) -> str:
        return self._url

    @property
    def descriptor(self) -> int | None:
        """Boards kept in a state file can be handed to a player process (which opens the
        file again by the URL); in-memory ones die with this program and cannot."""
        return self._handed_fd

    @property
    def bus_hz(self) -> int:
        return self._bus_hz

    def board(self, address: int) -> SimulatedBoard:
        """The simulated board at ``address`` (for tests and the simulated servos)."""
        with self._board_file():
            return self._boards[address]

    def message_ns(self, data_bytes: int) -> int:
        bits = 1 + 9 * (1 + data_bytes) + 1
        return math.ceil(bits * NS_PER_S * self._slow / self._bus_hz)

    def close(self) -> None:
        self._closed = True
        for fd in (self._lock_fd, self._handed_fd):
            if fd is not None:
                os.close(fd)
        self._lock_fd = self._handed_fd = None

    # -- boards kept in a file ----------------------------------------------------------------------

    @contextmanager
    def _board_file(self) -> Iterator[None]:
        """One message at a time on boards kept in the state file: read them as the last
        message left them, then write them through (replaced whole, so a program killed
        mid-message leaves the state before it, as a message cut before its STOP would)."""
        if self._state is None or self._in_message or self._lock_fd is None:
            yield
            return
        fcntl.flock(self._lock_fd, fcntl.LOCK_EX)
        self._in_message = True
        try:
            self._load()  # raising, it writes nothing: the file is not ours
            try:
                yield
            finally:
                self._save()
        finally:
            self._in_message = False
            fcntl.flock(self._lock_fd, fcntl.LOCK_UN)

    def _load(self) -> None:
        """The boards as the state file holds them (as powered up when there is none yet)."""
        assert self._state is not None
        try:
            data = board_file.read_state(self._state)
            if data is None or data == self._written:
                return  # powered up now, as the URL says; or as this program left them
            messages, boards = board_file.decode(data)
        except board_file.NotOurs as problem:
            raise PinArrayError(f"{self._url}: sim URL key state: {self._state}: {problem}; "
                                "name a new file or one this simulator wrote (it is left as "
                                "it is)") from None
        if sorted(boards) != sorted(self._boards):
            raise PinArrayError(
                f"{self._url}: sim URL key state: {self._state} holds boards at "
                f"{', '.join(f'0x{a:02x}' for a in sorted(boards))}, the URL names "
                f"{', '.join(f'0x{a:02x}' for a in sorted(self._boards))}")
        self._messages, self._boards = messages, boards
        self._written = data

    def _save(self) -> None:
        assert self._state is not None
        data = board_file.encode(self._messages, self._boards)
        try:
            board_file.replace_state(self._state, data)
            self._written = data
        except OSError as error:
            raise PinArrayError(f"{self._url}: sim URL key state: cannot write {self._state}: "
                                f"{error.strerror}") from None

    # -- messages ---------------------------------------------------------------------------------

    def write(self, address: int, data: bytes) -> I2cMessage:
        with self._board_file():
            return self._write(address, data)

    def _write(self, address: int, data: bytes) -> I2cMessage:
        self._begin(address)
        general = address == r.SWRST_ADDRESS
        boards = [b for b in self._boards.values() if (b.powered if general else b.answers(address))]
        refused: int | None
        if not boards or self._fault():
            refused = -1
        elif general:
            refused = _swrst_refusal(data)
        else:
            refusals = [b.refused_at(data) for b in boards]
            refused = None if None in refusals else min(i for i in refusals if i is not None)
        carried = data if refused is None else data[:refused + 1]
        stop_ns = self._stop_ns(len(carried))
        self._clock.sleep_until_ns(stop_ns)
        if refused is None:
            byte_ns = self.message_ns(1) - self.message_ns(0)
            for board in boards:
                if general:
                    board.general_call(data, stop_ns)
                else:
                    board.write(data, stop_ns, byte_ns)
        message = I2cMessage(address, False, carried, refused is None, stop_ns)
        self._hear(message)
        if refused is not None:
            where = "its address" if refused < 0 else f"byte {refused} (0x{data[refused]:02x})"
            raise I2cNack(f"{self._url}: board 0x{address:02x} did not acknowledge {where} "
                          f"of a {len(data)}-byte write", address)
        return message

    def write_read(self, address: int, data: bytes, count: int) -> bytes:
        with self._board_file():
            return self._write_read(address, data, count)

    def _write_read(self, address: int, data: bytes, count: int) -> bytes:
        self._write(address, data)
        self._begin(address)
        board = self._boards.get(address)
        answered = board is not None and board.answers(address, read=True) and not self._fault()
        stop_ns = self._stop_ns(count if answered else 0)
        self._clock.sleep_until_ns(stop_ns)
        read = board.read(count, stop_ns) if answered and board is not None else b""
        self._hear(I2cMessage(address, True, read, answered, stop_ns))
        if not answered:
            raise I2cNack(f"{self._url}: board 0x{address:02x} did not acknowledge its address "
                          f"for a {count}-byte read", address)
        return read

    def _begin(self, address: int) -> None:
        if self._closed:
            raise PortLost(f"{self._url}: the I2C bus was closed")
        if 0 <= self._vanish_after <= self._messages:
            raise PortLost(f"{self._url}: the I2C adapter vanished after {self._messages} "
                           f"messages (talking to board 0x{address:02x})")
        self._messages += 1
        if self._messages == self._kill_at:
            self._save()  # counted: the next program's messages go on from here
            os.kill(os.getpid(), signal.SIGKILL)
        if self._messages == self._power_loss_at:
            now = self._clock.now_ns()
            for board in self._boards.values():
                board.lose_power(now)
                board.power_up(now)

    def _fault(self) -> bool:
        """Whether this message's address goes unacknowledged by the URL's faults."""
        return self._messages == self._nack_at or (
            self._nack_rate > 0 and self._random.random() < self._nack_rate)

    def _stop_ns(self, data_bytes: int) -> int:
        return self._clock.now_ns() + self.message_ns(data_bytes)

    def _hear(self, message: I2cMessage) -> None:
        if self.listener is not None:
            self.listener(message)
