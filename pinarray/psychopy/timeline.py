"""One time line for the screen and the pins: PsychoPy's clock read on the array's.

PsychoPy stamps a flip with `psychopy.logging.defaultClock` (its time base, ``psychopy.clock
.getTime``: Psychtoolbox's ``GetSecs`` where Psychtoolbox loads, else ``time.perf_counter``,
on Linux CLOCK_MONOTONIC); an array's onsets are integer nanoseconds on its own clock
(``time.monotonic_ns`` on real servos). Where both read CLOCK_MONOTONIC the offset between
them is zero within a few microseconds; where they differ (``GetSecs``' own time base) it is
whatever it is. Either way it is measured, not assumed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

NS_PER_S = 1_000_000_000
# Readings of the two clocks taken back to back; the tightest pair sets the offset.
READINGS = 7


@dataclass(frozen=True)
class Timeline:
    """PsychoPy's time base (seconds, a float) and the array's clock (ns) as one line.

    Attributes
    ----------
    offset_ns : int
        The array's clock minus PsychoPy's time base, in ns.
    uncertainty_ns : int
        Half the tightest bracket the offset was read in, in ns.
    """

    offset_ns: int
    uncertainty_ns: int

    @classmethod
    def measure(cls, psychopy_s: Callable[[], float], array_ns: Callable[[], int]) -> Timeline:
        """Read PsychoPy's time base between two readings of the array's clock, ``READINGS``
        times, and keep the tightest bracket."""
        best: tuple[int, int] | None = None
        for _ in range(READINGS):
            before = array_ns()
            reading_ns = round(psychopy_s() * NS_PER_S)
            after = array_ns()
            bracket = after - before
            if best is None or bracket < best[1]:
                best = ((before + after) // 2 - reading_ns, bracket)
        assert best is not None
        return cls(best[0], (best[1] + 1) // 2)

    def to_array_ns(self, psychopy_s: float) -> int:
        """A time of PsychoPy's time base (s) on the array's clock (ns)."""
        return round(psychopy_s * NS_PER_S) + self.offset_ns

    def to_psychopy_s(self, array_ns: int) -> float:
        """A time of the array's clock (ns) on PsychoPy's time base (s)."""
        return (array_ns - self.offset_ns) / NS_PER_S
