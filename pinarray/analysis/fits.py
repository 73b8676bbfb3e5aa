"""Psychometric fits of a paradigm's answers, for the rooms whose trials ask for a choice.

A room that reports a threshold (two intervals, two points) or a point of subjective
simultaneity (temporal order) counts each subject's answers at each value (`points`), fits
them through the adaptive designs' fitting (`pinarray.adaptive.posterior`: the Bayesian
posterior over a grid of threshold x slope x lapse rate, its medians and 95 % credible
intervals, words where the answers cannot place a value), and says each value as an
`pinarray.analysis.seam.Estimate` with its status. Across subjects: the mean of the subjects'
values with the interval the analysis's settings name; a subject without a value is left out.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeAlias

import numpy as np

from pinarray.adaptive.posterior import ThresholdPosterior, ThresholdStatus, threshold_posterior
from pinarray.adaptive.psychometric import PsychometricKind
from pinarray.analysis.seam import Estimate, EstimateStatus, Reported
from pinarray.analysis.subjects import IntervalSettings, interval_of
from pinarray.analysis.tables import ALL_SUBJECTS, number
from pinarray.analysis.thresholds import NotFitted
from pinarray.errors import PinArrayError

NOT_FITTED = "not fitted"
NO_FIT = Estimate(math.nan, math.nan, math.nan, EstimateStatus.NOT_RESOLVED, NOT_FITTED)
Fit: TypeAlias = ThresholdPosterior | NotFitted


def placed(value: float, low: float, high: float, *, has_low: bool, has_high: bool,
           words: str) -> Estimate:
    """Numbers only where the words state them: the value and both bounds when both are
    stated, one bound alone, none when neither."""
    if has_low and has_high:
        return Estimate(value, low, high, EstimateStatus.ESTIMATED, words)
    if has_low or has_high:
        return Estimate(math.nan, low if has_low else math.nan, high if has_high else math.nan,
                        EstimateStatus.BOUNDED, words)
    return Estimate(math.nan, math.nan, math.nan, EstimateStatus.NOT_RESOLVED, words)


def threshold_estimate(fit: Fit, scale: float = 1.0) -> Estimate:
    """A fit's threshold (times ``scale``) as its `ThresholdStatus` places it: below the
    lowest value tested states an upper bound, above the highest a lower one."""
    if isinstance(fit, NotFitted):
        return NO_FIT
    status = fit.status
    estimated = status is ThresholdStatus.ESTIMATED
    return placed(fit.threshold * scale, fit.ci_low * scale, fit.ci_high * scale,
                  has_low=estimated or status is ThresholdStatus.ABOVE,
                  has_high=estimated or status is ThresholdStatus.BELOW, words=status.value)


@dataclass(frozen=True)
class Point:
    """The answers at one value: ``hits`` of ``trials`` (the answer the fit counts: the
    higher interval named, pin A named first...)."""

    x: float
    hits: int
    trials: int

    @property
    def proportion(self) -> float:
        return self.hits / self.trials


def points(pairs: Sequence[tuple[float, bool]]) -> tuple[Point, ...]:
    """(value, hit) pairs counted at each value, lowest first."""
    xs = sorted({x for x, _ in pairs})
    return tuple(Point(x, sum(hit for v, hit in pairs if v == x), sum(v == x for v, _ in pairs))
                 for x in xs)


def fit(kind: PsychometricKind, found: Sequence[Point], guess: float,
        lapse: float | None) -> Fit:
    """The Bayesian fit of ``found`` (a fixed ``lapse``, or None: fitted), or why there is none."""
    if len(found) < 2:
        return NotFitted(f"answers at {len(found)} value; a fit needs 2 or more")
    try:
        return threshold_posterior(kind, [p.x for p in found], [p.hits for p in found],
                                   [p.trials for p in found], guess=guess, lapse=lapse)
    except PinArrayError as problem:
        return NotFitted(str(problem))


@dataclass(frozen=True)
class AcrossMeasure:
    """One measure of a task with the subject as the unit."""

    task: str
    measure: str  # weber_fraction, threshold, pss_ms, jnd_ms...
    unit: str
    per_subject: tuple[tuple[str, float], ...]
    mean: float
    interval: tuple[float, float]

    @property
    def estimate(self) -> Estimate:
        low, high = self.interval
        return Estimate.of(self.mean, low, high)


def across(task: str, measure: str, unit: str, values: Sequence[tuple[str, float]],
           settings: IntervalSettings) -> AcrossMeasure:
    """The mean over subjects with a value (a subject fitted in several runs counts once)."""
    by_subject: dict[str, list[float]] = {}
    for subject, value in values:
        if not math.isnan(value):
            by_subject.setdefault(subject, []).append(value)
    kept = tuple((s, float(np.mean(v))) for s, v in sorted(by_subject.items()))
    numbers = [v for _, v in kept]
    mean = float(np.mean(numbers)) if numbers else math.nan
    return AcrossMeasure(task, measure, unit, kept, mean, interval_of(numbers, settings))


class SubjectFit(Protocol):
    """One subject's fit of one task: what `FittedFindings` needs of it."""

    @property
    def subject(self) -> str: ...

    @property
    def task(self) -> str: ...

    @property
    def trials(self) -> int: ...

    def reported(self) -> tuple[tuple[str, str, Estimate], ...]:
        """Its estimates: (measure, unit, estimate) each."""
        ...


