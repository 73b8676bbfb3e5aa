"""The schedule compiler: exact integer-nanosecond events from trains and waves. No I/O.

Every time is computed from an absolute pulse index with rational arithmetic and rounded once
to the nearest nanosecond (halves up): pulse ``k`` of a train starts at
``round((k + phase * pulses_per_cycle) * slot)``, never at an accumulated sum of periods, so
the last pulse of a 24 h train lands on the exact rational time.

Two views of a trial:

- `PulseList`: every servo pulse (pin, start, width), for pulse-driven outputs (a DAQ).
- `TargetList`: servo goal positions for bus servos, holding only *changes* of target.

Work and memory grow with the pulses of the active pins only: idle pins and the size of the
array cost nothing. The times of a train repeat with a period of ``D`` pulses, ``D`` being the
denominator of the slot in ns: pulse ``k + D`` starts exactly ``D * slot`` (a whole number of)
ns after pulse ``k``. So only the first ``D`` pulses are computed from their indices; the rest
of the train is whole-ns additions of that block onto itself, written straight into the output
arrays, with no schedule-length temporaries. Servo targets change at the same few places of
every cycle, so they are read off the pulse times with strided slices.

Past 400 lines on purpose: the exact-arithmetic compiler for trains, waves and their merge;
its parts share the same index arithmetic and are property-tested as one. Its two samplers for
a DAQ (`render_dense`, and `daq_words` a block at a time) share the rule of which sample a
pulse covers.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from math import lcm
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from pinarray.errors import PinArrayError
from pinarray.units import NS_PER_S

# The protocol's types are read only by the compiler's functions, which import them as they
# run: the player process unpickles `TargetList`s and `PulseList`s from here and needs none
# of the protocol's dozens of value types (some 35 ms of its start-up).
if TYPE_CHECKING:
    from pinarray.protocol import Device, PinDrive, Protocol, Train

__all__ = [
    "Frame",
    "PulseList",
    "TargetList",
    "TrialSchedule",
    "compile_drives",
    "compile_trial",
    "DAQ_LINES",
    "daq_sample_count",
    "daq_words",
    "pulse_indices",
    "render_dense",
    "train_pulses",
]

# Largest intermediate the int64 path may meet; beyond it we fall back to exact Python ints.
_INT64_SAFE = 2**62
# Pulses computed at once from their indices: bounds the temporaries of that path.
_CHUNK = 1 << 16


@dataclass(frozen=True)
class PulseList:
    """Servo pulses of one trial, sorted by start then pin; times from stimulus onset."""

    pin: np.ndarray  # int16
    start_ns: np.ndarray  # int64
    width_ns: np.ndarray  # int64

    def __len__(self) -> int:
        return len(self.pin)


@dataclass(frozen=True)
class Frame:
    """All target changes due at one instant."""

    time_ns: int
    pins: np.ndarray
    position_steps: np.ndarray


@dataclass(frozen=True)
class TargetList:
    """Goal-position changes of one trial, sorted by time then pin.

    Holds only changes: a pin whose target stays put appears nowhere. By ``end_ns`` every pin
    has been sent back to its rest position.
    """

    time_ns: np.ndarray  # int64
    pin: np.ndarray  # int16
    position_steps: np.ndarray  # int32
    end_ns: int

    def __len__(self) -> int:
        return len(self.time_ns)

    def frames(self) -> Iterator[Frame]:
        if not len(self.time_ns):
            return
        boundaries = np.flatnonzero(np.diff(self.time_ns)) + 1
        starts = np.concatenate(([0], boundaries))
        stops = np.concatenate((boundaries, [len(self.time_ns)]))
        for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
            yield Frame(int(self.time_ns[a]), self.pin[a:b], self.position_steps[a:b])


@dataclass(frozen=True)
class TrialSchedule:
    """One trial compiled: what each pin does, as pulses and as servo targets."""

    drives: tuple[PinDrive, ...]
    pulses: PulseList
    targets: TargetList
    end_ns: int

    @property
    def active_pins(self) -> tuple[int, ...]:
        return tuple(sorted({d.pin for d in self.drives}))


class _Line(NamedTuple):
    """Pulse start times as ``(k * step + offset) / denominator`` ns, all whole numbers."""

    step: int
    offset: int
    denominator: int


def _line(offset_ns: Fraction, step_ns: Fraction) -> _Line:
    denominator = lcm(step_ns.denominator, offset_ns.denominator)
    return _Line(
        step_ns.numerator * (denominator // step_ns.denominator),
        offset_ns.numerator * (denominator // offset_ns.denominator),
        denominator,
    )


def _exact_times_ns(k: np.ndarray, line: _Line) -> np.ndarray:
    """``round((k * step + offset) / denominator)`` for integer indices ``k``, halves up.

    Splits ``k = a * D + b``, ``step = q * D + r`` and ``offset = p * D + s`` (floor division:
    ``b``, ``r`` and ``s`` lie in ``[0, D)``) so that the int64 products stay below ``D**2``:
    ``a * step + b * q + p + round((b * r + s) / D)``. Exotic decimals (3.14159 Hz: ``D`` in
    the millions, ``step`` near 1e14) fit so; ``b * step`` alone did not.
    """
    step, offset, d = line
    q, r = divmod(step, d)
    p, s = divmod(offset, d)
    if 2 * (d * d + d) + d >= _INT64_SAFE or max(abs(step), abs(offset)) >= _INT64_SAFE:
        # Denominators past about 1.5e9 need more than 64 bits: stay exact, pay for it.
        big = [(2 * (int(x) * step + offset) + d) // (2 * d) for x in k]
        return np.array(big, dtype=np.int64)
    whole, part = np.divmod(k.astype(np.int64), d)
    return whole * step + part * q + p + (2 * (part * r + s) + d) // (2 * d)


def _extend_periodic(out: np.ndarray, period: int, increment: int) -> None:
    """Fill ``out[period:]`` from ``out[:period]`` so that ``out[i + period] = out[i] + increment``.

    Adds doubling blocks of the array onto its own end: each element is written once, in long
    vectorised runs, and nothing is allocated.
    """
    filled = period
    while filled < len(out):
        count = min(filled, len(out) - filled)
        if increment:
            np.add(out[:count], filled // period * increment, out=out[filled : filled + count])
        else:
            out[filled : filled + count] = out[:count]
        filled += count


def _fill_starts(out: np.ndarray, first: int, line: _Line, shift_ns: int) -> None:
    """``out[i]`` = the start of pulse ``first + i``, plus ``shift_ns``, exact to the ns."""
    head = min(len(out), line.denominator)  # one period of the times, or the whole train
    for a in range(0, head, _CHUNK):
        b = min(head, a + _CHUNK)
        out[a:b] = _exact_times_ns(np.arange(first + a, first + b, dtype=np.int64), line)
        if shift_ns:
            out[a:b] += shift_ns
    _extend_periodic(out, head, line.step)


def _fill_cycle(out: np.ndarray, first: int, cycle: Sequence[int | bool]) -> None:
    """``out[i] = cycle[(first + i) % len(cycle)]``."""
    head = min(len(out), len(cycle))
    out[:head] = [cycle[(first + i) % len(cycle)] for i in range(head)]
    _extend_periodic(out, head, 0)


def _check_periods(train: Train) -> None:
    # Pulses of at least 1 ns within their period keep starts rising and keep the pulses that
    # fit one run of consecutive indices, which the servo targets below rely on (and a servo
    # pulse longer than its period means nothing).
    narrowest_ns = min(train.up_width_ns, train.down_width_ns)
    widest_ns = max(train.up_width_ns, train.down_width_ns)
    if narrowest_ns < 1 or widest_ns > train.slot_ns:
        found_ns = widest_ns if widest_ns > train.slot_ns else narrowest_ns
        raise PinArrayError(
            "expected pulse widths of at least 1 ns within the pulse period: at "
            f"{float(train.frequency_hz):g} Hz the period is {float(train.slot_ns) / 1e6:g} ms, "
            f"found a {found_ns / 1e6:g} ms pulse"
        )


def pulse_indices(train: Train) -> np.ndarray:
    """Absolute indices of the train's pulses that start at or after 0 (phase may shift them).

    The last ones may still end past the signal length; `train_pulses` drops those.
    """
    first, count = _index_range(train)
    return np.arange(first, first + count, dtype=np.int64)


def _index_range(train: Train) -> tuple[int, int]:
    offset_slots = train.phase * train.pulses_per_cycle
    first = -int(offset_slots)  # floor: the earliest pulse at a time >= 0
    last = int((train.duration_ns / train.slot_ns) - offset_slots)  # start <= duration
    return first, max(0, last + 1 - first)


class _TrainPulses(NamedTuple):
    first: int  # absolute index of the first pulse kept
    start_ns: np.ndarray  # int64, strictly rising
    width_ns: np.ndarray  # int64


def _train_pulses(
    train: Train, delay_ns: int = 0, out: tuple[np.ndarray, np.ndarray] | None = None
) -> _TrainPulses:
    """The pulses of ``train`` that start at or after 0 and end within its length, delayed.

    ``out``: arrays for the starts and widths, as long as `_index_range` counts, to write
    into instead of new ones; the pulses kept are views of their beginning.
    """
    _check_periods(train)
    first, count = _index_range(train)
    slot_ns = train.slot_ns
    line = _line(train.phase * train.pulses_per_cycle * slot_ns, slot_ns)
    starts, widths = out or (np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64))
    _fill_starts(starts, first, line, delay_ns)
    cycle = [train.up_width_ns] * train.up_pulses + [train.down_width_ns] * (
        train.pulses_per_cycle - train.up_pulses
    )
    _fill_cycle(widths, first, cycle[: train.pulses_per_cycle])
    # The first index is the earliest pulse at or after onset. Starts rise by at least the
    # whole part of a slot and no width exceeds it, so the pulses that end within the signal
    # are a run from the first, and only the last few need a look.
    end_ns = delay_ns + train.duration_ns
    kept = int(np.searchsorted(starts, end_ns - max(cycle), side="right"))
    while kept < count and starts[kept] + widths[kept] <= end_ns:
        kept += 1
    return _TrainPulses(first, starts[:kept], widths[:kept])


def train_pulses(train: Train) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(start_ns, width_ns, is_up) of every pulse that ends within the signal length."""
    first, starts, widths = _train_pulses(train)
    is_up = np.empty(len(starts), dtype=bool)
    _fill_cycle(is_up, first, [j < train.up_pulses for j in range(train.pulses_per_cycle)])
    return starts, widths, is_up


