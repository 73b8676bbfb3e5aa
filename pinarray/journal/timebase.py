"""One time base per run: what its time zero is, how each sitting's clock joins it, seconds in files.

A run's times (``onset`` in beh.tsv and events.tsv) are nanoseconds from the run's *time
zero*, written in seconds. Unless the session is told another zero (e.g. the first counted
scanner volume), the zero is the stimulus onset of the run's first trial.

A run may take several *sittings* (a crash or an abort, then a resume): each sitting has its
own clock (a new process's monotonic clock, or a simulated one starting at 0), so each one
records where its clock joins the run's time. A resumed sitting starts no earlier than the
end of the last trial on file, so onsets never go back; when both the run's zero and the
sitting are in wall-clock time (real time, or real time sped up by a constant factor), it
starts where the wall clock says, so the pause between sittings is counted. In simulated time
(virtual, or paced for a scripted rehearsal) the wall clock says nothing about the run's
time, so the sitting continues from the end of the last trial on file.

Pure functions and values; the caller reads the clocks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from decimal import Decimal, InvalidOperation
from enum import StrEnum

from pinarray.units import NS_PER_S

FIRST_TRIAL_ONSET = "the stimulus onset of the run's first trial"


class ClockKind(StrEnum):
    """What a sitting's clock measures."""

    REAL = "real"  # the computer's monotonic clock: real servos, or a simulation in real time
    SCALED = "scaled"  # real time sped up (or slowed down) by a constant factor
    PACED = "paced"  # simulated time that only moves while waiting, paced on the wall clock
    VIRTUAL = "virtual"  # simulated time that jumps to every deadline: no relation to wall time
    UNKNOWN = "unknown"  # written by a pinarray that did not record it

    @property
    def follows_wall_clock(self) -> bool:
        """Whether wall-clock time elapsed, times the scale, is time elapsed on this clock."""
        return self in (ClockKind.REAL, ClockKind.SCALED)

    @property
    def simulated(self) -> bool:
        return self in (ClockKind.PACED, ClockKind.VIRTUAL)


@dataclass(frozen=True)
class TimeScale:
    """A sitting's clock: its kind, and how many of its seconds pass per wall-clock second.

    ``factor`` is 1 in real time, X for ``--speed X``, and None for virtual time.
    """

    kind: ClockKind
    factor: float | None = 1.0

    def describe(self) -> str:
        """In words, for a sidecar: does this sitting's time look like real data?"""
        match self.kind:
            case ClockKind.REAL:
                return "real time"
            case ClockKind.SCALED:
                return f"simulated: wall-clock time at {self.factor:g}x real time"
            case ClockKind.PACED:
                return (f"simulated: a scripted rehearsal paced at {self.factor:g}x real time (the "
                        "computer's own delays not counted)")
            case ClockKind.VIRTUAL:
                return "simulated: virtual time, no relation to the wall clock"
        return "clock not recorded"


REAL_TIME = TimeScale(ClockKind.REAL, 1.0)


class Answers(StrEnum):
    """Who or what answered a sitting's trials: a run resumes answered as it started, so that
    a person's answers and a model's never share a run."""

    SUBJECT = "subject"  # a person, in the UI
    SHEET = "responses"  # a sheet of answers (`pinarray batch --responses`)
    OBSERVER = "observer"  # a simulated observer (`pinarray batch --observer`): a rehearsal
    SCRIPT = "script"  # a lab's own code (`import pinarray`)
    UNKNOWN = "unknown"  # a sitting an earlier pinarray wrote

    @property
    def known(self) -> bool:
        """Whether these are surely a person's or surely not: a lab script's may be either (a
        script rehearsing with a simulated observer is resumed by `batch --observer`)."""
        return self in (Answers.SUBJECT, Answers.SHEET, Answers.OBSERVER)

    def describe(self) -> str:
        return _ANSWERS_SAID[self]

    def how_to_resume(self) -> str:
        return _RESUMED_BY[self]


_ANSWERS_SAID = {
    Answers.SUBJECT: "a subject's, in the UI", Answers.SHEET: "a responses sheet's",
    Answers.OBSERVER: "a simulated observer's", Answers.SCRIPT: "a lab script's",
    Answers.UNKNOWN: "not recorded"}
_RESUMED_BY = {
    Answers.SUBJECT: "in the UI (Resume on the start screen of pinarray tui)",
    Answers.SHEET: "with pinarray batch --responses CSV --resume",
    Answers.OBSERVER: "with pinarray batch --observer MODEL --resume",
    Answers.SCRIPT: "from the lab's script (resume=True)", Answers.UNKNOWN: "as it started"}


