"""Trial records as the lab reads them: one row per finished (or abandoned) trial, and its columns.

Every row is a `TrialRecord`: when the trial ran, what became of it, what reached the servos
and how far the pins moved, an adaptive design's cells, and the subject's answer. What the
trial presented is its paradigm's: each paradigm's room (`pinarray.paradigms`) has a record
type of its own (a subclass) and the columns that hold it (`pinarray.journal.seam`). Here are
the columns every row has (`COMMON_COLUMNS`) and the order files have kept since the first
release (`LEGACY_LAYOUT`). Times are whole nanoseconds in a record and decimal seconds in a
file; the writer is `pinarray.journal.writer`, the tables `pinarray.journal.rows`.
It passes 400 lines by the columns' descriptions (each a BIDS sidecar's words) and the
first release's column order, which every older file still read needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, StrEnum
from typing import Any, ClassVar, TypedDict

from pinarray.errors import ResultsError
from pinarray.journal.columns import Cell, Column
from pinarray.journal.paths import check_label


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


def coerce(record: object, name: str, kind: type[Enum], where: str) -> None:
    """Set a record's field ``name`` to its enum ``kind`` (a value read back as text), or a
    `ResultsError` naming the values it may take."""
    value = getattr(record, name)
    if value is None or isinstance(value, kind):
        return
    try:
        object.__setattr__(record, name, kind(value))
    except ValueError:
        allowed = ", ".join(str(member.value) for member in kind)
        raise ResultsError(f"{where}: {name} must be one of {allowed}, found {value!r}") from None


def check_pins(pins: object, where: str, count: int | None = None) -> None:
    """A record's pins: a tuple of pin numbers (``count`` of them, if given)."""
    if (not isinstance(pins, tuple) or not pins or (count is not None and len(pins) != count)
            or any(isinstance(p, bool) or not isinstance(p, int) or p < 1 for p in pins)):
        wanted = f"{count} pin numbers" if count else "pin numbers"
        raise ResultsError(f"{where}: pins must be {wanted}, found {pins!r}")


@dataclass(frozen=True, kw_only=True)
class TrialRecord:
    """One row of a run's ``beh.tsv``: what every trial row holds (its paradigm's record type
    adds what the trial presented). Times in whole nanoseconds; ``onset_ns`` on the run's time base.

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
    response : str or None
        The subject's answer, as the results write it; None when the trial got none.
    """

    paradigm: ClassVar[str] = ""  # the paradigm whose rows these are (its room's name)

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
    response: str | None = None

    def __post_init__(self) -> None:
        check_label("task", self.task)
        if isinstance(self.trial, bool) or not isinstance(self.trial, int) or self.trial < 0:
            raise ResultsError(f"trial number must be a whole number >= 0, found {self.trial!r}")
        where = f"trial {self.trial}"
        coerce(self, "status", TrialStatus, where)
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


class TrialFields(TypedDict, total=False):
    """The fields every record has, as the session fills them in and the reader reads them."""

    trial: int
    block: int
    task: str
    status: TrialStatus
    onset_ns: int
    duration_ns: int
    response_time_ns: int | None
    practice: bool
    resumed: bool
    delivery: DeliveryCounts | None
    status_reason: str | None
    adaptive: AdaptiveCells | None
    stroke: StrokeCounts | None
    motion_samples: int | None


# -- the columns every row has ---------------------------------------------------------------


