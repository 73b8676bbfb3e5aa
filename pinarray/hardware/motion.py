"""What the pins did: a trial's sampled positions turned into strokes, lags and a verdict.

Verified delivery proves that each goal reached its servo; it does not prove that the pin
moved the whole way. A servo too slow for a train turns back before it arrives and the
stroke shrinks. Where a family reads its servos' positions back (Feetech: Present Position,
sampled in the slack between frames), each moving pin's samples give:

commanded stroke
    The span of the goals the trial sends the pin, in steps.
achieved stroke
    The smallest peak-to-peak of the pin's samples over the trial's cycles (a cycle runs
    from one up-going goal change to the next; the last one to the trial's end), with the
    median peak-to-peak beside it.
lag
    The median time from a goal change to the first sample within `ARRIVAL_STEPS` of it
    (a change never reached counts as longer than any: none when at most half were reached).
short cycles
    Cycles whose peak-to-peak fell below the tolerance (a fraction of the commanded stroke).

A cycle is judged only when it holds at least `MIN_SAMPLES_PER_CYCLE` samples and no gap
between them (or from its edges) longer than `MAX_GAP_FRACTION` of it: sparse samples miss
the peaks and would make a good stroke look short, so such a cycle is *not measured* rather
than failed. It is not passed either: the smallest peak-to-peak is known only when every
cycle was judged, so a pin with a cycle not measured makes the trial not delivered as
specified (`TrialStrokes.problem`), as a pin that fell short does, unless the tolerance is 0
(no stroke checked). Pure values and arithmetic: no I/O.
"""

from __future__ import annotations

from array import array
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from itertools import pairwise
from typing import TYPE_CHECKING

from pinarray.hardware.delivery import Change

# No numpy here: strokes are measured in the player process, which never imports it (some
# 100 ms of processor at each start), nor do the bring-up commands, which name `PinTrace`.
# `PinTrace.of` and `goal_at`, for the numpy world, import it where they need it.
if TYPE_CHECKING:
    import numpy as np

# A trial delivers its stimulus as specified when every pin's achieved stroke is at least
# this fraction of its commanded stroke, unless the protocol says otherwise
# (device: stroke_tolerance_percent).
DEFAULT_STROKE_TOLERANCE = Fraction(8, 10)
# A pin has arrived at its goal when a sample is within this many steps of it.
ARRIVAL_STEPS = 3
MIN_SAMPLES_PER_CYCLE = 6
MAX_GAP_FRACTION = Fraction(1, 8)


@dataclass(frozen=True, eq=False)
class PinTrace:
    """One servo's sampled positions in a trial.

    Attributes
    ----------
    pin, servo_id : int
        Which pin, on which servo.
    time_ns : numpy.ndarray
        When each sample was taken, ns after the trial's onset (int64, rising).
    position_steps : numpy.ndarray
        The servo's Present Position at each sample, in steps (int32).
    """

    pin: int
    servo_id: int
    time_ns: np.ndarray
    position_steps: np.ndarray

    @classmethod
    def of(cls, samples: PinSamples) -> PinTrace:
        """The samples a player kept, as numpy arrays (int64 and int32, copies)."""
        import numpy as np

        return cls(samples.pin, samples.servo_id,
                   np.frombuffer(samples.time_ns, dtype=np.int64).copy(),
                   np.frombuffer(samples.position_steps, dtype=np.int32).copy())


@dataclass(frozen=True, eq=False)
class PinSamples:
    """One servo's sampled positions as a verifier keeps them: `PinTrace`'s columns without
    numpy (the player process imports none); `PinTrace.of` turns them into one.

    ``time_ns`` is an ``array('q')`` of ns after onset (rising), ``position_steps`` an
    ``array('i')`` of steps.
    """

    pin: int
    servo_id: int
    time_ns: array
    position_steps: array


# What a verifier hands over: numpy's arrays (the simulator computes its samples with it) or
# the player's own.
Samples = PinTrace | PinSamples