def _drive_targets(
    pulses: _TrainPulses, train: Train, up: int, down: int, rest: int, end_ns: int
) -> tuple[np.ndarray, np.ndarray]:
    """One drive's own targets: (time_ns, position_steps) in time order.

    The first pulse's position, then every pulse whose position differs from the pulse before
    it, then rest at the drive's end. Only the first and last may repeat what came before;
    `_pin_changes` looks at those when it joins the drives of a pin.
    """
    first, starts, _ = pulses
    count = len(starts)  # every pulse ends by end_ns and lasts at least 1 ns: none starts then
    per_cycle = train.pulses_per_cycle
    cycle = [up if j < train.up_pulses else down for j in range(per_cycle)]
    # Where the cycle changes position, as the pulse offset (1..per_cycle) of its first such
    # pulse after the drive's first pulse; in offset order the slices interleave in time.
    offsets = sorted(
        ((r - first) % per_cycle or per_cycle, cycle[r])
        for r in range(per_cycle)
        if cycle[r] != cycle[r - 1]
    )
    body = sum(len(range(offset, count, per_cycle)) for offset, _ in offsets)
    times = np.empty(body + 2, dtype=np.int64)
    positions = np.empty(body + 2, dtype=np.int32)
    times[-1], positions[-1] = end_ns, rest
    if not count:
        return times[-1:], positions[-1:]
    times[0], positions[0] = starts[0], cycle[first % per_cycle]
    for j, (offset, position) in enumerate(offsets):
        times[1 + j : 1 + body : len(offsets)] = starts[offset:count:per_cycle]
        positions[1 + j : 1 + body : len(offsets)] = position
    return times, positions


