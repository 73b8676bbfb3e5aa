"""Can this machine deliver the protocol's stimuli in time? A check to run before a session.

The player process (`pinarray.player.process`) measures how late it wakes for deadlines, with
the same priority and sleep strategy it plays trials with; the bus says how long one exchange
with a servo may take (wire, return delay, the adapter's latency). From those, `judge` says in
plain words whether a goal change can reach its servo within the protocol's tolerance, even
when it was lost once and had to be read back and written again, and what to change if not.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

from pinarray.units import NS_PER_MS

# Deadlines every millisecond for two seconds: 2000 wake-ups (the pre-flight measures as long
# as its protocol needs: `duration_for`).
DEFAULT_PERIOD_NS = NS_PER_MS
DEFAULT_DURATION_NS = 2_000 * NS_PER_MS
# A verdict is OK when fewer than this share of trials would be presented again, as measured
# on enough deadlines to have shown that share (`samples_needed`); NOT OK at this share or more.
RETRY_SHARE = 0.05
# Measurements the pre-flight takes at most (a protocol of very long trials says "measure
# longer" and how long).
LONGEST_CHECK_NS = 15_000 * NS_PER_MS
# The check measures in slices this long, saying how far it got after each: whoever waits
# sees the seconds left, and may go on without the verdict (`CheckSkipped`).
CHECK_SLICE_NS = 1_000 * NS_PER_MS


@dataclass(frozen=True)
class WakeUps:
    """How late the player woke for its deadlines, in nanoseconds."""

    samples: int
    p50_ns: int
    p99_ns: int
    max_ns: int
    lateness_ns: tuple[int, ...] = ()  # every one measured, in increasing order

    @classmethod
    def of(cls, lateness_ns: Sequence[int]) -> WakeUps:
        ordered = tuple(sorted(lateness_ns))
        if not ordered:
            return cls(0, 0, 0, 0)

        def at(fraction: float) -> int:
            return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]

        return cls(len(ordered), at(0.50), at(0.99), ordered[-1], ordered)

    def later_than(self, budget_ns: int) -> int:
        """How many wake-ups came later than ``budget_ns`` (the summary's max if not kept)."""
        if not self.lateness_ns:
            return self.samples if self.max_ns > budget_ns else 0
        return len(self.lateness_ns) - bisect_right(self.lateness_ns, budget_ns)

    def describe(self) -> str:
        return (f"wake-up lateness p50 {self.p50_ns / NS_PER_MS:.3f} ms, "
                f"p99 {self.p99_ns / NS_PER_MS:.3f} ms, max {self.max_ns / NS_PER_MS:.3f} ms "
                f"({self.samples} deadlines)")


@dataclass(frozen=True)
class PortFigures:
    """What the check knows of the servos' port and of the protocol's frames."""

    name: str
    changes_per_frame: int  # the most goal changes one frame of the protocol sends
    heal_ns: int  # reading those back and writing one again, as this bus usually takes
    latency_timer_ms: int | None  # a USB adapter's latency timer, when it has one
    frames_per_trial: int = 1  # the most frames one trial of the protocol writes


class Judgement(StrEnum):
    OK = "OK"
    NOT_SURE = "NOT SURE"  # too few measurements to tell: measure longer
    NOT_OK = "NOT OK"


@dataclass(frozen=True)
class Verdict:
    """The check's answer: can stimuli be delivered in time, why, and what to change."""

    judgement: Judgement
    worst_case_ns: int
    lines: tuple[str, ...]

    @property
    def deliverable(self) -> bool:
        return self.judgement is Judgement.OK

    @property
    def judgement_first(self) -> tuple[str, ...]:
        """The lines with the judgement and what to fix first, then what was measured: for a
        short screen (80x24), where what is seen without scrolling must be the answer."""
        said = tuple(line for line in self.lines
                     if line.startswith((f"{self.judgement.value}:", "to fix:")))
        return said + tuple(line for line in self.lines if line not in said)


@dataclass(frozen=True)
class CheckSkipped:
    """The check was not finished: whoever waited for it went on without a verdict."""

    measured_ns: int
    duration_ns: int

    def describe(self) -> str:
        return (f"skipped by the experimenter after {self.measured_ns / 1e9:.0f} of "
                f"{self.duration_ns / 1e9:.0f} s: no verdict")


def upper_bound(late: int, samples: int, confidence: float = 0.95) -> float:
    """A one-sided upper confidence bound of a rate seen ``late`` times in ``samples``.

    None seen: exact (1 - (1 - c)^(1/n), about 3/n at 95 %). Otherwise the Wilson score bound.
    """
    if samples <= 0:
        return 1.0
    if late == 0:
        return float(1 - (1 - confidence) ** (1 / samples))
    z = 1.6448536269514722  # one-sided 95 %
    p = late / samples
    centre = p + z * z / (2 * samples)
    margin = z * math.sqrt(p * (1 - p) / samples + z * z / (4 * samples * samples))
    return min(1.0, (centre + margin) / (1 + z * z / samples))


def samples_needed(frames_per_trial: int) -> int:
    """Wake-ups that, all in time, show at most `RETRY_SHARE` of trials presented again."""
    per_frame = 1 - (1 - RETRY_SHARE) ** (1 / max(1, frames_per_trial))
    return math.ceil(math.log(0.05) / math.log(1 - per_frame))


def duration_for(frames_per_trial: int, period_ns: int = DEFAULT_PERIOD_NS) -> int:
    """How long the pre-flight measures for a protocol: enough wake-ups to tell, within bounds."""
    wanted_ns = samples_needed(frames_per_trial) * period_ns
    return max(DEFAULT_DURATION_NS, min(LONGEST_CHECK_NS, wanted_ns))


def judge(wake_ups: WakeUps, realtime_problem: str, bus: PortFigures, tolerance_ns: int,
          window_ns: int | None = None) -> Verdict:
    """Whether goal changes reach their servos within ``tolerance_ns``, trial after trial.

    ``window_ns``: how late the hardware lets a frame be written at all (a PWM board's period
    less the write's margin); the tighter of the two is the limit.

    A goal whose sync write is lost in the busiest frame goes out as late as the player woke,
    is read back and written again: it arrives within tolerance when the wake-up was no later
    than ``tolerance - heal time`` (the heal time is what this bus usually takes). The share of
    wake-ups later than that, over the protocol's frames per trial, is the share of trials that
    may be reported not delivered (and presented again). Judged on the count of late wake-ups,
    not on the single worst one, so that one try agrees with the next: NOT OK when about
    `RETRY_SHARE` of trials or more are at stake; OK when fewer are and the deadlines measured
    were enough to have shown that many (`samples_needed`: with none late, the 95 % bound is
    `RETRY_SHARE`); NOT SURE, with how many to measure, when they were not.
    """
    worst_ns = wake_ups.max_ns + bus.heal_ns
    limit = f"the tolerance of {tolerance_ns / NS_PER_MS:g} ms"
    tolerance_limits = window_ns is None or tolerance_ns <= window_ns
    if window_ns is not None and not tolerance_limits:
        limit = (f"the write window of {window_ns / NS_PER_MS:.1f} ms: a board period less the "
                 "write's margin")
        tolerance_ns = window_ns
    budget_ns = tolerance_ns - bus.heal_ns
    late = wake_ups.later_than(budget_ns) if budget_ns > 0 else wake_ups.samples
    frames = max(1, bus.frames_per_trial)
    seen = 1 - (1 - late / max(1, wake_ups.samples)) ** frames
    needed = samples_needed(frames)
    priority = "not granted" if realtime_problem else "granted"
    goals = "goal" if bus.changes_per_frame == 1 else f"{bus.changes_per_frame} goals"
    lines = [
        f"this machine: {wake_ups.describe()}, real-time priority {priority}",
        f"servo bus {bus.name}: reading back the {goals} of the protocol's busiest frame and "
        f"writing one again usually takes {bus.heal_ns / NS_PER_MS:.1f} ms"
        + (f" (adapter latency timer {bus.latency_timer_ms} ms)"
           if bus.latency_timer_ms is not None else ""),
    ]
    share = (f"at most {100 * (1 - (1 - upper_bound(0, wake_ups.samples)) ** frames):.1f} %"
             if not late else f"about {100 * seen:.1f} %")
    rate = (f"{late} of {wake_ups.samples} wake-ups later than "
            f"{max(0, budget_ns) / NS_PER_MS:.1f} ms ({limit}, less the heal time); with "
            f"{frames} frame(s) a "
            f"trial, {share} of trials would be reported not delivered and presented again")
    if budget_ns > 0 and seen < RETRY_SHARE and wake_ups.samples >= needed:
        lines.append(f"OK: stimuli can be delivered as scheduled ({rate})")
        return Verdict(Judgement.OK, worst_ns, tuple(lines))
    if budget_ns > 0 and seen < RETRY_SHARE:
        lines.append(f"NOT SURE: {wake_ups.samples} deadlines cannot tell ({rate}); measure "
                     f"at least {needed} (`pinarray timing --seconds "
                     f"{math.ceil(needed * DEFAULT_PERIOD_NS / 1e9)}`)")
        return Verdict(Judgement.NOT_SURE, worst_ns, tuple(lines))
    lines.append(f"NOT OK: stimuli may be reported not delivered ({rate})")
    if realtime_problem:
        lines.append(f"to fix: {realtime_problem}")
    if bus.latency_timer_ms is not None and bus.latency_timer_ms > 1:
        lines.append(f"to fix: set the adapter's latency timer to 1 ms (docs/rig/timing.md: the USB adapter's latency timer); "
                     f"it is {bus.latency_timer_ms} ms")
    if not realtime_problem and bus.heal_ns <= tolerance_ns:
        lines.append("to fix: the machine itself is too busy; close other programs"
                     + (", or raise device: delivery_tolerance_ms if the experiment allows it"
                        if tolerance_limits else ""))
    return Verdict(Judgement.NOT_OK, worst_ns, tuple(lines))
