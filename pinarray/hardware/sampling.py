"""Which samples of the moving pins a trial's measured motion needs, and which decide nothing.

`pinarray.hardware.motion` measures each pin from its samples: per cycle the peak-to-peak
(judged only with at least `MIN_SAMPLES_PER_CYCLE` samples and no gap longer than
`MAX_GAP_FRACTION` of the cycle), per goal change the lag to the first sample within
`ARRIVAL_STEPS` of the goal. Sampled every `period_ns` throughout, a pin that has arrived
and holds its goal gives the same reading again and again until its next goal change: those
readings change no peak (the held position is already among the samples), no lag (the
arrival is already seen) and no count that matters. So while *every* moving pin holds, the
next sample is taken only when the cycle's gap rule needs it, and once just before the next
goal change of any moving pin (as late as it still fits before that frame); from the change
on, every period again. The gap rule is kept with what follows a change budgeted: the
frame's read-back and a sample after it (several servos on a slow bus take tens of ms); where
that budget leaves no room, samples are not held back at all.

A pin holds when its last two samples read the same position within `ARRIVAL_STEPS` of the
goal in force. A horn pushed off its goal between two sparse samples (a finger pressing
down, say) shows at the next one, at most a gap of the cycle rule later.

The same rule says when a sample *must* be taken where the usual ones would leave a gap too
long (`Holds.gap_fits`), and how late it may come (`Holds.reach_ns`): on a bus where one
sample of the moving servos takes milliseconds (many pins, the factory return delay, a slow
baud rate), the gap across a frame (the last sample before it, the frame, the read-back after
it, the next sample) can be longer than a cycle allows; the verifier then reads the goals
back and samples in one exchange, and takes the last sample before the frame as late as fits
(`pinarray.hardware.feetech.readback`).

Pure arithmetic on the trial's goal changes and the samples: no I/O, no clock.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

from pinarray.hardware.delivery import Change
from pinarray.hardware.motion import ARRIVAL_STEPS, MAX_GAP_FRACTION

NEVER_NS = 2**62  # later than any trial ends
# `MAX_GAP_FRACTION` as integers: a gap of ``g`` ns fits a cycle of ``c`` ns when
# ``g * _GAP_DEN <= c * _GAP_NUM`` (exact, and without a Fraction on the verifier's every sample).
_GAP_NUM, _GAP_DEN = MAX_GAP_FRACTION.numerator, MAX_GAP_FRACTION.denominator


def _allowed_ns(cycle_ns: int) -> int:
    """The longest gap a cycle of ``cycle_ns`` allows, in whole ns (toward zero)."""
    allowed = abs(cycle_ns) * _GAP_NUM // _GAP_DEN
    return allowed if cycle_ns >= 0 else -allowed


@dataclass(frozen=True)
class PinGoals:
    """One servo's goal changes in a trial, and where its cycles start (ns after onset)."""

    change_ns: tuple[int, ...]
    goal_steps: tuple[int, ...]
    cycle_start_ns: tuple[int, ...]  # its up-going changes, as `motion.measure_pin` cuts cycles

    @classmethod
    def of(cls, changes: Sequence[Change]) -> PinGoals:
        """From one servo's changes, in time order."""
        goals = [c.goal_steps for c in changes]
        lowest = min(goals, default=0)
        starts = tuple(c.time_ns for k, c in enumerate(changes)
                       if c.goal_steps > (goals[k - 1] if k else lowest))
        return cls(tuple(c.time_ns for c in changes), tuple(goals), starts)

    def goal_at(self, time_ns: int) -> int | None:
        """The goal in force at ``time_ns`` (None before the first change)."""
        index = bisect_right(self.change_ns, time_ns)
        return self.goal_steps[index - 1] if index else None

    def next_change_ns(self, time_ns: int) -> int:
        """The servo's first goal change after ``time_ns`` (never: a very large number)."""
        index = bisect_right(self.change_ns, time_ns)
        return self.change_ns[index] if index < len(self.change_ns) else NEVER_NS

    def gap_fits(self, from_ns: int, to_ns: int, end_ns: int) -> bool:
        """Whether no sample from ``from_ns`` to ``to_ns`` (ns after onset) keeps the cycle
        rule: each part of the gap inside one cycle (a cycle's start and end count as edges,
        as `pinarray.hardware.motion` cuts them) at most `MAX_GAP_FRACTION` of that cycle."""
        starts = self.cycle_start_ns
        index = bisect_right(starts, from_ns)  # cycle index - 1 holds from_ns (0: none yet)
        left_ns = from_ns
        while left_ns < min(to_ns, end_ns):
            stop_ns = starts[index] if index < len(starts) else end_ns
            right_ns = min(to_ns, stop_ns)
            if index and (right_ns - left_ns) * _GAP_DEN > (stop_ns - starts[index - 1]) * _GAP_NUM:
                return False
            left_ns, index = right_ns, index + 1
        return True

    def reach_ns(self, from_ns: int, end_ns: int) -> int:
        """The latest a sample may follow one at ``from_ns`` (ns after onset) and keep the cycle
        rule: `gap_fits` from ``from_ns`` exactly up to it (`NEVER_NS` after the trial's end)."""
        starts = self.cycle_start_ns
        index = bisect_right(starts, from_ns)
        left_ns = from_ns
        while left_ns < end_ns:
            stop_ns = starts[index] if index < len(starts) else end_ns
            if index:
                allowed = (stop_ns - starts[index - 1]) * _GAP_NUM  # the gap allowed, x _GAP_DEN
                if allowed < (stop_ns - left_ns) * _GAP_DEN:
                    return left_ns + allowed // _GAP_DEN  # the floor of the exact reach
            left_ns, index = stop_ns, index + 1
        return NEVER_NS

    def tightest_gap_ns(self, end_ns: int) -> int | None:
        """The shortest gap between samples any of this servo's cycles allows, in ns (None:
        no cycle starts)."""
        stops = (*self.cycle_start_ns[1:], end_ns)
        return min((_allowed_ns(stop_ns - start_ns)
                    for start_ns, stop_ns in zip(self.cycle_start_ns, stops, strict=True)),
                   default=None)

    def gap_allowed_ns(self, time_ns: int, end_ns: int) -> int | None:
        """The longest gap between samples the cycle holding ``time_ns`` allows (None
        outside every cycle: before the first one starts)."""
        index = bisect_right(self.cycle_start_ns, time_ns)
        if not index:
            return None
        start_ns = self.cycle_start_ns[index - 1]
        stop_ns = self.cycle_start_ns[index] if index < len(self.cycle_start_ns) else end_ns
        return _allowed_ns(stop_ns - start_ns)