def _pin_changes(
    drives: list[tuple[np.ndarray, np.ndarray]], rest: int
) -> tuple[np.ndarray, np.ndarray]:
    """The changes of target of one pin, from its drives' own targets in time order.

    Drives of a pin never overlap, so only their boundaries need a look: a first target equal
    to the position before it is dropped, so is an end at rest after rest, and where one drive
    ends at the instant the next begins, the next drive's first target wins.
    """
    spans: list[list[int]] = []  # [drive, low, high): runs of targets kept, merged when adjacent

    def keep(drive: int, low: int, high: int) -> None:
        if spans and spans[-1][0] == drive and spans[-1][2] == low:
            spans[-1][2] = high
        else:
            spans.append([drive, low, high])

    position = rest
    last_end: tuple[int, bool, int] | None = None  # time, kept, position before it
    for index, (times, positions) in enumerate(drives):
        if last_end is not None and last_end[0] == times[0]:
            _, kept, position = last_end
            if kept:
                spans[-1][2] -= 1
                if spans[-1][1] == spans[-1][2]:
                    spans.pop()
        body = len(times) - 1
        low = 1 if body and positions[0] == position else 0
        if low < body:
            keep(index, low, body)
            position = int(positions[body - 1])
        end = int(positions[body])
        last_end = (int(times[body]), end != position, position)
        if end != position:
            keep(index, body, body + 1)
        position = end
    if len(spans) == 1:
        drive, low, high = spans[0]
        return drives[drive][0][low:high], drives[drive][1][low:high]
    return (
        np.concatenate([drives[d][0][a:b] for d, a, b in spans] or [np.empty(0, np.int64)]),
        np.concatenate([drives[d][1][a:b] for d, a, b in spans] or [np.empty(0, np.int32)]),
    )


