"""What the parent and its player process say to each other (pickled over a socket).

Requests are numbered, so a stop meant for one cannot stop the next, nor a cue start it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from pinarray.hardware.delivery import PreparedTrial
from pinarray.hardware.driver import Handover, SafeStopReport
from pinarray.player.markers import Announcers, TrialMarkers

if TYPE_CHECKING:  # names in annotations only: a player that only measures wake-ups loads no playback
    from fractions import Fraction

    from pinarray.player.playback import Onset, PlaybackReport


@dataclass(frozen=True)
class Hello:
    """The first message: the servos to drive (None: timing only), priority and spin, and
    the marker stream the child opens once and announces on (None: no markers)."""

    handover: Handover | None  # None: no port, only timing measurements
    realtime_priority: int | None
    spin_ns: int
    markers: Announcers | None = None


@dataclass(frozen=True)
class Ready:
    """The answer to `Hello`: the player process guards the servos from now on."""

    realtime_problem: str  # empty when real-time priority was granted (or not asked for)
    markers_problem: str = ""  # empty unless the marker stream asked for could not be opened


@dataclass(frozen=True)
class OnCue:
    """A trial's onset not known yet: the child waits for a `Cue` (a screen flip as it
    happens) and starts at once when it comes."""


@dataclass(frozen=True)
class Play:
    """Play ``trial`` at ``onset`` (or on its `Cue`), verifying its goal changes within
    ``tolerance_ns``; answered by `Played`, `PlayStopped`, `PlaySuspended`, `PlayFailed` or
    `OnsetMissed`."""

    number: int  # a stop request names the trial it is for: a late one must not stop the next
    trial: PreparedTrial
    onset: Onset | OnCue
    tolerance_ns: int
    markers: TrialMarkers | None  # announced at the onset and the end, if any
    stroke_tolerance: Fraction


@dataclass(frozen=True)
class StopPlaying:
    """Stop request ``number`` (a stop signal or the parent's stop, named in ``reason``)."""

    number: int
    reason: str
    signal_number: int | None


@dataclass(frozen=True)
class Cue:
    """Start the trial `number` (sent `OnCue`) now."""

    number: int


@dataclass(frozen=True)
class MeasureWakeUps:
    """How late the player wakes for deadlines every ``period_ns`` for ``duration_ns``:
    answered by `WakeUpsMeasured`."""

    number: int
    duration_ns: int
    period_ns: int


@dataclass(frozen=True)
class Quit:
    """Rest the pins, release torque and leave."""


@dataclass(frozen=True)
class Played:
    """The trial ended as scheduled or not: its ``report`` says which."""

    report: PlaybackReport


@dataclass(frozen=True)
class PlayStopped:
    """The trial was stopped (`StopPlaying`, or a signal to the player process)."""

    reason: str
    signal_number: int | None
    safe_stop: SafeStopReport | None = None  # None: stopped before anything moved


@dataclass(frozen=True)
class PlaySuspended:
    """The parent was suspended (Ctrl-Z, SIGSTOP) while the trial played or waited for its
    onset: the child cut it, rested the pins and released torque, noticing at ``noticed_ns``
    (``time.monotonic_ns()``)."""

    message: str
    safe_stop: SafeStopReport
    noticed_ns: int


@dataclass(frozen=True)
class OnsetMissed:
    """The onset had passed by the time playback could begin: nothing was sent."""

    message: str
    late_ns: int


@dataclass(frozen=True)
class PlayFailed:
    """Playback stopped early by a fault; ``safe_stop`` says how the pins were left."""

    message: str
    safe_stop: SafeStopReport


@dataclass(frozen=True)
class WakeUpsMeasured:
    """How late each wake-up of a `MeasureWakeUps` was, in ns."""

    lateness_ns: tuple[int, ...]


# What the child answers, one per request (and Ready once, to Hello).
Answer = (Ready | Played | PlayStopped | PlaySuspended | PlayFailed | OnsetMissed
          | WakeUpsMeasured)
# What the parent asks, numbered where a stop or a cue may name it.
Request = Play | StopPlaying | Cue | MeasureWakeUps | Quit
ANSWERS = (Ready, Played, PlayStopped, PlaySuspended, PlayFailed, OnsetMissed, WakeUpsMeasured)
