"""Clocks: the only place that calls `time.*` for anything that waits.

Everything that plays against deadlines takes a `Clock`, so tests run in virtual time and a
simulated session can run faster than real time. All times are integer nanoseconds.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Protocol


class Clock(Protocol):
    """A monotonic nanosecond clock that can wait for an absolute deadline."""

    def now_ns(self) -> int:
        """The time now, in ns (only differences and deadlines on the same clock mean anything)."""
        ...

    def sleep_until_ns(self, deadline_ns: int) -> None:
        """Return at ``deadline_ns`` (a time on this clock), as close to it as it can."""
        ...

    def doze_until_ns(self, deadline_ns: int) -> None:
        """Wait without spinning: may wake a little late (for waits that are not deadlines)."""
        ...


class MonotonicClock:
    """Real time: sleep until shortly before the deadline, then spin.

    Waiting on absolute deadlines (never ``sleep(period - elapsed)``) keeps errors from
    accumulating; the final spin absorbs the OS scheduler's wake-up jitter.

    Parameters
    ----------
    spin_ns : int
        How long before a deadline to stop sleeping and start spinning, in nanoseconds.
    sleep : callable, optional
        Sleeps for a number of seconds (default `time.sleep`); may return early (the player
        process wakes for messages from its parent).
    """

    def __init__(self, spin_ns: int = 300_000, sleep: Callable[[float], object] = time.sleep):
        self.spin_ns = spin_ns
        self._sleep = sleep

    def now_ns(self) -> int:
        """``time.monotonic_ns()``: CLOCK_MONOTONIC on Linux."""
        return time.monotonic_ns()

    def sleep_until_ns(self, deadline_ns: int) -> None:
        """Sleep, then spin the last `spin_ns`: returns at the deadline, not after."""
        while True:
            remaining_ns = deadline_ns - time.monotonic_ns()
            if remaining_ns <= 0:
                return
            if remaining_ns > self.spin_ns:
                self._sleep((remaining_ns - self.spin_ns) / 1e9)

    def doze_until_ns(self, deadline_ns: int) -> None:
        """Sleep until about ``deadline_ns`` (no spin: may wake a little late)."""
        remaining_ns = deadline_ns - time.monotonic_ns()
        if remaining_ns > 0:
            time.sleep(remaining_ns / 1e9)


class ScaledClock:
    """Real time sped up (scale > 1) or slowed down (scale < 1) by a constant factor.

    ``now_ns`` counts scaled nanoseconds since construction; a schedule played against it
    takes ``1/scale`` of its nominal wall time.

    Inside `own_time` (a stimulus played on the in-process simulator) time moves only when
    something waits, as a `PacedClock`'s does: the host's own computing (the UI's redraws,
    another program) costs the simulated servos no time, so a rehearsal's stimulus is never
    late because the host was busy; it takes that much longer on the wall clock instead.
    Afterwards the clock follows the wall clock again, never going back.
    """

    def __init__(self, scale: float, base: MonotonicClock | None = None):
        if not scale > 0:
            from pinarray.errors import PinArrayError

            raise PinArrayError(f"time scale must be a positive number, found {scale}")
        self.scale = scale
        self._base = base or MonotonicClock()
        self._start_ns = self._base.now_ns()
        self._own: PacedClock | None = None  # inside `own_time`: the simulator's own time
        self._owner: int | None = None  # the thread that plays in own time (it alone waits so)
        self._floor_ns = 0  # where the last `own_time` ended: now_ns never goes below it

    def now_ns(self) -> int:
        own = self._own
        if own is not None:
            return own.now_ns()
        return max(self._floor_ns, round((self._base.now_ns() - self._start_ns) * self.scale))

    def sleep_until_ns(self, deadline_ns: int) -> None:
        self._wait(deadline_ns, self._base.sleep_until_ns)

    def doze_until_ns(self, deadline_ns: int) -> None:
        self._wait(deadline_ns, self._base.doze_until_ns)

    def _wait(self, deadline_ns: int, until: Callable[[int], None]) -> None:
        own = self._own
        if own is not None and self._owner == threading.get_ident():
            own.sleep_until_ns(deadline_ns)
        else:
            # The wall clock's time line (another thread inside `own_time` waits on it too).
            until(self._start_ns + int(deadline_ns / self.scale))

    @contextmanager
    def own_time(self) -> Iterator[None]:
        """Until the block ends, time moves only when this thread waits, as a `PacedClock`'s
        at this clock's scale; one block at a time."""
        if self._own is not None:
            raise RuntimeError("own_time is already in use: one stimulus plays at a time")
        own = PacedClock(self.scale, self.now_ns(), self._base)
        self._owner = threading.get_ident()
        self._own = own
        try:
            yield
        finally:
            self._floor_ns = own.now_ns()
            self._owner = None
            self._own = None