def compile_drives(drives: Sequence[PinDrive], device: Device) -> TrialSchedule:
    """Compile the pin drives of one trial into pulses and changed-only servo targets.

    Where one drive ends at the instant the next on its pin begins, the servo target of the
    one that begins wins.
    """
    from pinarray.protocol.drives import check_no_overlap
    from pinarray.protocol.feasibility import check_train

    check_no_overlap(drives)
    # Pin, then time order: the order the pulses of equal starts take.
    ordered = sorted(drives, key=lambda d: (d.pin, d.delay_ns))
    end_ns = max((d.delay_ns + d.train.duration_ns for d in drives), default=0)
    if len({(d.train, d.delay_ns) for d in ordered}) == 1:
        shared = _train_pulses(ordered[0].train, ordered[0].delay_ns)
        each = [shared] * len(ordered)
        pulses = _one_train_pulses([d.pin for d in ordered], shared)
    else:
        each, pulses = _sorted_pulses(ordered)

    own_targets: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for drive, drive_pulses in zip(ordered, each, strict=True):
        calibration = device.calibration(drive.pin)
        up = calibration.position_for_width(drive.train.up_width_ns)
        down = calibration.position_for_width(drive.train.down_width_ns)
        if device.scale_infeasible:
            # The protocol asked for strokes the servo cannot follow to shrink, not fail.
            fraction = check_train(drive.train, calibration, device).amplitude_fraction
            up = down + int((up - down) * fraction)
        own_targets.setdefault(drive.pin, []).append(
            _drive_targets(
                drive_pulses,
                drive.train,
                up,
                down,
                calibration.rest_steps,
                drive.delay_ns + drive.train.duration_ns,
            )
        )
    # Only the active pins' rest positions: the array's size must not cost anything.
    by_pin = [
        (pin, _pin_changes(parts, device.calibration(pin).rest_steps))
        for pin, parts in own_targets.items()
    ]
    return TrialSchedule(tuple(drives), pulses, _merge_targets(by_pin, end_ns), end_ns)


def _one_train_pulses(pins: list[int], train: _TrainPulses) -> PulseList:
    """The pulses of one train played at once on distinct ``pins`` (in order), by start, pin.

    Each start repeats once per pin: an interleave, with nothing to sort.
    """
    if len(pins) == 1:
        return PulseList(np.full(len(train.start_ns), pins[0], np.int16), *train[1:])
    shape = (len(train.start_ns), len(pins))
    pin, start, width = (np.empty(shape, dtype) for dtype in (np.int16, np.int64, np.int64))
    pin[:] = pins
    start[:] = train.start_ns[:, None]
    width[:] = train.width_ns[:, None]
    return PulseList(pin.ravel(), start.ravel(), width.ravel())


