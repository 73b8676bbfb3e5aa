"""Thresholds from the rows of adaptive designs: each procedure's own estimate, a psychometric
fit per subject, and their means with the subject as the unit.

What counts: rows with adaptive cells that count (status ok, not practice), in file order;
catch trials (procedure ``catch``) move no procedure and are left out of both. Per subject,
task and adapted parameter:

- each **procedure** (a staircase or QUEST+, by the name the protocol gives it, one per run)
  gives the estimate on its last counted row: a staircase's mean of its last reversals
  (``reversal_mean``; n/a before its first reversal, no interval), QUEST+'s posterior mean
  with its 95 % credible interval (``questplus_posterior``). A procedure is QUEST+ when any
  of its rows has a credible interval;
- one **Bayesian fit** (`pinarray.adaptive.posterior`) over every counted row of the task,
  pooled over its procedures (and runs), binned by intensity: a Weibull (``bayes_weibull``)
  with the guess rate the rows state, the threshold the median of its posterior over a grid of
  threshold x slope x lapse rate (a weakly informative prior on the slope), and its 95 %
  credible interval, whose coverage is measured on simulated subjects (`COVERAGE`). Where the
  answers cannot place the threshold, the fit says so in words (`ThresholdStatus`: below the
  lowest value tested, above the highest, not estimable) instead of a number. With an
  intensity of 0 or below a Weibull is undefined and a logistic is fitted instead
  (``bayes_logistic``); with fewer than two intensities there is no fit (n/a).

Across subjects (subject ``all``): for each procedure name, and for the fit, the mean of the
subjects' thresholds with the interval the analysis's settings name (subject bootstrap or t;
`pinarray.analysis.subjects`); a subject with no estimate, or whose fit gives words instead of
a threshold, is left out. A subject with several
runs of a procedure counts once, with the mean of their estimates.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from pinarray.adaptive.posterior import (
    SLOPE_LOG_SD,
    SLOPE_MEDIAN,
    ThresholdPosterior,
    ThresholdStatus,
    threshold_posterior,
)
from pinarray.adaptive.psychometric import PsychometricKind
from pinarray.analysis.load import LoadedTrial, RunSelection
from pinarray.analysis.stats import POOLED
from pinarray.analysis.subjects import (
    DEFAULT_SETTINGS,
    IntervalMethod,
    IntervalSettings,
    bootstrap_interval,
    t_interval,
)
from pinarray.errors import PinArrayError, ResultsError
from pinarray.journal.columns import NA
from pinarray.protocol.procedures import CATCH

ALL_SUBJECTS = POOLED  # the subject cell of an across-subject row
POOLED_PROCEDURES = "pooled"  # the procedure cell of a fit: every procedure of the task
# The unit an adapted parameter's name ends in (soa_ms), as a table says it.
UNITS = {"ms": "ms", "us": "us", "ns": "ns", "s": "s", "hz": "Hz", "steps": "steps",
         "mm": "mm", "deg": "deg"}


class ThresholdMethod(StrEnum):
    """Where a threshold comes from (the module docstring says how each is made)."""

    REVERSAL_MEAN = "reversal_mean"
    QUESTPLUS_POSTERIOR = "questplus_posterior"
    BAYES_WEIBULL = "bayes_weibull"
    BAYES_LOGISTIC = "bayes_logistic"


# What `make bench` (tests/benchmarks/bench_thresholds.py) measured: the share of simulated
# subjects whose fit's 95 % interval held their true threshold. Measured again there each run.
COVERAGE = ("95 % credible intervals measured to hold the true threshold for {motion} of "
            "simulated subjects running protocols/staircase_motion.yaml and {stroke} running "
            "protocols/quest_stroke.yaml (thresholds log-uniform over the tested values, 20-300 "
            "ms and 4-120 steps, slopes 1.5-5, "
            "lapse rates 0-0.04; a threshold given in words counted by the bound it states)")
MEASURED = {"motion": "96.3 % (289 of 300)", "stroke": "98.0 % (294 of 300)"}


def fit_method_text(kind: PsychometricKind = "weibull") -> str:
    """How the fit's threshold and interval are made, in a sentence (tables, report, figures)."""
    name = "Weibull" if kind == "weibull" else "logistic"
    return (f"Bayesian {name} fit: the threshold is the median of its posterior over a grid of "
            f"threshold x slope x lapse rate (lapse 0-0.1, prior highest at 0; slope prior "
            f"log-normal around {SLOPE_MEDIAN:g}, sd {SLOPE_LOG_SD:g} of its log; threshold "
            f"prior flat across the tested range, falling off beyond it), the interval its 95 % "
            f"equal-tailed credible interval; " + COVERAGE.format(**MEASURED))


