"""Trial records as the lab reads them: one row per finished (or abandoned) trial, and the reader.

A row is a `LocalisationRecord` (a pin moved; the subject named a pin, or nothing felt), a
`MotionRecord` (a wave along a row, or the no-wave control; the subject said which way, if
any), or one of the lab's paradigms: an `IdentificationRecord` (a pattern; the subject named
one, or a count), a `TwoIntervalRecord` (a standard and a comparison; the subject named an
interval) or a `TemporalOrderRecord` (two pins an SOA apart; the subject named the first).
`BEH_COLUMNS` is the ``beh.tsv`` schema, each column with its cell type (the lab's paradigms'
appended after the columns older files end with); times are whole nanoseconds in a record and
decimal seconds in a file. The writer is `pinarray.journal.writer`;
this module only formats and parses, so the analysis reads results without any writer code.

A process killed while writing leaves at most one torn last line (`split_torn_tail`); the
reader leaves it out.

Past 400 lines on purpose: the record types, the column schema and the reader are one
contract (every column is written and read back by the same table); split, they drift apart.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum, StrEnum
from pathlib import Path
from typing import Any, NamedTuple, TypeAlias

from pinarray.errors import ResultsError
from pinarray.grid import ErrorClass
from pinarray.journal.paths import check_label
from pinarray.journal.timebase import ns_from_seconds, seconds_text
from pinarray.protocol.model import NOTHING_FELT, Direction, MotionAnswer, is_motion_answer
from pinarray.protocol.paradigms import FIRST, SECOND, IntervalOrder
from pinarray.text_files import position_of

NA = "n/a"  # BIDS spelling of "not applicable"
class TrialStatus(StrEnum):
    """What became of a trial. Only ``ok`` finishes it; the others are presented again."""

    OK = "ok"
    REDONE = "redone"
    ABORTED = "aborted"
    INVALID = "invalid"


@dataclass(frozen=True)
class DeliveryCounts:
    """What reached the servos in one trial (see `pinarray.hardware.delivery.DeliveryRecord`)."""

    scheduled: int
    confirmed: int
    healed: int
    missing: int
    lateness_ns: int


@dataclass(frozen=True)
class StrokeCounts:
    """How far the trial's pins moved (see `pinarray.hardware.motion`), as the pin that moved
    the smallest share of its commanded stroke did; None where not measured."""

    commanded_steps: int
    achieved_steps: int | None = None
    median_steps: float | None = None
    lag_ns: int | None = None
    short_cycles: int | None = None


def _coerce(record: object, name: str, kind: type[Enum], where: str) -> None:
    value = getattr(record, name)
    if value is None or isinstance(value, kind):
        return
    try:
        object.__setattr__(record, name, kind(value))
    except ValueError:
        allowed = ", ".join(str(member.value) for member in kind)
        raise ResultsError(f"{where}: {name} must be one of {allowed}, found {value!r}") from None


def _coerce_name(record: object, name: str, kind: type[str], where: str) -> None:
    """A direction or motion answer: lowercase words joined by hyphens (left, up-right...)."""
    value = getattr(record, name)
    if value is None:
        return
    if not isinstance(value, str) or not is_motion_answer(value):
        raise ResultsError(f"{where}: {name} must be a direction's name (lowercase words joined "
                           f"by hyphens, e.g. left, up-right), none or unsure, found {value!r}")
    object.__setattr__(record, name, kind(value))


@dataclass(frozen=True)
class AdaptiveCells:
    """What a trial of an adaptive design adds to its row.

    ``procedure`` ran the trial (`CATCH` for a catch trial, which moves none); ``parameter``
    is the adapted parameter with its unit as the protocol names it (``soa_ms``); ``intensity``
    the value presented (None: a catch trial's own stimulus, not adapted). After the answer:
    whether it counted as ``correct``, whether it made a staircase ``reversal`` (None: QUEST+,
    a catch trial, or no answer), and the procedure's threshold ``estimate`` once the answer is
    taken (staircase: the mean of its last reversals; QUEST+: the posterior mean, with its 95 %
    credible interval).
    """

    procedure: str
    parameter: str
    intensity: float | None
    guess_rate: float
    correct: bool | None = None
    reversal: bool | None = None
    estimate: float | None = None
    estimate_ci_low: float | None = None
    estimate_ci_high: float | None = None


@dataclass(frozen=True, kw_only=True)
class _Trial:
    """What every trial row holds. Times in whole nanoseconds; ``onset_ns`` on the run's time base.

    Attributes
    ----------
    trial, block : int
        The trial's number in plan order (1..N) and its block (0: practice).
    task : str
        The BIDS task label.
    onset_ns, duration_ns : int
        The stimulus's onset on the run's time base and its length.
    status : TrialStatus
        ok, or redone, aborted, invalid (presented again); ``status_reason`` says why.
    response_time_ns : int or None
        From the stimulus's onset to the answer; None when not measured (scripted answers).
    practice, resumed : bool
        A practice trial; the first trial of a resumed sitting.
    delivery : DeliveryCounts or None
        What reached the servos (None: the stimulus never played).
    stroke : StrokeCounts or None
        How far the pins moved, as the pin that moved the smallest share did (None: not
        measured).
    adaptive : AdaptiveCells or None
        An adaptive design's cells (procedure, value, correct, estimate); None: a fixed design.
    motion_samples : int or None
        How many position samples of this presentation the run's motion recording holds, on
        disk before the row was (0: none taken); None in files written before it was counted.
    """

    trial: int
    block: int
    task: str
    onset_ns: int
    duration_ns: int
    status: TrialStatus = TrialStatus.OK
    response_time_ns: int | None = None
    practice: bool = False
    resumed: bool = False
    delivery: DeliveryCounts | None = None  # None: the stimulus never played (or older files)
    status_reason: str | None = None
    stroke: StrokeCounts | None = None  # None: not measured (PWM servos, or older files)
    adaptive: AdaptiveCells | None = None  # None: a trial of a fixed design
    motion_samples: int | None = None  # None: a file written before the count was kept

    def __post_init__(self) -> None:
        check_label("task", self.task)
        if isinstance(self.trial, bool) or not isinstance(self.trial, int) or self.trial < 0:
            raise ResultsError(f"trial number must be a whole number >= 0, found {self.trial!r}")
        where = f"trial {self.trial}"
        _coerce(self, "status", TrialStatus, where)
        for name in ("onset_ns", "duration_ns", "response_time_ns"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
                raise ResultsError(f"{where}: {name} must be whole nanoseconds, found {value!r}")
        count = self.motion_samples
        if count is not None and (isinstance(count, bool) or not isinstance(count, int)
                                  or count < 0):
            raise ResultsError(f"{where}: motion_samples must be a count, found {count!r}")
        for name in ("response", "status_reason"):
            text = getattr(self, name, None)
            if isinstance(text, str) and ("\n" in text or "\r" in text):
                # One row per line is what lets a torn last line be told from a whole one.
                raise ResultsError(f"{where}: a {name} cannot contain a line break")

    @property
    def counts(self) -> bool:
        """Whether analysis counts this row: a main (not practice) trial with status ok."""
        return self.status is TrialStatus.OK and not self.practice

    @property
    def key(self) -> tuple[int, bool]:
        """(trial, practice): what identifies a trial of the plan."""
        return self.trial, self.practice

    @property
    def end_ns(self) -> int:
        """When the trial was over on the run's time base: the stimulus, or the answer if later."""
        return self.onset_ns + max(self.duration_ns, self.response_time_ns or 0)


@dataclass(frozen=True, kw_only=True)
class LocalisationRecord(_Trial):
    """A localisation trial: ``pin`` moved at ``frequency_hz``; the subject named a pin or none.

    ``response`` is the pin named, as text, or "none" (nothing felt); None when the trial got
    no answer (redone, aborted, invalid). ``error_class`` classifies the pin named.
    """

    pin: int
    frequency_hz: float
    response: str | None = None
    error_class: ErrorClass | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        _coerce(self, "error_class", ErrorClass, where)
        text = self.response
        if text is not None and text != NOTHING_FELT and not (text.isdigit() and int(text) >= 1):
            raise ResultsError(f"{where}: a localisation response must be a pin number or "
                               f"'{NOTHING_FELT}', found {text!r}")
        if self.error_class is not None and self.reported_pin is None:
            raise ResultsError(f"{where}: error class {self.error_class} needs a pin named, "
                               f"found the response {text!r}")

    @property
    def reported_pin(self) -> int | None:
        """The pin the subject named; None for nothing felt or no answer."""
        return int(self.response) if self.response and self.response.isdigit() else None

    @property
    def nothing_felt(self) -> bool:
        """Whether the subject said nothing was felt."""
        return self.response == NOTHING_FELT

    @property
    def category(self) -> str | None:
        """The ``error_class`` cell: correct, A-D, or "none" (nothing felt); None if no answer."""
        if self.nothing_felt:
            return NOTHING_FELT
        return None if self.error_class is None else self.error_class.value


@dataclass(frozen=True, kw_only=True)
class MotionRecord(_Trial):
    """An apparent-motion trial: a wave going ``direction`` (or no wave), along ``row`` or,
    with ``row`` None, up or down a column or along a sequence of pins; the subject's
    ``response`` (a direction, none or unsure; None when the trial got no answer)."""

    row: int | None
    direction: Direction
    response: MotionAnswer | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        _coerce_name(self, "direction", Direction, where)
        _coerce_name(self, "response", MotionAnswer, where)

    @property
    def perceived_motion(self) -> bool | None:
        """Whether a moving dot was felt; None when the trial got no answer."""
        return None if self.response is None else self.response != MotionAnswer.NONE

    @property
    def direction_correct(self) -> bool | None:
        """Whether the direction named is the wave's; None without a felt wave to name."""
        if not self.perceived_motion or self.direction == Direction.NONE:
            return None
        return self.response.value == self.direction.value if self.response else None


def _check_pins(pins: object, where: str, count: int | None = None) -> None:
    if (not isinstance(pins, tuple) or not pins or (count is not None and len(pins) != count)
            or any(isinstance(p, bool) or not isinstance(p, int) or p < 1 for p in pins)):
        wanted = f"{count} pin numbers" if count else "pin numbers"
        raise ResultsError(f"{where}: pins must be {wanted}, found {pins!r}")


@dataclass(frozen=True, kw_only=True)
class IdentificationRecord(_Trial):
    """An identification trial: the pattern stimulus ``pattern`` raised ``pins``; the subject
    named a pattern, or a count of pins (``response``; None when the trial got no answer)."""

    pattern: str
    pins: tuple[int, ...]
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_pins(self.pins, f"trial {self.trial}")

    @property
    def correct(self) -> bool | None:
        """Whether the answer names the pattern (or, a count, how many pins it raised)."""
        if self.response is None:
            return None
        if self.response.isdigit():
            return int(self.response) == len(self.pins)
        return self.response == self.pattern


@dataclass(frozen=True, kw_only=True)
class TwoIntervalRecord(_Trial):
    """A two-interval trial: ``compared`` (``frequency_hz``...) at ``standard`` and at
    ``comparison`` in ``interval_order``, on ``pins``; the subject's ``response`` names the
    interval that had more of it, ``first`` or ``second`` (None when the trial got no
    answer)."""

    compared: str
    standard: float
    comparison: float
    interval_order: IntervalOrder
    pins: tuple[int, ...]
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        _coerce(self, "interval_order", IntervalOrder, where)
        _check_pins(self.pins, where)
        if self.response not in (None, FIRST, SECOND):
            raise ResultsError(f"{where}: a two-interval response must be {FIRST} or {SECOND}, "
                               f"found {self.response!r}")

    @property
    def comparison_first(self) -> bool:
        """Whether the comparison played in the first interval."""
        return self.interval_order is IntervalOrder.COMPARISON_FIRST

    @property
    def chose_comparison(self) -> bool | None:
        """Whether the interval named is the comparison's; None without an answer."""
        if self.response is None:
            return None
        return (self.response == FIRST) == self.comparison_first

    @property
    def correct(self) -> bool | None:
        """Whether the interval named had the higher value."""
        chose = self.chose_comparison
        return None if chose is None else chose == (self.comparison > self.standard)


@dataclass(frozen=True, kw_only=True)
class TemporalOrderRecord(_Trial):
    """A temporal-order trial: a train on ``pins`` (A, B), B starting ``soa_ns`` after A
    (negative: B first); the subject named the pin that came first (``response``)."""

    pins: tuple[int, int]
    soa_ns: int
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        _check_pins(self.pins, where, 2)
        if isinstance(self.soa_ns, bool) or not isinstance(self.soa_ns, int):
            raise ResultsError(f"{where}: soa_ns must be whole nanoseconds, found {self.soa_ns!r}")
        if self.response is not None and self.response not in map(str, self.pins):
            raise ResultsError(f"{where}: a temporal-order response must name pin "
                               f"{self.pins[0]} or {self.pins[1]}, found {self.response!r}")

    @property
    def named_a_first(self) -> bool | None:
        """Whether the subject said pin A (the first listed) came first."""
        return None if self.response is None else self.response == str(self.pins[0])

    @property
    def correct(self) -> bool | None:
        """Whether the pin named started first; None without an answer or at an SOA of 0."""
        if self.response is None or self.soa_ns == 0:
            return None
        return self.named_a_first == (self.soa_ns > 0)


TrialRecord: TypeAlias = (LocalisationRecord | MotionRecord | IdentificationRecord
                          | TwoIntervalRecord | TemporalOrderRecord)
"""One row of a run's ``beh.tsv``: a localisation, apparent-motion, identification,
two-interval or temporal-order trial."""
LabRecord: TypeAlias = IdentificationRecord | TwoIntervalRecord | TemporalOrderRecord


# -- the columns ---------------------------------------------------------------------------------


class Cell(Enum):
    """How a column's cells are written and read."""

    INTEGER = "integer"
    SECONDS = "seconds"  # whole nanoseconds inside, exact decimal seconds in the file
    NUMBER = "number"
    BOOLEAN = "boolean"
    TEXT = "text"


class Column(NamedTuple):
    name: str
    cell: Cell
    description: str
    units: str | None = None
    levels: Mapping[Any, str] | None = None  # fixed levels (str or StrEnum); run-specific: sidecar


_BOOLEAN = {"true": True, "false": False}
TRIAL_STATUS_MEANING = {
    TrialStatus.OK: "completed and counted",
    TrialStatus.REDONE: "repeated at the experimenter's request; a later row holds the repeat",
    TrialStatus.ABORTED: "cut short; presented again on resume",
    TrialStatus.INVALID: "the stimulus failed (e.g. a bus fault, or not delivered as "
                         "scheduled); presented again",
}
DIRECTION_MEANING = {
    Direction.LEFT: "wave travels leftwards",
    Direction.RIGHT: "wave travels rightwards",
    Direction.UP: "wave travels up a column",
    Direction.DOWN: "wave travels down a column",
    Direction.NONE: "no wave: the central pin alternates with the lateral ones",
}
CATEGORY_MEANING = {
    "correct": "the stimulated pin", "A": "adjacent, same row or column",
    "B": "diagonal neighbour", "C": "same row or column, not adjacent",
    "D": "neither on the same row or column nor close", NOTHING_FELT: "nothing felt",
}
MOTION_ANSWER_MEANING = {
    MotionAnswer.NONE: "felt no moving dot", MotionAnswer.LEFT: "a dot moving leftwards",
    MotionAnswer.RIGHT: "a dot moving rightwards", MotionAnswer("up"): "a dot moving upwards",
    MotionAnswer("down"): "a dot moving downwards",
    MotionAnswer.UNSURE: "a moving dot, direction not named",
}

BEH_COLUMNS: tuple[Column, ...] = (
    Column("trial", Cell.INTEGER, "Trial number in the run's plan, 1..N in presentation order. "
           "Practice trials come first and are numbered like the rest (1..P, marked in the "
           "practice column); a trial presented again keeps its number."),
    Column("block", Cell.INTEGER, "Block number: 0 for practice, then 1..blocks."),
    Column("task", Cell.TEXT, "Task label: which experiment this row belongs to."),
    Column("pin", Cell.INTEGER, "Stimulated pin, numbered as the subject sees it (1 = bottom-left, "
           "rising along the bottom row, then row by row upwards); n/a for motion trials."),
    Column("row", Cell.INTEGER, "Grid row the apparent-motion wave runs along (1 = bottom row); "
           "n/a for localisation trials and for waves not along a row (up or down a column, or "
           "along a sequence of pins)."),
    Column("direction", Cell.TEXT, "Direction of the stimulated wave, as the subject would name "
           "it: left or right (a row), up or down (a column), a direction a sequence of pins "
           "declares, or none (no wave); n/a for localisation trials.",
           levels=DIRECTION_MEANING),
    Column("frequency_hz", Cell.NUMBER, "Stimulation frequency of the moving pin.", units="Hz"),
    Column("response", Cell.TEXT, "The subject's answer; n/a when the trial got none (redone, "
           "aborted, invalid)."),
    Column("error_class", Cell.TEXT, "Localisation answer relative to the stimulated pin.",
           levels=CATEGORY_MEANING),
    Column("perceived_motion", Cell.BOOLEAN, "Whether the subject felt a moving dot.",
           levels={"true": "felt motion", "false": "felt no motion"}),
    Column("direction_correct", Cell.BOOLEAN, "Whether the named direction matches the wave's; "
           "n/a when no motion was felt or there was no wave.",
           levels={"true": "named the wave's direction", "false": "did not"}),
    Column("stimulus_onset", Cell.SECONDS, "Stimulus onset on the run's time base: seconds from "
           "the run's time zero, continuing across sittings (see TimeBase); the onset column of "
           "the run's events.tsv.", units="s"),
    Column("stimulus_duration", Cell.SECONDS, "Stimulus duration (for a trial cut short, the time "
           "it ran); the duration column of the run's events.tsv.", units="s"),
    Column("response_time", Cell.SECONDS, "Time from stimulus onset to the response; n/a for "
           "scripted answers.", units="s"),
    Column("status", Cell.TEXT, "What became of the trial.", levels=TRIAL_STATUS_MEANING),
    Column("practice", Cell.BOOLEAN, "Whether this was a practice trial (not analysed).",
           levels={"true": "practice", "false": "main trial"}),
    Column("resumed", Cell.BOOLEAN, "Whether the trial ran in a sitting after the first (the run "
           "was resumed).", levels={"true": "after a resume", "false": "in the first sitting"}),
    Column("goals_scheduled", Cell.INTEGER, "Servo goal-position changes the trial's schedule "
           "holds; n/a when the stimulus never played."),
    Column("goals_confirmed", Cell.INTEGER, "Goal changes read back from their servo as sent "
           "(sync writes get no reply, so each is verified by a read)."),
    Column("goals_healed", Cell.INTEGER, "Goal changes the servo did not hold when read back "
           "(lost on the wire), written again with an acknowledged write."),
    Column("goals_missing", Cell.INTEGER, "Goal changes never confirmed on their servo; any makes "
           "the trial invalid."),
    Column("delivery_lateness", Cell.SECONDS, "How late the latest confirmed or healed goal change "
           "reached its servo after its scheduled time (host write time plus wire time); above "
           "the protocol's delivery tolerance the trial is invalid.", units="s"),
    Column("status_reason", Cell.TEXT, "Why a trial is not ok: the bus fault, what was not "
           "delivered as scheduled, or who stopped it; n/a for ok rows."),
    Column("procedure", Cell.TEXT, "The adaptive procedure (staircase or QUEST+, named in the "
           "protocol) whose trial this was, or catch for a catch trial (which moves none); n/a "
           "in a fixed design."),
    Column("adapted_parameter", Cell.TEXT, "The stimulus parameter the procedures adapt, with its "
           "unit as the protocol names it (soa_ms, stroke_steps, frequency_hz...); n/a in a fixed "
           "design."),
    Column("intensity", Cell.NUMBER, "The adapted parameter's value presented, in the unit "
           "adapted_parameter names; n/a for a catch trial's own stimulus and in a fixed design."),
    Column("correct", Cell.BOOLEAN, "Whether the answer counted as correct for the task (the "
           "wave's direction named; the moved pin named; something felt on a stimulus trial, "
           "nothing on a catch trial; the pattern, or its count of pins, named; the interval "
           "with the higher value named; the pin that started first named); n/a without an "
           "answer, in a fixed localisation or motion design, and at a temporal order's SOA "
           "of 0.",
           levels={"true": "counted as correct", "false": "counted as wrong"}),
    Column("reversal", Cell.BOOLEAN, "Whether the answer made the staircase reverse (move the "
           "other way from its previous move); n/a for QUEST+ and catch trials.",
           levels={"true": "a reversal", "false": "not a reversal"}),
    Column("threshold_estimate", Cell.NUMBER, "The procedure's threshold estimate once this "
           "answer is taken, in the adapted parameter's unit: a staircase's mean of its last "
           "reversals (n/a before its first), QUEST+'s posterior mean."),
    Column("threshold_ci_low", Cell.NUMBER, "QUEST+: the 2.5 % point of the threshold's "
           "posterior once this answer is taken; n/a for staircases."),
    Column("threshold_ci_high", Cell.NUMBER, "QUEST+: the 97.5 % point of the threshold's "
           "posterior once this answer is taken; n/a for staircases."),
    Column("guess_rate", Cell.NUMBER, "The chance of a correct answer without feeling the "
           "stimulus that the task implies (1/2 for two directions; 0 for detection), as the "
           "procedures and the analysis's fits assume."),
    Column("stroke_commanded", Cell.INTEGER, "The stroke the schedule commanded of the pin that "
           "moved the smallest share of it: the span of its goal positions, in servo steps; "
           "n/a when the servos report no position (PWM) or the stimulus never played.",
           units="steps"),
    Column("stroke_achieved", Cell.INTEGER, "That pin's achieved stroke: the smallest "
           "peak-to-peak of its sampled positions over the trial's cycles (a cycle runs from one "
           "up-going goal change to the next); below the protocol's stroke tolerance the trial "
           "is invalid. n/a when not measured (too few samples to judge a cycle).",
           units="steps"),
    Column("stroke_median", Cell.NUMBER, "That pin's median peak-to-peak over the cycles.",
           units="steps"),
    Column("motion_lag", Cell.SECONDS, "That pin's median time from a goal change to the first "
           "sample within 3 steps of the goal, a change never reached counting as longer than any; "
           "n/a when it reached no more than half of them.",
           units="s"),
    Column("cycles_short", Cell.INTEGER, "That pin's cycles whose peak-to-peak fell below the "
           "stroke tolerance."),
    Column("motion_samples", Cell.INTEGER, "How many position samples of this presentation the "
           "run's motion recording (its _recording-motion_physio.tsv.gz) holds: written and "
           "synced to disk before this row, in the order of the rows; 0 when none were taken "
           "(PWM servos, a stimulus that never played)."),
    # The lab's paradigms (identification, two intervals, temporal order), appended after the
    # columns files written before them hold (0.2.2's motion_samples the last of those).
    Column("pattern", Cell.TEXT, "Identification: the pattern presented, by its name in the "
           "protocol; n/a for the other paradigms."),
    Column("pins", Cell.TEXT, "The pins the stimulus moved, numbered as the subject sees them "
           "and separated by spaces: identification, every pin of the pattern; two intervals, "
           "the stimulus's pins; temporal order, pin A then pin B as the protocol lists them "
           "(soa is B's onset minus A's); n/a for localisation (see pin) and motion trials."),
    Column("compared_parameter", Cell.TEXT, "Two intervals: the parameter the intervals differ "
           "in, with its unit as the protocol names it (frequency_hz, duration_ms, soa_ms); n/a "
           "for the other paradigms."),
    Column("standard", Cell.NUMBER, "Two intervals: the standard's value, in the unit "
           "compared_parameter names."),
    Column("comparison", Cell.NUMBER, "Two intervals: the comparison's value, in the unit "
           "compared_parameter names (an adaptive design's: its intensity)."),
    Column("interval_order", Cell.TEXT, "Two intervals: which interval held the standard.",
           levels={IntervalOrder.STANDARD_FIRST: "the standard in the first interval, the "
                                                 "comparison in the second",
                   IntervalOrder.COMPARISON_FIRST: "the comparison in the first interval, the "
                                                   "standard in the second"}),
    Column("soa", Cell.SECONDS, "Temporal order: the onset of pin B's train minus pin A's "
           "(the pins column's order): positive when A started first, negative when B did.",
           units="s"),
)
BEH_NAMES = tuple(c.name for c in BEH_COLUMNS)
COLUMN = {c.name: c for c in BEH_COLUMNS}
# BIDS reserves onset and duration for events files (the validator warns BEH_ONSET_DURATION
# about a beh.tsv that has them): the same times are onset and duration in events.tsv, where
# BIDS requires them first, and stimulus_onset and stimulus_duration in beh.tsv.
EVENT_ONLY = {c.name: c for c in (
    Column("onset", Cell.SECONDS, "Stimulus onset on the run's time base: seconds from the run's "
           "time zero, continuing across sittings (see TimeBase).", units="s"),
    Column("duration", Cell.SECONDS, "Stimulus duration (for a trial cut short, the time it ran).",
           units="s"),
    Column("trial_type", Cell.TEXT, "Condition: the task and the frequency (localisation) or the "
           "wave's direction (motion), e.g. localisation_10hz."),
)}
TRIAL_TYPE = EVENT_ONLY["trial_type"]
EVENT_NAMES = ("onset", "duration", "trial_type", "trial", "pin", "row", "direction",
               "frequency_hz", "response", "status", "practice")
# beh.tsv columns that had another name in files written by an earlier pinarray: read as today's.
RENAMED = {"onset": "stimulus_onset", "duration": "stimulus_duration"}
# The columns of the first release; later ones were appended after them.
FIRST_NAMES = BEH_NAMES[: BEH_NAMES.index("resumed") + 1]


def number_text(value: float) -> str:
    """A number as a cell: whole numbers as integers ("10", not "10.0"), others exactly."""
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


_FORMAT: dict[Cell, Callable[[Any], str]] = {
    Cell.INTEGER: str,
    Cell.SECONDS: seconds_text,
    Cell.NUMBER: lambda value: number_text(float(value)),
    Cell.BOOLEAN: lambda value: "true" if value else "false",
    Cell.TEXT: str,
}


def _boolean(text: str) -> bool:
    return _BOOLEAN[text]


_PARSE: dict[Cell, Callable[[str], Any]] = {
    Cell.INTEGER: int,
    Cell.SECONDS: ns_from_seconds,
    Cell.NUMBER: float,
    Cell.BOOLEAN: _boolean,
    Cell.TEXT: str,
}


def _values(record: TrialRecord) -> dict[str, Any]:
    """The record's cells as Python values (None for n/a), by column name."""
    values: dict[str, Any] = {
        "trial": record.trial, "block": record.block, "task": record.task,
        "stimulus_onset": record.onset_ns, "stimulus_duration": record.duration_ns,
        "response_time": record.response_time_ns, "status": record.status,
        "practice": record.practice, "resumed": record.resumed,
        "status_reason": record.status_reason, "motion_samples": record.motion_samples,
    }
    match record:
        case LocalisationRecord():
            values |= {"pin": record.pin, "frequency_hz": record.frequency_hz,
                       "response": record.response, "error_class": record.category}
        case MotionRecord():
            values |= {"row": record.row, "direction": record.direction,
                       "response": record.response, "perceived_motion": record.perceived_motion,
                       "direction_correct": record.direction_correct}
        case IdentificationRecord():
            values |= {"pattern": record.pattern, "pins": pins_text(record.pins),
                       "response": record.response, "correct": record.correct}
        case TwoIntervalRecord():
            values |= {"compared_parameter": record.compared, "standard": record.standard,
                       "comparison": record.comparison, "interval_order": record.interval_order,
                       "pins": pins_text(record.pins), "response": record.response,
                       "correct": record.correct}
        case TemporalOrderRecord():
            values |= {"pins": pins_text(record.pins), "soa": record.soa_ns,
                       "response": record.response, "correct": record.correct}
    if record.stroke is not None:
        s = record.stroke
        values |= {"stroke_commanded": s.commanded_steps, "stroke_achieved": s.achieved_steps,
                   "stroke_median": s.median_steps, "motion_lag": s.lag_ns,
                   "cycles_short": s.short_cycles}
    if record.delivery is not None:
        d = record.delivery
        values |= {"goals_scheduled": d.scheduled, "goals_confirmed": d.confirmed,
                   "goals_healed": d.healed, "goals_missing": d.missing,
                   "delivery_lateness": d.lateness_ns}
    if record.adaptive is not None:
        a = record.adaptive
        values |= {"procedure": a.procedure, "adapted_parameter": a.parameter,
                   "intensity": a.intensity, "correct": a.correct, "reversal": a.reversal,
                   "threshold_estimate": a.estimate, "threshold_ci_low": a.estimate_ci_low,
                   "threshold_ci_high": a.estimate_ci_high, "guess_rate": a.guess_rate}
    return values


def _cells(values: Mapping[str, Any], names: Sequence[str]) -> list[str]:
    def cell(name: str) -> str:
        value = values.get(name)
        column = COLUMN.get(name) or EVENT_ONLY[name]
        return NA if value is None else _FORMAT[column.cell](value)

    return [cell(name) for name in names]


def pins_text(pins: Sequence[int]) -> str:
    """A pins cell: the pins separated by spaces."""
    return " ".join(map(str, pins))


def _pins_cell(text: str, where: str) -> tuple[int, ...]:
    try:
        return tuple(int(p) for p in text.split())
    except ValueError:
        raise ResultsError(f"{where}: column 'pins' cannot hold {text!r}") from None


def trial_type(record: TrialRecord) -> str:
    """The events.tsv condition label, e.g. ``localisation_10hz``, ``apparentmotion_left``,
    ``shapes_L``, ``flutter2ifc_12hz`` or ``toj_soa-40ms``."""
    match record:
        case LocalisationRecord():
            return condition_label(record.task, frequency_hz=record.frequency_hz)
        case MotionRecord():
            return condition_label(record.task, direction=record.direction)
        case IdentificationRecord():
            return f"{record.task}_{record.pattern}"
        case TwoIntervalRecord():
            unit = record.compared.rpartition("_")[2]
            return f"{record.task}_{number_text(record.comparison)}{unit}"
        case TemporalOrderRecord():
            return f"{record.task}_soa{number_text(record.soa_ns / 1e6)}ms"


def condition_label(task: str, *, frequency_hz: float | None = None,
                    direction: Direction | None = None) -> str:
    """``<task>_<frequency>hz`` or ``<task>_<direction>``: one trial_type level."""
    if direction is not None:
        return f"{task}_{direction.value}"
    assert frequency_hz is not None
    return f"{task}_{number_text(float(frequency_hz))}hz"


def trial_row(record: TrialRecord) -> list[str]:
    """The ``beh.tsv`` cells of ``record``, in column order."""
    return _cells(_values(record), BEH_NAMES)


def event_row(record: TrialRecord) -> list[str]:
    """The ``events.tsv`` cells of ``record``, in `EVENT_NAMES` order."""
    values = _values(record)
    return _cells(values | {"onset": values["stimulus_onset"],
                            "duration": values["stimulus_duration"],
                            "trial_type": trial_type(record)}, EVENT_NAMES)


def tsv_line(cells: Sequence[str]) -> str:
    out = io.StringIO()
    csv.writer(out, delimiter="\t", lineterminator="\n").writerow(cells)
    return out.getvalue()


# -- reading -------------------------------------------------------------------------------------


def split_torn_tail(data: bytes, columns: int) -> tuple[int, bytes]:
    """Where the whole rows of a TSV end, and the torn bytes after them.

    A row is whole when it ends in a newline and has ``columns`` cells. Only the last row can
    be torn (rows are written one at a time, each fsync'd); zero bytes that a file system may
    leave after a power cut are torn too.
    """
    end = len(data.rstrip(b"\0"))
    end = data.rfind(b"\n", 0, end) + 1  # 0 when there is no whole line at all
    if end:
        start = data.rfind(b"\n", 0, end - 1) + 1
        last = data[start:end].decode("utf-8", errors="replace")
        try:
            cells = len(next(csv.reader([last], delimiter="\t")))
        except csv.Error:  # not a row at all: not torn but damaged, which reading it says
            cells = columns
        if start and cells != columns:
            end = start
    return end, data[end:]


def beh_header(path: Path) -> list[str]:
    """The column names of an existing ``beh.tsv`` (empty if it has no header yet)."""
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            first = handle.readline()
    except FileNotFoundError:
        return []
    if not first.endswith("\n"):
        return []  # no header yet, or one torn by a crash (a resume drops it)
    return next(csv.reader([first], delimiter="\t"), []) if first.strip() else []


def todays_names(header: Sequence[str]) -> tuple[str, ...]:
    """A ``beh.tsv`` header with the columns an earlier pinarray named otherwise renamed."""
    return tuple(RENAMED.get(name, name) for name in header)


def _parse(name: str, text: str, where: str) -> Any:
    if text == NA:
        return None
    try:
        return _PARSE[COLUMN[name].cell](text)
    except (ValueError, KeyError):
        raise ResultsError(f"{where}: column {name!r} cannot hold {text!r}") from None


def _required(values: Mapping[str, Any], name: str, where: str) -> Any:
    if values.get(name) is None:
        raise ResultsError(f"{where}: column {name!r} cannot be n/a")
    return values[name]


def _record(values: Mapping[str, Any], where: str) -> TrialRecord:
    delivery = None
    goals: list[int] = [values[name] for name in ("goals_scheduled", "goals_confirmed",
                                                  "goals_healed", "goals_missing",
                                                  "delivery_lateness")
                        if values.get(name) is not None]
    if len(goals) == 5:
        delivery = DeliveryCounts(*goals)
    stroke = None
    if values.get("stroke_commanded") is not None:
        stroke = StrokeCounts(values["stroke_commanded"], values.get("stroke_achieved"),
                              values.get("stroke_median"), values.get("motion_lag"),
                              values.get("cycles_short"))
    adaptive = None
    if values.get("procedure") is not None:
        adaptive = AdaptiveCells(
            values["procedure"], _required(values, "adapted_parameter", where),
            values.get("intensity"), _required(values, "guess_rate", where),
            values.get("correct"), values.get("reversal"), values.get("threshold_estimate"),
            values.get("threshold_ci_low"), values.get("threshold_ci_high"))
    common: dict[str, Any] = {
        "trial": _required(values, "trial", where), "block": _required(values, "block", where),
        "task": _required(values, "task", where),
        "onset_ns": _required(values, "stimulus_onset", where),
        "duration_ns": _required(values, "stimulus_duration", where),
        "status": _required(values, "status", where),
        "response_time_ns": values.get("response_time"),
        "practice": bool(values.get("practice")), "resumed": bool(values.get("resumed")),
        "delivery": delivery, "status_reason": values.get("status_reason"), "stroke": stroke,
        "adaptive": adaptive, "motion_samples": values.get("motion_samples"),
    }
    try:
        if values.get("pattern") is not None:
            return IdentificationRecord(
                **common, pattern=values["pattern"],
                pins=_pins_cell(_required(values, "pins", where), where),
                response=values.get("response"))
        if values.get("interval_order") is not None:
            return TwoIntervalRecord(
                **common, compared=_required(values, "compared_parameter", where),
                standard=_required(values, "standard", where),
                comparison=_required(values, "comparison", where),
                interval_order=values["interval_order"],
                pins=_pins_cell(_required(values, "pins", where), where),
                response=values.get("response"))
        if values.get("soa") is not None:
            pins = _pins_cell(_required(values, "pins", where), where)
            return TemporalOrderRecord(**common, pins=pins,  # type: ignore[arg-type]
                                       soa_ns=values["soa"], response=values.get("response"))
        if values.get("pin") is not None:
            error_class = values.get("error_class")
            return LocalisationRecord(
                **common, pin=values["pin"], frequency_hz=_required(values, "frequency_hz", where),
                response=values.get("response"),
                error_class=None if error_class in (None, NOTHING_FELT) else error_class)
        if values.get("direction") is not None:
            return MotionRecord(**common, row=values.get("row"),
                                direction=values["direction"], response=values.get("response"))
    except ResultsError as problem:
        raise ResultsError(f"{where}: {problem}") from None
    raise ResultsError(f"{where}: a row needs a pin (localisation), a direction (motion), a "
                       "pattern (identification), an interval order (two intervals) or an soa "
                       "(temporal order)")


def read_trials(path: Path | str) -> list[TrialRecord]:
    """The whole rows of a ``beh.tsv`` (a torn last row is left out, not an error).

    Row ``i`` of the list is line ``i + 2`` of the file (line 1 is the header).
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ResultsError(f"{path}: no such results file") from None
    columns = len(beh_header(path)) or len(BEH_NAMES)
    end, _ = split_torn_tail(data, columns)
    try:
        rows = list(csv.reader(io.StringIO(data[:end].decode("utf-8")), delimiter="\t"))
    except csv.Error as problem:
        raise ResultsError(_not_a_table(path, data[:end], problem)) from None
    if not rows:
        return []
    header = todays_names(rows[0])
    if header != BEH_NAMES[: len(header)] or len(header) < len(FIRST_NAMES):
        raise ResultsError(f"{path}:1: expected the columns {list(BEH_NAMES)}, found {rows[0]}")
    # Files written before the delivery columns existed end at `resumed`: read what they hold.
    records = []
    for number, cells in enumerate(rows[1:], start=2):
        where = f"{path}:{number}"
        if len(cells) != len(header):
            raise ResultsError(f"{where}: expected {len(header)} cells, found {len(cells)}")
        values = {name: _parse(name, cell, where) for name, cell in zip(header, cells, strict=True)}
        records.append(_record(values, where))
    return records


def _not_a_table(path: Path, data: bytes, problem: csv.Error) -> str:
    """Where and why ``data`` cannot be read as tab-separated rows."""
    lone = re.search(rb"\r(?!\n)", data)
    if lone is None:
        return f"{path}: expected a tab-separated results table, found {problem}"
    line, col = position_of(data, lone.start())
    return (f"{path}:{line}:{col}: expected a tab-separated results table, found a carriage "
            "return inside a row")


def finished_trials(records: Iterable[TrialRecord]) -> frozenset[tuple[int, bool]]:
    """(trial, practice) of every trial whose row finishes it (status ok)."""
    return frozenset(r.key for r in records if r.status is TrialStatus.OK)


def finished_twice(records: Sequence[TrialRecord]) -> dict[tuple[int, bool], list[int]]:
    """Trials with more than one ``ok`` row, and the file lines of those rows (header = line 1)."""
    lines: dict[tuple[int, bool], list[int]] = {}
    for index, record in enumerate(records):
        if record.status is TrialStatus.OK:
            lines.setdefault(record.key, []).append(index + 2)
    return {key: found for key, found in lines.items() if len(found) > 1}