@dataclass(frozen=True)
class PinStroke:
    """One pin's motion in a trial, measured from its samples (see the module docstring).

    ``commanded_steps`` is the span of the goals the trial sent the pin; ``achieved_steps``
    and ``median_steps`` are over the cycles judged, None when none was (too few samples), as
    ``lag_ns`` is when too few arrivals were seen; ``cycles`` counts the cycles judged,
    ``short_cycles`` those that fell short, ``unmeasured_cycles`` those sampled too sparsely
    to judge.
    """

    pin: int
    commanded_steps: int
    achieved_steps: int | None
    median_steps: float | None
    lag_ns: int | None
    cycles: int
    short_cycles: int
    unmeasured_cycles: int = 0

    @property
    def measured(self) -> bool:
        """Whether any of the pin's cycles was sampled densely enough to judge (its achieved
        stroke is known); `unmeasured_cycles` says whether every one was."""
        return self.achieved_steps is not None


@dataclass(frozen=True)
class TrialStrokes:
    """Every moving pin's stroke in one trial, and the tolerance they were judged by."""

    pins: tuple[PinStroke, ...]
    tolerance: Fraction

    @property
    def worst(self) -> PinStroke | None:
        """The measured pin whose achieved stroke is the smallest share of its commanded one."""
        measured = [p for p in self.pins if p.measured and p.commanded_steps]
        return min(measured, key=lambda p: Fraction(p.achieved_steps or 0, p.commanded_steps),
                   default=None)

    @property
    def commanded_steps(self) -> int | None:
        """The worst pin's commanded stroke (any pin's when none was measured)."""
        pin = self.worst or (self.pins[0] if self.pins else None)
        return None if pin is None else pin.commanded_steps

    @property
    def unmeasured(self) -> tuple[PinStroke, ...]:
        """The pins with a stroke commanded and a cycle sampled too sparsely to judge."""
        return tuple(p for p in self.pins if p.commanded_steps and p.unmeasured_cycles)

    @property
    def short(self) -> tuple[PinStroke, ...]:
        """The measured pins that moved less than the tolerance's share of their stroke."""
        return tuple(p for p in self.pins if p.measured and p.commanded_steps
                     and Fraction(p.achieved_steps or 0, p.commanded_steps) < self.tolerance)

    def problem(self) -> str:
        """Empty when every pin was measured in every cycle and moved enough; else, in words,
        which pin fell short or, failing that, which was not measured. A tolerance of 0 checks
        no stroke: no cycle can fall short, so none unmeasured can hide one."""
        short = self.short
        if short:
            worst = min(short, key=lambda p: Fraction(p.achieved_steps or 0, p.commanded_steps))
            share = 100 * (worst.achieved_steps or 0) / worst.commanded_steps
            others = f" (and {len(short) - 1} more pin(s))" if len(short) > 1 else ""
            return (f"pin {worst.pin} moved {worst.achieved_steps} of {worst.commanded_steps} "
                    f"commanded steps ({share:.0f} %, below the tolerance of "
                    f"{float(self.tolerance) * 100:g} %) in {worst.short_cycles} of "
                    f"{worst.cycles} cycles{others}")
        unmeasured = self.unmeasured
        if not unmeasured or not self.tolerance:
            return ""
        first = max(unmeasured, key=lambda p: Fraction(p.unmeasured_cycles,
                                                        p.unmeasured_cycles + p.cycles))
        others = f" (and {len(unmeasured) - 1} more pin(s))" if len(unmeasured) > 1 else ""
        return (f"pin {first.pin}'s stroke not measured in {first.unmeasured_cycles} of "
                f"{first.unmeasured_cycles + first.cycles} cycles{others}: too few position "
                f"samples to judge (a cycle needs {MIN_SAMPLES_PER_CYCLE}, none more than "
                f"{MAX_GAP_FRACTION} of it apart); fewer moving pins, a shorter return delay "
                "(pinarray servos return-delay) or a faster baud rate leave room for them")