TRIAL_STATUS_MEANING = {
    TrialStatus.OK: "completed and counted",
    TrialStatus.REDONE: "repeated at the experimenter's request; a later row holds the repeat",
    TrialStatus.ABORTED: "cut short; presented again on resume",
    TrialStatus.INVALID: "the stimulus failed (e.g. a bus fault, or not delivered as "
                         "scheduled); presented again",
}
COMMON_COLUMNS: tuple[Column, ...] = (
    Column("trial", Cell.INTEGER, "Trial number in the run's plan, 1..N in presentation order. "
           "Practice trials come first and are numbered like the rest (1..P, marked in the "
           "practice column); a trial presented again keeps its number."),
    Column("block", Cell.INTEGER, "Block number: 0 for practice, then 1..blocks."),
    Column("task", Cell.TEXT, "Task label: which experiment this row belongs to."),
    Column("response", Cell.TEXT, "The subject's answer; n/a when the trial got none (redone, "
           "aborted, invalid)."),
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
    Column("pins", Cell.TEXT, "The pins the stimulus moved, numbered as the subject sees them "
           "and separated by spaces: identification, every pin of the pattern; two intervals, "
           "the stimulus's pins; temporal order, pin A then pin B as the protocol lists them "
           "(soa is B's onset minus A's); n/a for localisation (see pin) and motion trials."),
)
COMMON = {c.name: c for c in COMMON_COLUMNS}
# The columns of a ``beh.tsv`` as every file written before the paradigm seam has them, in
# their order: the common ones and the five paradigms' of those releases (each n/a where the
# row is not its paradigm's). Those paradigms write them still, so that files and the tools
# reading them stay as they were; a paradigm added since writes the common columns, then its
# own (`pinarray.journal.seam.ParadigmRows.layout`).
LEGACY_LAYOUT = (
    "trial", "block", "task", "pin", "row", "direction", "frequency_hz", "response", "error_class",
    "perceived_motion", "direction_correct", "stimulus_onset", "stimulus_duration",
    "response_time", "status", "practice", "resumed", "goals_scheduled", "goals_confirmed",
    "goals_healed", "goals_missing", "delivery_lateness", "status_reason", "procedure",
    "adapted_parameter", "intensity", "correct", "reversal", "threshold_estimate",
    "threshold_ci_low", "threshold_ci_high", "guess_rate", "stroke_commanded", "stroke_achieved",
    "stroke_median", "motion_lag", "cycles_short", "motion_samples",
    # 0.3's paradigms, appended after the columns files before them hold (0.2.2's
    # motion_samples the last of those).
    "pattern", "pins", "compared_parameter", "standard", "comparison", "interval_order", "soa")
# The columns of the first release; later ones were appended after them.
FIRST_NAMES = LEGACY_LAYOUT[: LEGACY_LAYOUT.index("resumed") + 1]
# beh.tsv columns that had another name in files written by an earlier pinarray: read as today's.
RENAMED = {"onset": "stimulus_onset", "duration": "stimulus_duration"}
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
# events.tsv's columns as files before the seam have them; one added since: its own.
LEGACY_EVENT_LAYOUT = ("onset", "duration", "trial_type", "trial", "pin", "row", "direction",
                       "frequency_hz", "response", "status", "practice")
EVENT_LAYOUT = ("onset", "duration", "trial_type", "trial", "response", "status", "practice")


def common_cells(record: TrialRecord) -> dict[str, Any]:
    """The cells every row has, as Python values (None for n/a), by column name."""
    values: dict[str, Any] = {
        "trial": record.trial, "block": record.block, "task": record.task,
        "stimulus_onset": record.onset_ns, "stimulus_duration": record.duration_ns,
        "response_time": record.response_time_ns, "status": record.status,
        "practice": record.practice, "resumed": record.resumed,
        "status_reason": record.status_reason, "motion_samples": record.motion_samples,
        "response": record.response,
    }
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
    return values


def adaptive_cells(record: TrialRecord) -> dict[str, Any]:
    """An adaptive design's cells of the row (none in a fixed design's)."""
    if record.adaptive is None:
        return {}
    a = record.adaptive
    return {"procedure": a.procedure, "adapted_parameter": a.parameter,
            "intensity": a.intensity, "correct": a.correct, "reversal": a.reversal,
            "threshold_estimate": a.estimate, "threshold_ci_low": a.estimate_ci_low,
            "threshold_ci_high": a.estimate_ci_high, "guess_rate": a.guess_rate}


def required(values: dict[str, Any], name: str, where: str) -> Any:
    """A cell read back that may not be n/a."""
    if values.get(name) is None:
        raise ResultsError(f"{where}: column {name!r} cannot be n/a")
    return values[name]


def common_fields(values: dict[str, Any], where: str) -> TrialFields:
    """The fields every record has, from a row's cells read back (by column name)."""
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
            values["procedure"], required(values, "adapted_parameter", where),
            values.get("intensity"), required(values, "guess_rate", where),
            values.get("correct"), values.get("reversal"), values.get("threshold_estimate"),
            values.get("threshold_ci_low"), values.get("threshold_ci_high"))
    return {
        "trial": required(values, "trial", where), "block": required(values, "block", where),
        "task": required(values, "task", where),
        "onset_ns": required(values, "stimulus_onset", where),
        "duration_ns": required(values, "stimulus_duration", where),
        "status": required(values, "status", where),
        "response_time_ns": values.get("response_time"),
        "practice": bool(values.get("practice")), "resumed": bool(values.get("resumed")),
        "delivery": delivery, "status_reason": values.get("status_reason"), "stroke": stroke,
        "adaptive": adaptive, "motion_samples": values.get("motion_samples"),
    }