def threshold_definition(kind: PsychometricKind, guess: float) -> str:
    """What the fit's threshold is: the share of the function's rise and the probability
    correct there, in a sentence."""
    if kind == "weibull":
        share, rise = "1 - 1/e (63.2 %)", float(-math.expm1(-1.0))
    else:
        share, rise = "half (50 %)", 0.5
    at = f"{100 * (guess + (1 - guess) * rise):.1f} %"
    return (f"the intensity at which the fitted {kind} has risen {share} of its way from the "
            f"guess rate ({guess:g}, as the rows state) to 1 - lapse rate (the lapse rate "
            f"fitted): {at} correct at a lapse rate of 0, less by {rise:.3f} x the lapse rate")


def interval_name(settings: IntervalSettings) -> str:
    """The across-subject interval of thresholds, named (in the threshold's unit, unbounded)."""
    match settings.method:
        case IntervalMethod.T:
            return f"{settings.level_pct} t interval across subjects (mean ± t(N-1) · SD/√N)"
        case IntervalMethod.BOOTSTRAP:
            return (f"{settings.level_pct} subject bootstrap (percentile; "
                    f"{settings.bootstrap_resamples} resamples of subjects, seed "
                    f"{settings.bootstrap_seed})")
    raise AssertionError(settings.method)


def parameter_and_unit(adapted_parameter: str) -> tuple[str, str]:
    """``soa_ms`` -> (``soa``, ``ms``); a name without a known unit suffix keeps it, unit n/a."""
    name, _, suffix = adapted_parameter.rpartition("_")
    unit = UNITS.get(suffix.lower())
    return (name, unit) if name and unit else (adapted_parameter, NA)


@dataclass(frozen=True)
class TrackPoint:
    """One counted trial of a procedure: the run's trial number, the intensity presented (the
    adapted parameter's unit), whether the answer counted as correct, and whether it made a
    staircase reversal (always False for QUEST+)."""

    trial: int
    intensity: float
    correct: bool
    reversal: bool


@dataclass(frozen=True)
class ProcedureEstimate:
    """One procedure's own estimate, from its last counted row; NaN where there is none
    (a staircase before its first reversal; a staircase's interval)."""

    procedure: str
    run_label: str  # "ses-1 run-2"; shown only when a subject ran the procedure more than once
    method: ThresholdMethod
    track: tuple[TrackPoint, ...]
    threshold: float
    ci_low: float
    ci_high: float

    @property
    def n_trials(self) -> int:
        return len(self.track)


@dataclass(frozen=True)
class Bin:
    """The counted trials at one intensity, all procedures of a subject's task pooled."""

    intensity: float
    correct: int
    trials: int

    @property
    def proportion(self) -> float:
        return self.correct / self.trials


@dataclass(frozen=True)
class NotFitted:
    """No psychometric function was fitted; ``reason`` says why."""

    reason: str