def measure_pin(trace: Samples, goals: Sequence[tuple[int, int]], end_ns: int,
                tolerance: Fraction = DEFAULT_STROKE_TOLERANCE) -> PinStroke:
    """One pin's stroke, lag and short cycles from its samples and its goal changes.

    Parameters
    ----------
    trace : PinTrace or PinSamples
        The pin's samples.
    goals : sequence of (time_ns, goal_steps)
        The pin's goal changes in the trial, in time order (ns after onset).
    end_ns : int
        The trial's end, ns after onset: where its last cycle ends.
    tolerance : Fraction
        A cycle whose peak-to-peak is below this share of the commanded stroke fell short.
    """
    values = [goal for _, goal in goals]
    commanded = max(values) - min(values) if values else 0
    times: list[int] = trace.time_ns.tolist()
    positions: list[int] = trace.position_steps.tolist()
    starts = [time_ns for k, (time_ns, goal) in enumerate(goals)
              if goal > (goals[k - 1][1] if k else min(values))]
    peaks: list[int] = []
    for k, start_ns in enumerate(starts):
        stop_ns = starts[k + 1] if k + 1 < len(starts) else end_ns
        peak = _peak_to_peak(times, positions, start_ns, stop_ns)
        if peak is not None:
            peaks.append(peak)
    lag_ns = _median_lag(times, positions, goals, end_ns)
    unmeasured = len(starts) - len(peaks)
    if not peaks:
        return PinStroke(trace.pin, commanded, None, None, lag_ns, 0, 0, unmeasured)
    short = sum(1 for peak in peaks if commanded and Fraction(peak, commanded) < tolerance)
    return PinStroke(trace.pin, commanded, min(peaks), median(peaks), lag_ns, len(peaks), short,
                     unmeasured)


def measure_trial(traces: Sequence[Samples], changes: Sequence[Change], end_ns: int,
                  tolerance: Fraction = DEFAULT_STROKE_TOLERANCE) -> TrialStrokes:
    """Every sampled pin of a trial measured against its goal changes (`measure_pin`)."""
    pins = []
    for trace in traces:
        goals = [(c.time_ns, c.goal_steps) for c in changes if c.servo_id == trace.servo_id]
        pins.append(measure_pin(trace, goals, end_ns, tolerance))
    return TrialStrokes(tuple(pins), tolerance)


def median(values: Sequence[int]) -> float:
    """``float(numpy.median(values))`` of integers (at least one), exactly: the middle one, or
    the two middle ones each made a float, added and halved, as numpy's mean does."""
    ordered = sorted(values)
    middle = len(ordered) // 2
    if len(ordered) % 2:
        return float(ordered[middle])
    return (float(ordered[middle - 1]) + float(ordered[middle])) / 2


def goal_at(goals: Sequence[tuple[int, int]], time_ns: np.ndarray) -> np.ndarray:
    """The goal in force at each of ``time_ns`` (-1 before the first change), in steps."""
    import numpy as np

    change_ns = np.array([t for t, _ in goals], dtype=np.int64)
    value = np.array([-1, *(g for _, g in goals)], dtype=np.int64)
    return value[np.searchsorted(change_ns, time_ns, side="right")]


def _peak_to_peak(times: list[int], positions: list[int], start_ns: int,
                  stop_ns: int) -> int | None:
    """The cycle's peak-to-peak in steps; None when its samples are too few or too sparse."""
    first, last = bisect_left(times, start_ns), bisect_left(times, stop_ns)
    if last - first < MIN_SAMPLES_PER_CYCLE:
        return None
    edges = [start_ns, *times[first:last], stop_ns]
    if max(b - a for a, b in pairwise(edges)) > (stop_ns - start_ns) * MAX_GAP_FRACTION:
        return None
    window = positions[first:last]
    return max(window) - min(window)


def _median_lag(times: list[int], positions: list[int], goals: Sequence[tuple[int, int]],
                end_ns: int) -> int | None:
    """Median time from a goal change to the first sample within `ARRIVAL_STEPS` of it,
    before the pin's next change, a change the pin never reached counting as longer than any;
    None when it reached half of them or fewer (a median of those it reached would flatter a
    servo that mostly turns back early)."""
    lags = []
    for k, (time_ns, goal) in enumerate(goals):
        until_ns = goals[k + 1][0] if k + 1 < len(goals) else end_ns
        near = next((i for i in range(bisect_left(times, time_ns), bisect_left(times, until_ns))
                     if abs(positions[i] - goal) <= ARRIVAL_STEPS), None)
        if near is not None:
            lags.append(times[near] - time_ns)
    lags.sort()
    # The unreached changes sort after every reached one: the median of all the changes is
    # known only while its middle falls among the reached ones.
    low, high = (len(goals) - 1) // 2, len(goals) // 2
    if high >= len(lags):
        return None
    return (lags[low] + lags[high]) // 2
