"""Can the servo bus carry a stimulus? Every frame of goal changes written, then read back,
before the next frame is due. Pure Python: `pinarray validate` runs it without numpy.

A trial's goal changes go out in frames: at each instant where any pin's goal changes, one
SYNC WRITE carries every servo that changes then (`8 + 3 n` bytes for ``n`` servos: header,
id, length, instruction, address, data length and checksum, then an id and a 2-byte goal
each), written at its deadline. Sync writes get no reply, so in the slack between frames the
player reads the changed goals back (`pinarray.hardware.feetech.readback`): as many pending
ones as fit before the next frame, oldest first, in one SYNC READ of `8 + k` bytes answered by
``k`` status packets of 8 bytes, each after the servo's return delay. On a wire of ``baud``
bits a second every byte takes 10 bits (start, 8 data, stop). A goal its servo's next change
replaces before the read-back confirmed it is lost, and the trial is not delivered; so is a
goal that reaches its servo later than the device's delivery tolerance. This check plays the
trial's frames against that bus and refuses a stimulus, with the numbers, when

- a frame's last goal would arrive later than the delivery tolerance (a frame too long for
  the baud rate, or frames queued behind each other), or
- a servo changes again before the read-back of its last change could fit.

The USB adapter's latency comes on top of these (1 ms tuned, 16 ms at the FTDI default), as
does the host's; `pinarray timing` measures those on the machine that plays.

Which instants are frames follows the compiler (`pinarray.schedule`): each drive's first
pulse, every pulse whose position differs from the one before, and its end (back to rest).
Times here are exact fractions of a nanosecond (the compiler rounds each to a whole one: a
nanosecond either way changes no verdict), played as whole numbers of a unit that divides
them all. A change that leaves a pin where it was is counted
too, so the check never passes what the player would refuse for these reasons.

Long trials cost little: drives of more than `_ENUMERATE_ALL` changes that repeat with a
common period are played on two periods around each drive's start and end, where the mix of
frames changes; between those, every period is the same.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

from pinarray.protocol.model import NS_PER_S, PinDrive, ServoSettings, Train

# The packets, as `pinarray.hardware.feetech.packets` builds them (a test holds them equal).
SYNC_WRITE_FIXED_BYTES = 8
BYTES_PER_GOAL = 3
SYNC_READ_FIXED_BYTES = 8
STATUS_PACKET_BYTES = 8  # a reply carrying one 2-byte goal
BITS_PER_BYTE = 10
# Below this many changes a stimulus is judged change by change, whatever its period.
_ENUMERATE_ALL = 20_000


def write_bytes(servos: int) -> int:
    """Bytes of one frame's SYNC WRITE of ``servos`` 2-byte goals."""
    return SYNC_WRITE_FIXED_BYTES + BYTES_PER_GOAL * servos


def readback_bytes(servos: int) -> int:
    """Bytes of the SYNC READ that reads ``servos`` goals back, and of their replies."""
    return SYNC_READ_FIXED_BYTES + servos + STATUS_PACKET_BYTES * servos


def wire_ns(byte_count: int, baud_rate: int) -> Fraction:
    """How long ``byte_count`` bytes take on the wire at ``baud_rate``, in ns."""
    return Fraction(byte_count * BITS_PER_BYTE * NS_PER_S, baud_rate)


@dataclass(frozen=True)
class FrameCost:
    """What one frame of ``servos`` goal changes asks of the bus, in bytes and ns."""

    servos: int
    write_bytes: int
    write_ns: Fraction
    readback_bytes: int
    readback_ns: Fraction  # on the wire, and every servo's return delay

    @property
    def total_ns(self) -> Fraction:
        return self.write_ns + self.readback_ns

    @property
    def frames_per_s(self) -> float:
        """How many such frames a second the bus carries, read-backs included."""
        return NS_PER_S / float(self.total_ns)