def _sorted_pulses(ordered: list[PinDrive]) -> tuple[list[_TrainPulses], PulseList]:
    """Each drive's pulses and all of them by start then pin, from drives in pin, time order.

    The drives write their pulses one after the other into one buffer (no copy to join them);
    each drive's run is sorted, and a stable sort keeps equal starts in pin order.
    """
    counts = [_index_range(d.train)[1] for d in ordered]
    start = np.empty(sum(counts), dtype=np.int64)
    width = np.empty(sum(counts), dtype=np.int64)
    pin = np.empty(sum(counts), dtype=np.int16)
    each = []
    used = 0
    for drive, count in zip(ordered, counts, strict=True):
        out = (start[used : used + count], width[used : used + count])
        each.append(_train_pulses(drive.train, drive.delay_ns, out))
        pin[used : used + len(each[-1].start_ns)] = drive.pin
        used += len(each[-1].start_ns)
    by_time = np.argsort(start[:used], kind="stable")
    return each, PulseList(pin[by_time], start[by_time], width[by_time])


def _merge_targets(
    by_pin: list[tuple[int, tuple[np.ndarray, np.ndarray]]], end_ns: int
) -> TargetList:
    """All pins' target changes by time then pin."""
    by_pin.sort(key=lambda item: item[0])
    if len(by_pin) == 1:
        only, (times, positions) = by_pin[0]
        return TargetList(times, np.full(len(times), only, np.int16), positions, end_ns)
    if not by_pin:
        empty = np.empty(0, np.int64)
        return TargetList(empty, empty.astype(np.int16), empty.astype(np.int32), end_ns)
    pin = np.concatenate([np.full(len(t), p, np.int16) for p, (t, _) in by_pin])
    time = np.concatenate([t for _, (t, _) in by_pin])
    position = np.concatenate([s for _, (_, s) in by_pin])
    # Each pin's changes are in time order; the stable sort keeps equal times in pin order.
    by_time = np.argsort(time, kind="stable")
    return TargetList(time[by_time], pin[by_time], position[by_time], end_ns)


def compile_trial(protocol: Protocol, planned_trial) -> TrialSchedule:
    """Compile one trial of a plan (see `pinarray.plan`)."""
    from pinarray.protocol.drives import trial_drives

    return compile_drives(trial_drives(protocol, planned_trial.condition), protocol.device)


def render_dense(
    pulses: PulseList, pins: Sequence[int], sample_rate_hz: int, end_ns: int
) -> np.ndarray:
    """Sample the pulse outputs for a DAQ: a bool array (len(pins), samples), True while high.

    Sample ``n`` is taken at ``n / sample_rate_hz`` s and is high when a pulse covers it, so each
    edge moves to the next sample instant: the worst-case edge error is one sample period.
    """
    if sample_rate_hz <= 0:
        raise PinArrayError(f"sample rate must be a positive number of Hz, found {sample_rate_hz}")
    samples = _first_sample_at_or_after(np.array([end_ns], dtype=np.int64), sample_rate_hz)[0]
    out = np.zeros((len(pins), samples), dtype=bool)
    # Row of each pulse's pin, -1 for pins not asked for: one table lookup per pulse.
    row_of_pin = np.full(max([*pins, int(pulses.pin.max(initial=0))]) + 1, -1, dtype=np.int64)
    row_of_pin[list(pins)] = np.arange(len(pins))
    rows = row_of_pin[pulses.pin]
    chosen = rows >= 0
    if not chosen.any():
        return out
    rows = rows[chosen]
    first = _first_sample_at_or_after(pulses.start_ns[chosen], sample_rate_hz)
    stop = _first_sample_at_or_after(
        pulses.start_ns[chosen] + pulses.width_ns[chosen], sample_rate_hz
    )
    edges = np.zeros((len(pins), samples + 1), dtype=np.int32)
    np.add.at(edges, (rows, np.minimum(first, samples)), 1)
    np.add.at(edges, (rows, np.minimum(stop, samples)), -1)
    out[:] = np.cumsum(edges, axis=1)[:, :samples] > 0
    return out