@dataclass(frozen=True)
class SubjectThresholds:
    """One subject's thresholds for one task and adapted parameter."""

    subject: str
    task: str
    adapted_parameter: str
    guess_rate: float
    procedures: tuple[ProcedureEstimate, ...]
    bins: tuple[Bin, ...]
    fit: ThresholdPosterior | NotFitted

    @property
    def parameter(self) -> str:
        return parameter_and_unit(self.adapted_parameter)[0]

    @property
    def unit(self) -> str:
        return parameter_and_unit(self.adapted_parameter)[1]

    @property
    def fit_method(self) -> ThresholdMethod:
        match self.fit:
            case ThresholdPosterior(kind="logistic"):
                return ThresholdMethod.BAYES_LOGISTIC
        return ThresholdMethod.BAYES_WEIBULL

    @property
    def fit_threshold(self) -> float:
        """The fit's threshold where the answers place it; NaN where there is none or words."""
        match self.fit:
            case ThresholdPosterior(status=ThresholdStatus.ESTIMATED, threshold=threshold):
                return threshold
        return math.nan

    @property
    def fit_trials(self) -> int:
        return sum(b.trials for b in self.bins)

    @property
    def stem(self) -> str:
        """The part of a figure's file name that names this subject, task and parameter."""
        return f"sub-{self.subject}_task-{self.task}_{self.parameter}"

    def label(self, estimate: ProcedureEstimate) -> str:
        """The procedure's name, with its run when this subject ran it more than once."""
        runs = sum(p.procedure == estimate.procedure for p in self.procedures)
        return estimate.procedure if runs < 2 else f"{estimate.procedure} {estimate.run_label}"


@dataclass(frozen=True)
class AcrossSubjectThreshold:
    """One threshold with subjects as the unit: each subject's value and their mean.

    ``procedure`` names the procedure (or ``pooled`` for the fit); ``per_subject`` holds
    (subject, threshold, counted trials) for the subjects with an estimate; the interval is
    NaN with fewer than two subjects.
    """

    task: str
    adapted_parameter: str
    method: ThresholdMethod
    procedure: str
    per_subject: tuple[tuple[str, float, int], ...]
    t_interval: tuple[float, float]
    bootstrap_interval: tuple[float, float]

    @property
    def subjects(self) -> int:
        return len(self.per_subject)

    @property
    def n_trials(self) -> int:
        return sum(n for _, _, n in self.per_subject)

    @property
    def mean(self) -> float:
        return float(np.mean([v for _, v, _ in self.per_subject])) if self.per_subject \
            else math.nan

    def interval(self, method: IntervalMethod) -> tuple[float, float]:
        match method:
            case IntervalMethod.T:
                return self.t_interval
            case IntervalMethod.BOOTSTRAP:
                return self.bootstrap_interval
        raise AssertionError(method)


@dataclass(frozen=True)
class Thresholds:
    """Every subject's thresholds and their across-subject means; empty without adaptive rows."""

    per_subject: tuple[SubjectThresholds, ...]
    across: tuple[AcrossSubjectThreshold, ...]
    settings: IntervalSettings

    @property
    def found(self) -> bool:
        return bool(self.per_subject)


def thresholds(runs: RunSelection, settings: IntervalSettings = DEFAULT_SETTINGS) -> Thresholds:
    """The thresholds of the included runs' adaptive rows (the module docstring's rule)."""
    groups: dict[tuple[str, str, str], list[LoadedTrial]] = {}
    for trial in runs.trials:
        cells = trial.record.adaptive
        if cells is None or not trial.record.counts or cells.procedure == CATCH:
            continue
        groups.setdefault((trial.subject, trial.record.task, cells.parameter), []).append(trial)
    per_subject = tuple(_subject(key, groups[key]) for key in sorted(groups))
    return Thresholds(per_subject, _across(per_subject, settings), settings)


