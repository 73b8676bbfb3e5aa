"""A clock whose waits can be cut short, so quitting never waits out a 10 s stimulus."""

from __future__ import annotations

import threading

from pinarray.clock import Clock
from pinarray.errors import Interrupted

# Longest single wait between looks at the stop flag, in clock nanoseconds.
SLICE_NS = 50_000_000


class Stopped(Interrupted):
    """The experimenter quit or aborted while the session was waiting or playing."""


class StoppableClock:
    """Delegates to ``clock``; after `stop`, every wait raises `Stopped` until `clear`.

    Only the session's and the player's waits go through it, never the bus's own: a wait
    cut short inside a packet exchange would leave the safe stop talking to a confused
    port. `Stopped` is an `Interrupted`, not a fault: the player rests the pins and re-raises,
    and the session, aborted next, logs the cut trial as aborted (presented again on resume).

    Parameters
    ----------
    clock : Clock
        The clock the bus also uses (same time base).
    """

    def __init__(self, clock: Clock):
        self.clock = clock
        self._stop = threading.Event()

    def stop(self) -> None:
        self._stop.set()

    def clear(self) -> None:
        self._stop.clear()

    def now_ns(self) -> int:
        return self.clock.now_ns()

    def sleep_until_ns(self, deadline_ns: int) -> None:
        while True:
            if self._stop.is_set():
                raise Stopped("stopped from the UI")
            now_ns = self.clock.now_ns()
            if now_ns >= deadline_ns:
                return
            self.clock.sleep_until_ns(min(deadline_ns, now_ns + SLICE_NS))