class Holds:
    """Which moving pins hold their goal, and when the next sample is needed.

    Parameters
    ----------
    changes : sequence of Change
        The trial's goal changes, in time order.
    servo_ids : tuple of int
        The moving servos, sampled together.
    end_ns : int
        The trial's end, ns after onset (where its last cycle ends).
    period_ns : int
        The sampling period while any pin moves.
    """

    def __init__(self, changes: Sequence[Change], servo_ids: tuple[int, ...], end_ns: int,
                 period_ns: int):
        self.end_ns = end_ns
        self.period_ns = period_ns
        self._goals = {servo_id: PinGoals.of([c for c in changes if c.servo_id == servo_id])
                       for servo_id in servo_ids}
        self._last_steps: dict[int, int] = {}
        self._holding: set[int] = set()

    def moved(self, servo_id: int) -> None:
        """The servo is not known to hold any more: a frame changed its goal, or a sample
        went unanswered."""
        self._holding.discard(servo_id)
        self._last_steps.pop(servo_id, None)

    def sampled(self, servo_id: int, at_ns: int, steps: int) -> None:
        """The servo read ``steps`` at ``at_ns`` (ns after onset)."""
        if (self._last_steps.get(servo_id) == steps
                and (goal := self._goals[servo_id].goal_at(at_ns)) is not None
                and abs(steps - goal) <= ARRIVAL_STEPS):
            self._holding.add(servo_id)
        else:
            self._holding.discard(servo_id)
        self._last_steps[servo_id] = steps

    def gap_fits(self, from_ns: int, to_ns: int) -> bool:
        """Whether every moving pin's cycles allow no sample from ``from_ns`` to ``to_ns``
        (ns after onset): see `PinGoals.gap_fits`."""
        end_ns = self.end_ns
        for goals in self._goals.values():  # a loop, not all() over a generator: per frame
            if not goals.gap_fits(from_ns, to_ns, end_ns):
                return False
        return True

    def tightest_gap_ns(self) -> int | None:
        """The shortest gap between samples any moving pin's cycle allows, in ns (None: no
        pin has a cycle)."""
        return min((gap for goals in self._goals.values()
                    if (gap := goals.tightest_gap_ns(self.end_ns)) is not None), default=None)

    def reach_ns(self, from_ns: int) -> int:
        """The latest the next sample may follow one at ``from_ns`` (ns after onset) and keep
        every moving pin's cycle rule: see `PinGoals.reach_ns`."""
        reach_ns = NEVER_NS  # the reach of no pin (none moves, or none has a cycle)
        for goals in self._goals.values():  # a loop, not min() over a generator: per frame
            reach_ns = min(reach_ns, goals.reach_ns(from_ns, self.end_ns))
        return reach_ns

    def next_sample_ns(self, last_ns: int, sample_ns: int, after_change_ns: int) -> int:
        """When, after a sample at ``last_ns`` (ns after onset), the next one is needed.

        ``sample_ns``: what one sample of the moving servos takes on this bus;
        ``after_change_ns``: the longest from a goal change to the first sample after it (the
        frame, its read-back, a sample).
        """
        dense_ns = last_ns + max(self.period_ns, sample_ns)
        if len(self._holding) < len(self._goals):
            return dense_ns
        allowed = [goals.gap_allowed_ns(last_ns, self.end_ns) for goals in self._goals.values()]
        if None in allowed:
            return dense_ns
        # The last sample before a change must still fit before its frame, a period early;
        # from it to the first sample after the change the gap must fit the rule too.
        before_change_ns = sample_ns + self.period_ns
        gap_ns = min(a for a in allowed if a is not None)
        if before_change_ns + after_change_ns > gap_ns:
            return dense_ns  # no room to hold anything back on this bus
        next_change_ns = min((goals.next_change_ns(last_ns) for goals in self._goals.values()),
                             default=self.end_ns)
        wanted_ns = min(last_ns + gap_ns - after_change_ns, next_change_ns - before_change_ns)
        # On the grid sampling every period would keep: the samples after the next change
        # then fall where they would have, and so do the lags they measure.
        step_ns = dense_ns - last_ns
        return max(dense_ns, last_ns + (wanted_ns - last_ns) // step_ns * step_ns)