@dataclass(frozen=True)
class Sitting:
    """One stretch of a run in one process: started, clock, and where it joins the run's time.

    Attributes
    ----------
    number : int
        1 for the sitting that started the run, then 2, 3, ... for each resume.
    started_at : str
        Wall-clock start, ISO 8601 with its UTC offset.
    clock : TimeScale
        The sitting's clock.
    start_ns : int or None
        The run's time (ns from its zero) when the sitting started; None while the run's zero
        is not known yet (before its first trial), and for sittings written by an older pinarray.
    pid : int
        The process that wrote it.
    host : str
        The computer it ran on.
    software_version : str
        The pinarray that wrote it.
    timing_check : str
        What the pre-flight's timing check said before the sitting began, in words (its
        verdict, or that the experimenter skipped it); empty where none ran (batch).
    answers : Answers
        Who or what answered its trials.
    """

    number: int
    started_at: str
    clock: TimeScale
    start_ns: int | None
    pid: int = 0
    host: str = ""
    software_version: str = ""
    timing_check: str = ""
    answers: Answers = Answers.UNKNOWN


@dataclass(frozen=True)
class TimeZero:
    """What the run's time zero is, and when it was on the wall clock (ISO 8601 with offset)."""

    event: str
    at: str


def answered_otherwise(sittings: Sequence[Sitting], answers: Answers) -> Answers | None:
    """The answers a run of ``sittings`` began with (its first sitting of a known kind's)
    when a resume answered by ``answers`` may not take it on, another known kind; else None
    (a lab script's and an earlier pinarray's go with any)."""
    started = next((s.answers for s in sittings if s.answers.known), Answers.UNKNOWN)
    return started if answers.known and started.known and started is not answers else None


def seconds_text(time_ns: int) -> str:
    """Nanoseconds as exact decimal seconds: 12_500_000_000 -> ``"12.5"``, 0 -> ``"0"``."""
    sign = "-" if time_ns < 0 else ""
    whole, fraction = divmod(abs(time_ns), NS_PER_S)
    return f"{sign}{whole}.{fraction:09d}".rstrip("0").rstrip(".") if fraction else f"{sign}{whole}"


# A time in a results file: within 30 years either way (a run's time base continues across
# sittings), so that nanoseconds stay within 64 bits and any arithmetic on them within a float.
MAX_SECONDS = 10**9


def ns_from_seconds(text: str) -> int:
    """Decimal seconds (as written by `seconds_text`, or any decimal) to whole nanoseconds.

    Raises ValueError for text that is not a finite decimal number of at most `MAX_SECONDS`.
    """
    try:
        if not text.isascii():  # Decimal() reads other scripts' digits (１.５)
            raise InvalidOperation(text)
        value = Decimal(text)
    except InvalidOperation:
        raise ValueError(text) from None
    if not value.is_finite() or abs(value) > MAX_SECONDS:
        raise ValueError(text)
    return int((value * NS_PER_S).to_integral_value())


def wall_ns(at: datetime) -> int:
    """An aware datetime as nanoseconds since the Unix epoch (microsecond resolution)."""
    delta = at - datetime.fromtimestamp(0, at.tzinfo)
    return (delta.days * 86_400 + delta.seconds) * NS_PER_S + delta.microseconds * 1000


def zero_wall_time(now: datetime, zero_ago_ns: int, clock: TimeScale) -> datetime:
    """The wall-clock time of a zero ``zero_ago_ns`` ago on ``clock`` (now if clock is simulated)."""
    if clock.kind.follows_wall_clock and clock.factor:
        return now - timedelta(microseconds=zero_ago_ns / clock.factor / 1000)
    return now


def resumed_start_ns(last_end_ns: int | None, zero_at: datetime | None, now: datetime,
                     clock: TimeScale) -> int | None:
    """Where a resumed sitting's clock joins the run's time, in ns from the run's zero.

    Parameters
    ----------
    last_end_ns : int or None
        The latest end (onset + duration, or + response time if later) of any trial on file;
        None when no trial is on file.
    zero_at : datetime or None
        Wall-clock time of the run's zero; None if the run has none recorded (no trial ran, or
        an older pinarray wrote the run).
    now : datetime
        Wall-clock time at the sitting's start.
    clock : TimeScale
        The new sitting's clock.

    Returns
    -------
    int or None
        None when no trial is on file: the new sitting's first trial becomes the zero.
    """
    if last_end_ns is None:
        return None
    start_ns = last_end_ns
    if zero_at is not None and clock.kind.follows_wall_clock and clock.factor:
        start_ns = max(start_ns, round((wall_ns(now) - wall_ns(zero_at)) * clock.factor))
    return start_ns