# A PacedClock sleeps only once its simulated time is this far ahead of the wall clock's pace:
# a sleep costs the host about 0.1 ms however short it is, and a simulated bus waits for every
# exchange (a few hundred us of wire, 1/pace of it on the wall), which slept one by one made a
# batch at 50x with its pins' positions sampled run 50 times slower.
MIN_WALL_SLEEP_NS = 1_000_000
# How far behind its pace a PacedClock may fall and still catch up (by not sleeping until it
# has): the host's computing between waits is absorbed by the sleeps after it. Further behind
# (a suspended laptop, a long stall) it starts its pace again from now, rather than racing.
MAX_CATCH_UP_NS = 100_000_000


class PacedClock:
    """Simulated time that waits on the wall clock, ``pace`` times faster than real time.

    Like `VirtualClock`, time moves only when something waits, so the host's own computing
    costs no simulated time and a simulated stimulus is delivered exactly as scheduled; unlike
    it, a wait also sleeps until the wall clock has reached the waited-for time at that pace
    (counted from where the pace started), so a rehearsal runs at a watchable speed (and can
    be interrupted). The host's computing between waits is paid from those sleeps, not added
    to them: a stimulus takes its scheduled time on the wall clock unless the host needs more
    than that to compute it. Short waits are slept together (`MIN_WALL_SLEEP_NS`). For
    scripted runs, where nobody answers in real time.
    """

    def __init__(self, pace: float, start_ns: int = 0, base: MonotonicClock | None = None):
        if not pace > 0:
            from pinarray.errors import PinArrayError

            raise PinArrayError(f"time scale must be a positive number, found {pace}")
        self.pace = pace
        self._now_ns = start_ns
        self._base = base or MonotonicClock()
        # Where the pace started: simulated time here was the wall clock's there.
        self._paced_from_ns = start_ns
        self._wall_from_ns = self._base.now_ns()

    def now_ns(self) -> int:
        return self._now_ns

    def sleep_until_ns(self, deadline_ns: int) -> None:
        if deadline_ns <= self._now_ns:
            return
        self._now_ns = deadline_ns
        base = self._base
        wall_ns = self._wall_from_ns + int((deadline_ns - self._paced_from_ns) / self.pace)
        ahead_ns = wall_ns - base.now_ns()
        if ahead_ns >= MIN_WALL_SLEEP_NS:
            base.doze_until_ns(wall_ns)  # what the OS oversleeps, the next waits pay back
        elif ahead_ns < -MAX_CATCH_UP_NS:
            self._paced_from_ns, self._wall_from_ns = deadline_ns, base.now_ns()

    doze_until_ns = sleep_until_ns


class VirtualClock:
    """Simulated time: waiting jumps straight to the deadline; nothing ever sleeps.

    Simulated devices may also `advance` it, e.g. by the wire time of a packet.
    """

    def __init__(self, start_ns: int = 0):
        self._now_ns = start_ns

    def now_ns(self) -> int:
        """Virtual time: moves only when something waits or a simulated device advances it."""
        return self._now_ns

    def sleep_until_ns(self, deadline_ns: int) -> None:
        """Jump to ``deadline_ns`` at once (never back)."""
        if deadline_ns > self._now_ns:
            self._now_ns = deadline_ns

    doze_until_ns = sleep_until_ns

    def advance(self, duration_ns: int) -> None:
        """Move time on by ``duration_ns`` (a simulated packet's time on the wire)."""
        if duration_ns < 0:
            raise ValueError(f"virtual time cannot go backwards ({duration_ns} ns)")
        self._now_ns += duration_ns
