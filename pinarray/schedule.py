"""The schedule compiler: exact integer-nanosecond events from trains and waves. No I/O.

Every time is computed from an absolute pulse index with rational arithmetic and rounded once
to the nearest nanosecond (halves up): pulse ``k`` of a train starts at
``round((k + phase * pulses_per_cycle) * slot)``, never at an accumulated sum of periods, so
the last pulse of a 24 h train lands on the exact rational time.

Two views of a trial:

- `PulseList`: every servo pulse (pin, start, width), for pulse-driven outputs (a DAQ).
- `TargetList`: servo goal positions for bus servos, holding only *changes* of target.

Work is proportional to the number of pulses of the active pins: idle pins and the size of
the array cost nothing.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from math import gcd

import numpy as np

from pinarray.errors import PinArrayError
from pinarray.feasibility import check_train
from pinarray.protocol import Device, PinDrive, Protocol, Train

# Largest intermediate the int64 path may meet; beyond it we fall back to exact Python ints.
_INT64_SAFE = 2**62


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


def _exact_times_ns(k: np.ndarray, offset: Fraction, step: Fraction) -> np.ndarray:
    """``round((k * step + offset))`` in ns for integer indices ``k``, rounding halves up.

    Writes ``k*step + offset = (k*A + B) / D`` and splits ``k = a*D + b`` so that the int64
    products stay small: ``a*A + round((b*A + B) / D)``.
    """
    denominator = step.denominator * offset.denominator // gcd(step.denominator, offset.denominator)
    a_num = step.numerator * (denominator // step.denominator)
    b_num = offset.numerator * (denominator // offset.denominator)
    if 2 * (denominator * abs(a_num) + abs(b_num)) + denominator >= _INT64_SAFE:
        # Exotic decimals (e.g. 3.14159 Hz) need more than 64 bits: stay exact, pay for it.
        big = [(2 * (int(x) * a_num + b_num) + denominator) // (2 * denominator) for x in k]
        return np.array(big, dtype=np.int64)
    k = k.astype(np.int64)
    whole, part = np.divmod(k, denominator)
    return whole * a_num + (2 * (part * a_num + b_num) + denominator) // (2 * denominator)


def pulse_indices(train: Train) -> np.ndarray:
    """Absolute indices of the train's pulses that start at or after 0 (phase may shift them)."""
    offset_slots = train.phase * train.pulses_per_cycle
    first = -int(offset_slots)  # floor: the earliest pulse at a time >= 0
    last = int((train.duration_ns / train.slot_ns) - offset_slots)  # start <= duration
    return np.arange(first, max(first, last + 1), dtype=np.int64)