# Asked for the same few frame sizes by every check of a protocol's conditions: made once.
@lru_cache(maxsize=1024)
def frame_cost(servos: int, servo: ServoSettings) -> FrameCost:
    """The cost of one frame of ``servos`` goal changes on ``servo``'s bus."""
    baud = servo.baud_rate
    written, read = write_bytes(servos), readback_bytes(servos)
    return FrameCost(servos, written, wire_ns(written, baud), read,
                     wire_ns(read, baud) + servos * servo.return_delay_us * 1000)


def frames(drives: Sequence[PinDrive]) -> list[tuple[Fraction, frozenset[int]]]:
    """(time from onset in ns, pins whose goal changes then) of every frame that decides the
    check, in time order (the module docstring says which)."""
    groups: dict[tuple[Train, int], set[int]] = {}
    for drive in drives:
        groups.setdefault((drive.train, drive.delay_ns), set()).add(drive.pin)
    count = sum(_estimated_changes(train) for train, _ in groups)
    windows: list[tuple[Fraction, Fraction]] | None = None
    if count > _ENUMERATE_ALL:
        period = _common_period(train for train, _ in groups)
        if period is not None:
            edges = sorted({Fraction(edge) for train, delay in groups
                            for edge in (delay, delay + train.duration_ns)})
            windows = _merged((edge - 2 * period, edge + 2 * period) for edge in edges)
    at: dict[Fraction, set[int]] = {}
    for (train, delay), pins in groups.items():
        for time in _changes(train, delay, windows):
            at.setdefault(time, set()).update(pins)
    return [(time, frozenset(pins)) for time, pins in sorted(at.items())]


