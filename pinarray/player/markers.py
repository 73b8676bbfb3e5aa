"""Markers the player announces as a trial plays: at its onset and at its end.

Whoever plays the trial (the player process, or the playback in this process) announces: the
onset marker right after the onset frame's write (in the slack before the next frame, never
before a write), the offset marker at the trial's end, each stamped with the schedule's time
on the player's clock. What carries them (an LSL outlet) lives above the player: the player
is given a picklable `Announcers` (a factory), opens it once where it plays, and pushes
through the `Announcer` it gets. A failing announcer never fails the trial: the first
problem is kept (`MarkerPush.problem`) and reported with the trial.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol as Interface

from pinarray.clock import Clock


@dataclass(frozen=True)
class TrialMarkers:
    """The two markers of one trial's stimulus, as the caller wants them sent."""

    onset: str
    offset: str


class Announcer(Interface):
    """An open marker stream (an LSL outlet)."""

    def push(self, marker: str, at_ns: int) -> None:
        """Send ``marker`` stamped with ``at_ns`` (the clock it was opened on, ns)."""
        ...

    def close(self) -> None: ...


class Announcers(Interface):
    """Opens an `Announcer` where the player plays (pickled to the player process)."""

    def open(self, clock: Clock) -> Announcer:
        """The stream, its stamps taken on ``clock``; raises `PinArrayError` if it cannot."""
        ...


class MarkerPush:
    """Pushes one trial's markers through ``announcer``; never raises.

    ``sent`` counts the markers that went out; ``problem`` is the first failure, in plain
    words (empty when none).
    """

    def __init__(self, announcer: Announcer, markers: TrialMarkers):
        self.announcer = announcer
        self.markers = markers
        self.sent = 0
        self.problem = ""
        self.onset_sent = False

    def onset(self, at_ns: int) -> None:
        self.onset_sent = True
        self._push("onset", self.markers.onset, at_ns)

    def offset(self, at_ns: int) -> None:
        self._push("offset", self.markers.offset, at_ns)

    def _push(self, event: str, marker: str, at_ns: int) -> None:
        try:
            self.announcer.push(marker, at_ns)
        except Exception as error:  # whatever the outlet's library raises: the trial goes on
            if not self.problem:
                self.problem = f"the {event} marker was not sent: {error}"
            return
        self.sent += 1