# The DAQ's digital lines: pin n drives line n - 1, one bit of a uint16 sample.
DAQ_LINES = 16


def daq_sample_count(end_ns: int, sample_rate_hz: int) -> int:
    """Samples of a trial on the DAQ's lines: every instant ``n / sample_rate_hz`` s from its
    onset up to and including its end ``end_ns``, at which every pulse is over.

    One more than `render_dense` gives where the end falls on a sample instant, and never
    fewer: the last sample is low on every line, so a finite task leaves the lines low.
    """
    return end_ns * sample_rate_hz // NS_PER_S + 1


def daq_words(
    pulses: PulseList, sample_rate_hz: int, count: int, block: int = 1 << 18
) -> Iterator[np.ndarray]:
    """Samples 0 to ``count - 1`` of a trial for a DAQ's 16 lines, ``block`` at a time.

    Each sample is a uint16 word, bit ``pin - 1`` high while a pulse of that pin covers the
    sample's instant: `render_dense`'s rule, exact in integers. Memory is a few ``block``-sized
    arrays whatever ``count`` is; only the pulses that reach a block are looked at.
    """
    if sample_rate_hz <= 0:
        raise PinArrayError(f"sample rate must be a positive number of Hz, found {sample_rate_hz}")
    if len(pulses) and not 1 <= int(pulses.pin.min()) <= int(pulses.pin.max()) <= DAQ_LINES:
        outside = int(pulses.pin.max()) if pulses.pin.max() > DAQ_LINES else int(pulses.pin.min())
        raise PinArrayError(
            f"expected pins 1 to {DAQ_LINES}, one per line of the DAQ's uint16 samples, "
            f"found pin {outside}"
        )
    # Pulses of one pin never overlap (drives of a pin do not, and no width exceeds its
    # period), nor do their spans of samples: so each pin's bit is added and taken away once
    # per pulse, and a running sum of those steps is the word. The word only changes where a
    # pulse begins or ends: the sum runs over those changes, and each level is repeated up to
    # the next (a 100 kHz block of 10 Hz pulses holds a few changes, not 262 144 sums).
    widest_ns = int(pulses.width_ns.max(initial=0))
    for a in range(0, count, block):
        b = min(count, a + block)
        # Pulses whose first sample is before b, and that may still be high at a.
        low = np.searchsorted(pulses.start_ns, a * NS_PER_S // sample_rate_hz - widest_ns,
                              side="right")
        high = np.searchsorted(pulses.start_ns, (b - 1) * NS_PER_S // sample_rate_hz,
                               side="right")
        start_ns = pulses.start_ns[low:high]
        first = _first_sample_at_or_after(start_ns, sample_rate_hz) - a
        stop = _first_sample_at_or_after(start_ns + pulses.width_ns[low:high], sample_rate_hz) - a
        bits = np.left_shift(1, pulses.pin[low:high].astype(np.int32) - 1)
        at = np.concatenate((np.clip(first, 0, b - a), np.clip(stop, 0, b - a)))
        order = np.argsort(at, kind="stable")
        levels = np.cumsum(np.concatenate((bits, -bits))[order], dtype=np.int32)
        # Level 0 up to the first change, then each change's level up to the next; changes at
        # one sample give runs of none, and those at b (or later) hold for none of the block.
        held = np.diff(np.concatenate(([0], at[order], [b - a])))
        yield np.repeat(np.concatenate(([0], levels)).astype("<u2"), held)


def _first_sample_at_or_after(time_ns: np.ndarray, sample_rate_hz: int) -> np.ndarray:
    """ceil(time_ns * rate / 1e9) without int64 overflow for day-long schedules."""
    whole_s, rest_ns = np.divmod(time_ns.astype(np.int64), 1_000_000_000)
    return whole_s * sample_rate_hz + (rest_ns * sample_rate_hz + 999_999_999) // 1_000_000_000