def bus_problem(drives: Sequence[PinDrive], servo: ServoSettings,
                tolerance_ns: int) -> str | None:
    """Why the bus cannot deliver ``drives`` (the numbers in words), or None if it can."""
    timed = frames(drives)
    # Played in whole units of 1/scale ns, in which every frame's time and every frame's cost
    # on the wire is a whole number (the baud rate divides it): the same comparisons as in
    # Fractions, exactly, without making thousands of them.
    scale = math.lcm(servo.baud_rate, *(time.denominator for time, _ in timed))
    bus = _ScaledBus(servo, scale)
    pending: dict[int, tuple[int, int]] = {}  # pin -> (its frame's time, that frame's size)
    wire_free = -(10**18) * scale  # when the wire is next free, from onset
    for time, pins in timed:
        at = time.numerator * (scale // time.denominator)
        wire_free = _read_back(pending, wire_free, at, bus)
        lost = sorted(pins & pending.keys())
        if lost:
            sent, servos = pending[lost[0]]
            cost = frame_cost(servos, servo)
            apart = Fraction(at - sent, scale)
            return (f"pin {lost[0]} changes again at {_ms(time)}, before its goal of "
                    f"{_ms(Fraction(sent, scale))} is read back: a frame of {servos} goal(s) is "
                    f"{cost.write_bytes} bytes, {_ms(cost.write_ns)} at {servo.baud_rate} baud, "
                    f"its read-back {cost.readback_bytes} bytes + {servos} x "
                    f"{servo.return_delay_us} us return delay, {_ms(cost.readback_ns)}: "
                    f"{_ms(cost.total_ns)} a frame, at most {math.floor(cost.frames_per_s)} "
                    f"frames/s, but they come {_ms(apart)} apart ({NS_PER_S / float(apart):.0f}/s); "
                    "lower the frequency or the pins moved at once, raise the baud rate, or "
                    "lower the return delay (pinarray servos return-delay; device: servo: "
                    "return_delay_us)")
        write = bus.write(len(pins))
        wire_free = max(wire_free, at) + write
        if wire_free - at > tolerance_ns * scale:
            cost = frame_cost(len(pins), servo)
            queued = "" if wire_free - at == write else (
                f", queued behind the frames before it ({_ms(Fraction(wire_free - at, scale))} "
                "in all)")
            return (f"a frame of {len(pins)} goal(s) at {_ms(time)} is {cost.write_bytes} bytes, "
                    f"{_ms(cost.write_ns)} at {servo.baud_rate} baud{queued}: its last goal would "
                    f"reach its servo later than the delivery tolerance of {_ms(tolerance_ns)}; "
                    "raise the baud rate or move fewer pins at once")
        for pin in sorted(pins):
            pending[pin] = (at, len(pins))
    return None


class _ScaledBus:
    """Frame costs on ``servo``'s bus in units of 1/``scale`` ns, each worked out once."""

    def __init__(self, servo: ServoSettings, scale: int) -> None:
        self._servo, self._scale = servo, scale
        self._write: dict[int, int] = {}
        self._readback: dict[int, int] = {}

    def write(self, servos: int) -> int:
        if servos not in self._write:
            self._write[servos] = self._scaled(frame_cost(servos, self._servo).write_ns)
        return self._write[servos]

    def readback(self, servos: int) -> int:
        if servos not in self._readback:
            self._readback[servos] = self._scaled(frame_cost(servos, self._servo).readback_ns)
        return self._readback[servos]

    def _scaled(self, ns: Fraction) -> int:
        whole = ns * self._scale
        assert whole.denominator == 1  # the baud rate divides the scale
        return whole.numerator


def _read_back(pending: dict[int, tuple[int, int]], wire_free: int, before: int,
               bus: _ScaledBus) -> int:
    """Read pending goals back, oldest first, as many at a time as fit before ``before``
    (the next frame's deadline); when the wire is free then."""
    while pending:
        count = len(pending)
        while count and wire_free + bus.readback(count) > before:
            count -= 1
        if not count:
            break
        for pin in list(pending)[:count]:
            del pending[pin]
        wire_free += bus.readback(count)
    return wire_free


def _ms(ns: Fraction | int) -> str:
    return f"{float(ns) / 1e6:.2f} ms"


def _estimated_changes(train: Train) -> int:
    return math.ceil(2 * train.frequency_hz * train.duration_ns / NS_PER_S) + 2


def _common_period(trains: Iterable[Train]) -> Fraction | None:
    """The shortest time after which every train repeats (None when it exceeds any trial)."""
    periods = {1 / train.frequency_hz for train in trains}  # in seconds, exact
    numerator = math.lcm(*(p.numerator for p in periods))
    denominator = math.gcd(*(p.denominator for p in periods))
    period_ns = Fraction(numerator, denominator) * NS_PER_S
    return period_ns if period_ns <= 3600 * NS_PER_S else None


def _merged(spans: Iterable[tuple[Fraction, Fraction]]) -> list[tuple[Fraction, Fraction]]:
    merged: list[tuple[Fraction, Fraction]] = []
    for low, high in sorted(spans):
        if merged and low <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], high))
        else:
            merged.append((low, high))
    return merged


def _changes(train: Train, delay_ns: int,
             windows: list[tuple[Fraction, Fraction]] | None) -> list[Fraction]:
    """When ``train``, started ``delay_ns`` after onset, changes a goal: its first pulse, each
    pulse that starts a new position, its end (within ``windows`` when given)."""
    slot = train.slot_ns
    offset = train.phase * train.pulses_per_cycle
    first = -math.floor(offset)
    last = math.floor(train.duration_ns / slot - offset)
    end = Fraction(delay_ns + train.duration_ns)
    per_cycle, up = train.pulses_per_cycle, train.up_pulses
    spans = windows if windows is not None else [(Fraction(delay_ns), end)]
    times: list[Fraction] = []
    for low, high in spans:
        # Pulse indices whose start falls within the span.
        k_low = max(first + 1, math.ceil((low - delay_ns) / slot - offset))
        k_high = min(last, math.floor((high - delay_ns) / slot - offset))
        for cycle in range(k_low // per_cycle, k_high // per_cycle + 1):
            for k in (cycle * per_cycle, cycle * per_cycle + up):
                if k_low <= k <= k_high:
                    times.append(delay_ns + (k + offset) * slot)
        start = delay_ns + (first + offset) * slot
        if low <= start <= high and first <= last:
            times.append(start)
        if low <= end <= high:
            times.append(end)
    return times