@dataclass(frozen=True)
class FittedFindings:
    """Findings made of per-subject fits and their across-subject means: the part of
    `pinarray.analysis.seam.Findings` every fitting room states alike (its trials, tasks and
    estimates). A room's findings subclass it and add ``paradigm`` and the rest."""

    fits: tuple[SubjectFit, ...]
    across: tuple[AcrossMeasure, ...]
    settings: IntervalSettings

    @property
    def trials(self) -> int:
        return sum(f.trials for f in self.fits)

    def task_trials(self, task: str) -> int:
        return sum(f.trials for f in self.fits if f.task == task)

    def tasks(self) -> list[str]:
        return sorted({f.task for f in self.fits})

    def measures_of(self, task: str) -> dict[str, AcrossMeasure]:
        return {m.measure: m for m in self.across if m.task == task}

    def task_subjects(self, task: str) -> int:
        """How many subjects have a fit of ``task`` (with a number or not)."""
        return len({f.subject for f in self.fits if f.task == task})

    def across_text(self, measure: AcrossMeasure, digits: int = 3) -> str:
        """The across-subject cell of ``measure``: its mean and interval, or what is true
        when there is none (`across_text`)."""
        return across_text(measure, self.task_subjects(measure.task), digits)

    @property
    def estimates(self) -> tuple[Reported, ...]:
        found = [Reported(f.task, f.subject, measure, unit, f.trials, e)
                 for f in self.fits for measure, unit, e in f.reported()]
        return (*found, *(Reported(m.task, ALL_SUBJECTS, m.measure, m.unit,
                                   self.task_trials(m.task), m.estimate) for m in self.across))

    def methods(self) -> list[str]:
        return []


def estimate_text(e: Estimate, digits: int = 3) -> str:
    """A subject's value with its credible interval, or its words with the bound they state."""
    if e.words == NOT_FITTED:
        return NOT_FITTED
    if e.status is EstimateStatus.ESTIMATED:
        return f"{_n(e.value, digits)} [{_n(e.ci_low, digits)}, {_n(e.ci_high, digits)}]"
    bound = (f" (< {_n(e.ci_high, digits)})" if not math.isnan(e.ci_high)
             else f" (> {_n(e.ci_low, digits)})" if not math.isnan(e.ci_low) else "")
    return f"*{e.words}*{bound}"


def _n(value: float, digits: int) -> str:
    return number(value, digits)


# -- what the tables' sidecars and the summary say of fitted estimates ----------------------

ACROSS_TEXT = ("; for subject all, the mean over the subjects whose value is a number, with the "
               "across-subject interval the summary names")
THRESHOLD_WORDS = {
    ThresholdStatus.ESTIMATED.value: "a value and its 95 % credible interval",
    ThresholdStatus.BELOW.value: "the answers cannot bound it from below (e.g. every answer "
    "right): only its upper bound, one-sided 95 %",
    ThresholdStatus.ABOVE.value: "the answers cannot bound it from above (e.g. every answer "
    "at chance): only its lower bound, one-sided 95 %",
    ThresholdStatus.NOT_ESTIMABLE.value: "the answers bound it neither from below nor from "
    "above", NOT_FITTED: "no fit (summary.md says why)", "n/a": "an across-subject mean"}
COVERAGE_TEXT = ("on simulated subjects running the shipped protocol the 95 % credible intervals "
                 "held the true value {measured} (a check made once, not re-measured by make "
                 "bench; thresholds.json gives the adaptive designs' measured coverage)")


def bounds_columns(name: str, unit: str) -> dict[str, dict[str, object]]:
    """A fitted estimate's ``ci_low`` and ``ci_high`` columns, as a table's sidecar says them."""
    return {f"{name}ci_low": {"Description": "the 2.5 % point of the 95 % credible interval "
                              "(one-sided 95 % lower bound where the status says 'above'); "
                              "n/a where there is none" + ACROSS_TEXT, "Units": unit},
            f"{name}ci_high": {"Description": "the 97.5 % point of the 95 % credible interval "
                               "(one-sided 95 % upper bound where the status says 'below'); "
                               "n/a where there is none" + ACROSS_TEXT, "Units": unit}}


def write_sidecar(path: Path, columns: dict[str, dict[str, object]]) -> Path:
    """A table's sidecar (BIDS style: each column's Description, Units, Levels)."""
    path.write_text(json.dumps(columns, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def not_fitted_notes(fits: Sequence[tuple[str, str, Fit, Sequence[tuple[str, Estimate]]]]
                     ) -> list[str]:
    """A note for each subject without a fit, and each whose value is in words (left out of
    the across-subject mean): (subject, task, fit, (name, estimate)...) each."""
    notes = []
    for subject, task, found, said in fits:
        if isinstance(found, NotFitted):
            notes.append(f"- subject {subject}, task {task}: no fit: {found.reason}")
            continue
        for name, e in said:
            if e.words != NOT_FITTED and math.isnan(e.value):
                notes.append(f"- subject {subject}, task {task}: {name} {estimate_text(e)}, "
                             f"tested {found.lowest_tested:g} to {found.highest_tested:g}; left "
                             "out of the across-subject mean")
    return [""] + notes if notes else []


def markdown_row(cells: Sequence[object]) -> str:
    """One row of a Markdown table."""
    return "| " + " | ".join(map(str, cells)) + " |"


def across_text(measure: AcrossMeasure, subjects: int, digits: int = 3) -> str:
    """An across-subject mean with its interval, of ``subjects`` subjects fitted, or what is
    true when there is none: no subject with a number, or only one."""
    with_number = len(measure.per_subject)
    if not with_number:
        return ("not resolved (one subject)" if subjects == 1
                else f"not resolved in any of {subjects} subjects")
    low, high = measure.interval
    of = f" of {subjects}" if subjects > with_number else ""
    if math.isnan(low):
        return f"{_n(measure.mean, digits)}, no interval (one subject with a number{of})"
    shown = f"{_n(measure.mean, digits)} [{_n(low, digits)}, {_n(high, digits)}]"
    return shown + (f" ({with_number} subjects with a number{of})" if of else "")
