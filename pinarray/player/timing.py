"""Can this machine deliver the protocol's stimuli in time? A check to run before a session.

The player process (`pinarray.player.process`) measures how late it wakes for deadlines, with
the same priority and sleep strategy it plays trials with; the bus says how long one exchange
with a servo may take (wire, return delay, the adapter's latency). From those, `judge` says in
plain words whether a goal change can reach its servo within the protocol's tolerance, even
when it was lost once and had to be read back and written again, and what to change if not.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pinarray.units import NS_PER_MS

# Deadlines every millisecond for two seconds: 2000 wake-ups.
DEFAULT_PERIOD_NS = NS_PER_MS
DEFAULT_DURATION_NS = 2_000 * NS_PER_MS


@dataclass(frozen=True)
class WakeUps:
    """How late the player woke for its deadlines, in nanoseconds."""

    samples: int
    p50_ns: int
    p99_ns: int
    max_ns: int

    @classmethod
    def of(cls, lateness_ns: Sequence[int]) -> WakeUps:
        ordered = sorted(lateness_ns)
        if not ordered:
            return cls(0, 0, 0, 0)

        def at(fraction: float) -> int:
            return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]

        return cls(len(ordered), at(0.50), at(0.99), ordered[-1])

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


@dataclass(frozen=True)
class Verdict:
    """The check's answer: can stimuli be delivered in time, why, and what to change."""

    deliverable: bool
    worst_case_ns: int
    lines: tuple[str, ...]


def judge(wake_ups: WakeUps, realtime_problem: str, bus: PortFigures, tolerance_ns: int) -> Verdict:
    """Whether a goal change reaches its servo within ``tolerance_ns`` at worst.

    The worst case is a goal whose sync write is lost in the busiest frame: it goes out as late
    as the player ever woke, the frame's goals are read back, and it is written again:
    ``max wake-up lateness + heal time``. The heal time is what this bus usually takes (a
    slower reply is read back again at the next chance), so the verdict holds for a bus as
    it was measured.
    """
    worst_ns = wake_ups.max_ns + bus.heal_ns
    deliverable = worst_ns <= tolerance_ns
    priority = "not granted" if realtime_problem else "granted"
    goals = "goal" if bus.changes_per_frame == 1 else f"{bus.changes_per_frame} goals"
    lines = [
        f"this machine: {wake_ups.describe()}, real-time priority {priority}",
        f"servo bus {bus.name}: reading back the {goals} of the protocol's busiest frame and "
        f"writing one again usually takes {bus.heal_ns / NS_PER_MS:.1f} ms"
        + (f" (adapter latency timer {bus.latency_timer_ms} ms)"
           if bus.latency_timer_ms is not None else ""),
    ]
    verdict = (f"a goal lost on the wire and written again reaches its servo within "
               f"{worst_ns / NS_PER_MS:.1f} ms at worst; the protocol's tolerance is "
               f"{tolerance_ns / NS_PER_MS:g} ms")
    if deliverable:
        lines.append(f"OK: stimuli can be delivered as scheduled ({verdict})")
        return Verdict(True, worst_ns, tuple(lines))
    lines.append(f"NOT OK: stimuli may be reported not delivered ({verdict})")
    if realtime_problem:
        lines.append(f"to fix: {realtime_problem}")
    if bus.latency_timer_ms is not None and bus.latency_timer_ms > 1:
        lines.append(f"to fix: set the adapter's latency timer to 1 ms (README: latency timer); "
                     f"it is {bus.latency_timer_ms} ms")
    if not realtime_problem and bus.heal_ns <= tolerance_ns:
        lines.append("to fix: the machine itself is too busy; close other programs, or raise "
                     "device: delivery_tolerance_ms if the experiment allows it")
    return Verdict(False, worst_ns, tuple(lines))