def train_pulses(train: Train) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(start_ns, width_ns, is_up) of every pulse that ends within the signal length."""
    k = pulse_indices(train)
    starts = _exact_times_ns(k, train.phase * train.pulses_per_cycle * train.slot_ns, train.slot_ns)
    is_up = np.mod(k, train.pulses_per_cycle) < train.up_pulses
    widths = np.where(is_up, train.up_width_ns, train.down_width_ns).astype(np.int64)
    keep = (starts >= 0) & (starts + widths <= train.duration_ns)
    return starts[keep], widths[keep], is_up[keep]


def check_no_overlap(drives: Sequence[PinDrive]) -> None:
    by_pin: dict[int, list[PinDrive]] = {}
    for drive in drives:
        by_pin.setdefault(drive.pin, []).append(drive)
    for pin, pin_drives in by_pin.items():
        pin_drives.sort(key=lambda d: d.delay_ns)
        for before, after in itertools.pairwise(pin_drives):
            if before.delay_ns + before.train.duration_ns > after.delay_ns:
                raise PinArrayError(
                    f"pin {pin} is driven twice at once: a train from {before.delay_ns / 1e6:g} ms "
                    f"lasting {before.train.duration_ns / 1e6:g} ms overlaps one starting at "
                    f"{after.delay_ns / 1e6:g} ms; lengthen the SOA or shorten the train"
                )


def compile_drives(drives: Sequence[PinDrive], device: Device) -> TrialSchedule:
    """Compile the pin drives of one trial into pulses and changed-only servo targets."""
    check_no_overlap(drives)
    pulse_parts: list[tuple[np.ndarray, ...]] = []
    target_parts: list[tuple[np.ndarray, ...]] = []
    end_ns = 0
    for order, drive in enumerate(drives):
        calibration = device.calibration(drive.pin)
        starts, widths, is_up = train_pulses(drive.train)
        starts = starts + drive.delay_ns
        pins = np.full(len(starts), drive.pin, dtype=np.int16)
        pulse_parts.append((pins, starts, widths))

        up = calibration.position_for_width(drive.train.up_width_ns)
        down = calibration.position_for_width(drive.train.down_width_ns)
        if device.scale_infeasible:
            # The protocol asked for strokes the servo cannot follow to shrink, not fail.
            fraction = check_train(drive.train, calibration, device.servo).amplitude_fraction
            up = down + int((up - down) * fraction)
        positions = np.where(is_up, up, down).astype(np.int32)
        drive_end_ns = drive.delay_ns + drive.train.duration_ns
        # The drive starts from rest and hands the pin back at rest when its signal ends.
        times = np.concatenate((starts, [drive_end_ns]))
        positions = np.concatenate((positions, [calibration.rest_steps])).astype(np.int32)
        target_parts.append(
            (
                np.full(len(times), drive.pin, dtype=np.int16),
                times,
                positions,
                np.full(len(times), order, dtype=np.int32),
            )
        )
        end_ns = max(end_ns, drive_end_ns)

    if pulse_parts:
        pin, start, width = (np.concatenate(column) for column in zip(*pulse_parts, strict=True))
    else:
        pin, start, width = (np.empty(0, np.int16), np.empty(0, np.int64), np.empty(0, np.int64))
    by_time = np.lexsort((pin, start))
    pulses = PulseList(pin[by_time], start[by_time], width[by_time])
    return TrialSchedule(tuple(drives), pulses, _changes_only(target_parts, device, end_ns), end_ns)


def _changes_only(parts: list[tuple[np.ndarray, ...]], device: Device, end_ns: int) -> TargetList:
    if not parts:
        empty = np.empty(0, np.int64)
        return TargetList(empty, empty.astype(np.int16), empty.astype(np.int32), end_ns)
    pin, time, position, order = (np.concatenate(column) for column in zip(*parts, strict=True))
    # Per pin in time order; at equal times the later drive wins (one ends as the next starts).
    index = np.lexsort((order, time, pin))
    pin, time, position = pin[index], time[index], position[index]
    same_instant_next = np.zeros(len(pin), dtype=bool)
    same_instant_next[:-1] = (pin[1:] == pin[:-1]) & (time[1:] == time[:-1])
    keep = ~same_instant_next
    pin, time, position = pin[keep], time[keep], position[keep]
    previous = np.empty_like(position)
    previous[1:] = position[:-1]
    first_of_pin = np.ones(len(pin), dtype=bool)
    first_of_pin[1:] = pin[1:] != pin[:-1]
    # Only the active pins' rest positions: the array's size must not cost anything.
    previous[first_of_pin] = [device.calibration(int(p)).rest_steps for p in pin[first_of_pin]]
    changed = position != previous
    pin, time, position = pin[changed], time[changed], position[changed]
    by_time = np.lexsort((pin, time))
    return TargetList(time[by_time], pin[by_time], position[by_time], end_ns)


def trial_drives(protocol: Protocol, condition) -> tuple[PinDrive, ...]:
    """The pin drives a design condition asks for."""
    stimulus = protocol.stimulus(condition.stimulus)
    if stimulus.wave is not None:
        return stimulus.wave.drives()
    assert stimulus.train is not None
    train = stimulus.train
    if condition.frequency_hz is not None:
        train = train.with_frequency(condition.frequency_hz)
    return (PinDrive(condition.pin, train, 0),)


def compile_trial(protocol: Protocol, planned_trial) -> TrialSchedule:
    """Compile one trial of a plan (see `pinarray.plan`)."""
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
    row_of_pin = {pin: row for row, pin in enumerate(pins)}
    out = np.zeros((len(pins), samples), dtype=bool)
    rows = np.array([row_of_pin.get(int(p), -1) for p in pulses.pin], dtype=np.int64)
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


def _first_sample_at_or_after(time_ns: np.ndarray, sample_rate_hz: int) -> np.ndarray:
    """ceil(time_ns * rate / 1e9) without int64 overflow for day-long schedules."""
    whole_s, rest_ns = np.divmod(time_ns.astype(np.int64), 1_000_000_000)
    return whole_s * sample_rate_hz + (rest_ns * sample_rate_hz + 999_999_999) // 1_000_000_000