def _subject(key: tuple[str, str, str], trials: Sequence[LoadedTrial]) -> SubjectThresholds:
    subject, task, parameter = key
    guesses = sorted({t.record.adaptive.guess_rate for t in trials if t.record.adaptive})
    if len(guesses) > 1:
        sources = ", ".join(sorted({str(t.source) for t in trials}))
        raise ResultsError(f"{sources}: expected one guess_rate for task {task} ({parameter}) "
                           f"of subject {subject}, found {', '.join(map(str, guesses))}")
    by_procedure: dict[tuple[str, str, int], list[LoadedTrial]] = {}
    for trial in trials:
        assert trial.record.adaptive is not None
        by_procedure.setdefault((trial.record.adaptive.procedure, trial.session, trial.run),
                                []).append(trial)
    procedures = tuple(_procedure(name, f"ses-{session} run-{run}", rows)
                       for (name, session, run), rows in sorted(by_procedure.items()))
    points = [p for estimate in procedures for p in estimate.track]
    intensities = sorted({p.intensity for p in points})
    bins = tuple(Bin(x, sum(p.correct for p in points if p.intensity == x),
                     sum(p.intensity == x for p in points)) for x in intensities)
    return SubjectThresholds(subject, task, parameter, guesses[0], procedures, bins,
                             _fit(bins, guesses[0]))


def _number(value: float | None) -> float:
    return math.nan if value is None else float(value)


def _procedure(name: str, run_label: str, rows: Sequence[LoadedTrial]) -> ProcedureEstimate:
    cells = [r.record.adaptive for r in rows if r.record.adaptive is not None]
    questplus = any(c.estimate_ci_low is not None or c.estimate_ci_high is not None
                    for c in cells)
    track = tuple(TrackPoint(r.record.trial, c.intensity, c.correct, bool(c.reversal))
                  for r, c in zip(rows, cells, strict=True)
                  if c.intensity is not None and c.correct is not None)
    last = cells[-1]
    if questplus:
        return ProcedureEstimate(name, run_label, ThresholdMethod.QUESTPLUS_POSTERIOR, track,
                                 _number(last.estimate), _number(last.estimate_ci_low),
                                 _number(last.estimate_ci_high))
    return ProcedureEstimate(name, run_label, ThresholdMethod.REVERSAL_MEAN, track,
                             _number(last.estimate), math.nan, math.nan)


def _fit(bins: Sequence[Bin], guess: float) -> ThresholdPosterior | NotFitted:
    if len(bins) < 2:
        return NotFitted(f"answers at {len(bins)} intensity; a fit needs 2 or more")
    kind: PsychometricKind = "weibull" if all(b.intensity > 0 for b in bins) else "logistic"
    try:
        return threshold_posterior(kind, [b.intensity for b in bins], [b.correct for b in bins],
                                   [b.trials for b in bins], guess=guess)
    except PinArrayError as problem:
        return NotFitted(str(problem))


def _across(per_subject: Iterable[SubjectThresholds],
            settings: IntervalSettings) -> tuple[AcrossSubjectThreshold, ...]:
    # (task, parameter, method, procedure) -> subject -> [(threshold, trials)]
    values: dict[tuple[str, str, ThresholdMethod, str], dict[str, list[tuple[float, int]]]] = {}
    for s in per_subject:
        for estimate in s.procedures:
            key = (s.task, s.adapted_parameter, estimate.method, estimate.procedure)
            values.setdefault(key, {}).setdefault(s.subject, []).append(
                (estimate.threshold, estimate.n_trials))
        key = (s.task, s.adapted_parameter, s.fit_method, POOLED_PROCEDURES)
        values.setdefault(key, {}).setdefault(s.subject, []).append((s.fit_threshold,
                                                                     s.fit_trials))
    across = []
    for (task, parameter, method, procedure), subjects in values.items():
        kept = []
        for subject, found in sorted(subjects.items()):
            estimates = [v for v, _ in found if not math.isnan(v)]
            if estimates:
                kept.append((subject, float(np.mean(estimates)), sum(n for _, n in found)))
        numbers = [v for _, v, _ in kept]
        across.append(AcrossSubjectThreshold(
            task, parameter, method, procedure, tuple(kept), t_interval(numbers, settings.level),
            bootstrap_interval(numbers, settings.bootstrap_seed, settings.bootstrap_resamples,
                               settings.level)))
    return tuple(sorted(across, key=lambda a: (a.task, a.adapted_parameter,
                                               a.procedure == POOLED_PROCEDURES, a.procedure)))

