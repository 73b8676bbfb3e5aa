"""Two intervals' findings: a Weber fraction per subject, from a psychometric fit.

Over each subject's counted rows of a task (status ok, not practice), fixed and adaptive
alike: the proportion of answers naming the interval with the higher value against the
difference ``|comparison - standard|`` (per standard), a Bayesian Weibull with guess rate 1/2
and the lapse rate fitted (0-0.1), as the adaptive designs' fit (`pinarray.analysis.fits`).
The difference threshold is the Weibull's (its rise 1 - 1/e of the way, 81.6 % correct
without lapses), the posterior's median with its credible interval; the **Weber fraction** is
that threshold over the standard (interval likewise); the difference at 75 % correct (the
function at the posterior medians) is given beside it. Where the answers cannot place the
threshold it is given in words (below the lowest value tested, above the highest, not
estimable) with the one bound they state. Across subjects (subject ``all``): the mean of the
subjects' Weber fractions with the interval the analysis's settings name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.adaptive.posterior import SLOPE_LOG_SD, SLOPE_MEDIAN, ThresholdPosterior
from pinarray.analysis.fits import (
    ACROSS_TEXT,
    COVERAGE_TEXT,
    THRESHOLD_WORDS,
    AcrossMeasure,
    Fit,
    FittedFindings,
    Point,
    across,
    bounds_columns,
    estimate_text,
    fit,
    markdown_row,
    not_fitted_notes,
    points,
    threshold_estimate,
    write_sidecar,
)
from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.seam import (
    AnalysisDefaults,
    Context,
    Estimate,
    EstimateStatus,
    Findings,
)
from pinarray.analysis.tables import ALL_SUBJECTS, number, write_csv
from pinarray.analysis.thresholds import interval_name, parameter_and_unit
from pinarray.errors import PinArrayError
from pinarray.paradigms.two_interval.rows import TwoIntervalRecord

GUESS = 0.5
METHOD = (
    "Bayesian Weibull fit, as the adaptive designs' (pinarray.adaptive.posterior), of the "
    "proportion naming the interval with the higher value against the difference from the "
    "standard: guess rate 1/2, lapse rate 0-0.1 (prior highest at 0); the threshold, the "
    "difference at which the Weibull has risen 1 - 1/e of its way from 1/2 to 1 - lapse rate "
    "(81.6 % correct at a lapse rate of 0), is the median of its posterior over a grid of "
    "threshold x slope x lapse rate (slope prior log-normal around {median:g}, sd {sd:g} of its "
    "log; threshold prior flat in log across the differences tested, falling off beyond), "
    "the interval its 95 % equal-tailed credible interval; the Weber fraction is both over "
    "the standard")
# Checked once (issue 40's merge), not re-measured by `make bench`: 900 simulated subjects
# (Weber fraction 0.1-0.3, Weibull shape 1.5-5, lapse rates 0-0.04) running
# protocols/flutter_2ifc.yaml as tests/analysis/test_lab_analysis.py simulates them.
COVERAGE = "of the Weber fraction for 95.7 % of them (861 of 900)"
COLUMNS = ("subject", "task", "parameter", "unit", "standard", "threshold", "ci_low", "ci_high",
           "status", "weber_fraction", "weber_ci_low", "weber_ci_high", "difference_75pct",
           "n_trials")


def method_text() -> str:
    """How the threshold and Weber fraction are made, in a sentence."""
    return (f"{METHOD.format(median=SLOPE_MEDIAN, sd=SLOPE_LOG_SD)}; "
            f"{COVERAGE_TEXT.format(measured=COVERAGE)}")


@dataclass(frozen=True)
class IntervalFit:
    """One subject's two-interval discrimination of ``compared`` around ``standard``."""

    subject: str
    task: str
    compared: str
    standard: float
    points: tuple[Point, ...]  # x: the difference from the standard
    fit: Fit

    @property
    def unit(self) -> str:
        return parameter_and_unit(self.compared)[1]

    @property
    def trials(self) -> int:
        return sum(p.trials for p in self.points)

    @property
    def threshold(self) -> Estimate:
        """The difference threshold and its interval, in the compared unit."""
        return threshold_estimate(self.fit)

    def reported(self) -> tuple[tuple[str, str, Estimate], ...]:
        return (("threshold", self.unit, self.threshold), ("weber_fraction", "", self.weber))

    @property
    def weber(self) -> Estimate:
        """The Weber fraction (threshold over the standard) and its interval."""
        return threshold_estimate(self.fit, 1 / abs(self.standard) if self.standard else math.nan)

    @property
    def difference_75(self) -> float:
        """The difference answered right 75 % of the time (the function at the posterior
        medians); NaN where the threshold is in words or there is no fit."""
        if not isinstance(self.fit, ThresholdPosterior) or self.threshold.status is not \
                EstimateStatus.ESTIMATED:
            return math.nan
        try:
            return self.fit.function.intensity_for(0.75)
        except PinArrayError:
            return math.nan


def _n(value: float, digits: int = 3) -> str:
    return number(value, digits)


@dataclass(frozen=True)
class TwoIntervals(FittedFindings):
    """Every subject's two-interval fits and their across-subject means (`Findings`)."""

    fits: tuple[IntervalFit, ...]
    paradigm: str = "two_interval"

    def counted(self) -> str:
        return f"{self.trials} two-interval trials"

    def tables(self, out: Path) -> list[Path]:
        """``two_interval.csv``: each subject's row, then the across-subject means (subject
        ``all``, the interval the settings name); and its sidecar ``two_interval.json``."""
        rows: list[list[object]] = [
            [f.subject, f.task, *parameter_and_unit(f.compared), f"{f.standard:g}",
             *map(_n, f.threshold.numbers), f.threshold.words, *map(_n, f.weber.numbers),
             _n(f.difference_75), f.trials] for f in self.fits]
        for m in self.across:
            if m.measure == "weber_fraction":
                rows.append([ALL_SUBJECTS, m.task, "", "", "", "", "", "", "n/a", _n(m.mean),
                             *map(_n, m.interval), "", self.task_trials(m.task)])
        return [write_csv(out / "two_interval.csv", COLUMNS, rows), _sidecar(out)]

    def sections(self) -> list[str]:
        lines = ["## Two intervals", "",
                 f"Per subject and standard: a {method_text()}. Where a subject's answers "
                 "cannot place the threshold, the table gives words (*below the lowest value "
                 "tested*, *above the highest value tested*, *not estimable*) with the one "
                 "bound they state. Across subjects: the mean of the subjects with a number, "
                 f"with the {interval_name(self.settings)}.", "",
                 markdown_row(["subject", "task", "standard", "threshold", "Weber fraction",
                               "75 % difference", "trials"]), "|---" * 7 + "|"]
        for f in self.fits:
            name, unit = parameter_and_unit(f.compared)
            lines.append(markdown_row([f.subject, f.task, f"{name} {f.standard:g} {unit}",
                                       estimate_text(f.threshold), estimate_text(f.weber),
                                       _n(f.difference_75), f.trials]))
        for m in self.across:
            if m.measure == "weber_fraction":
                lines.append(markdown_row([ALL_SUBJECTS, m.task, "", "",
                                           self.across_text(m), "",
                                           self.task_trials(m.task)]))
        notes = not_fitted_notes([(f.subject, f.task, f.fit, [("threshold", f.threshold)])
                                  for f in self.fits])
        return lines + [*notes, "", "[two_interval.csv](two_interval.csv); its columns and "
                        "the method: [two_interval.json](two_interval.json).", ""]

    def lines(self) -> list[str]:
        return [f"two intervals {m.task}: mean {m.measure} {_n(m.mean)} over "
                f"{len(m.per_subject)} subject(s)" for m in self.across
                if m.measure == "weber_fraction"]

    def captions(self) -> dict[str, str]:
        return {f"two_interval_{task}": self.caption(task)
                for task in self.tasks()}

    def caption(self, task: str) -> str:
        weber = next(m for m in self.across if m.task == task and m.measure == "weber_fraction")
        return (f"Two-interval discrimination, task {task}: per subject, the proportion of "
                f"trials naming the interval with the higher value at each difference from the "
                f"standard (dot area: trials) and its Bayesian Weibull fit at the posterior "
                f"medians, drawn where the answers place the threshold (guess rate 1/2, "
                f"dashed). Mean Weber fraction {number(weber.mean, 3)} over {len(weber.per_subject)} "
                f"subject(s) ({interval_name(self.settings)} in summary.md); "
                f"{self.task_trials(task)} trials. Counted: main trials with status ok.")

    def figures(self, out: Path) -> list[Path]:
        import numpy as np

        from pinarray.analysis.figures import OKABE_ITO, fitted_curves, plt, save

        drawn: list[Path] = []
        for task in self.tasks():
            fits = [f for f in self.fits if f.task == task]
            top = max(p.x for f in fits for p in f.points)
            figure, axes = plt.subplots(figsize=(5.6, 3.8))
            fitted_curves(axes, [(f.subject, f.points, f.fit, f.threshold) for f in fits],
                          np.linspace(1e-6, top * 1.1, 300))
            axes.axhline(0.5, color=OKABE_ITO["vermillion"], linestyle="--", linewidth=1.0)
            axes.set_xlabel(f"difference from the standard ({fits[0].unit})")
            axes.set_ylabel("proportion naming the higher interval")
            axes.set_title(f"Two intervals, task {task}", fontsize=9)
            drawn += save(figure, out / f"two_interval_{task}", self.caption(task))
        return drawn


def _sidecar(out: Path) -> Path:
    """``two_interval.json``: each column of the table described, with the fit's method."""
    unit = "the compared parameter's unit (column unit)"
    columns: dict[str, dict[str, object]] = {
        "subject": {"Description": f"the subject; {ALL_SUBJECTS}: the across-subject mean"},
        "task": {"Description": "the task"},
        "parameter": {"Description": "the parameter the intervals differ in"},
        "unit": {"Description": "its unit"},
        "standard": {"Description": "the standard's value", "Units": unit},
        "threshold": {"Description": "the difference threshold: " + method_text() + "; n/a "
                      "where the status gives words instead", "Units": unit},
        **bounds_columns("", unit),
        "status": {"Description": "whether the answers place the threshold (and so the "
                   "Weber fraction)", "Levels": THRESHOLD_WORDS},
        "weber_fraction": {"Description": "the threshold over the standard" + ACROSS_TEXT},
        **bounds_columns("weber_", "fraction of the standard"),
        "difference_75pct": {"Description": "the difference answered right 75 % of the time "
                             "by the function at the posterior medians; n/a where the "
                             "threshold is in words", "Units": unit},
        "n_trials": {"Description": "the counted trials behind the numbers"}}
    return write_sidecar(out / "two_interval.json", columns)


def two_intervals(trials: Sequence[LoadedTrial], context: Context) -> TwoIntervals:
    """The two-interval rows of ``trials`` (those that count), fitted per subject and across."""
    pairs: dict[tuple[str, str, str, float], list[tuple[float, bool]]] = {}
    for trial in trials:
        record = trial.record
        if isinstance(record, TwoIntervalRecord) and record.counts and record.correct is not None:
            key = (record.task, trial.subject, record.compared, record.standard)
            pairs.setdefault(key, []).append((abs(record.comparison - record.standard),
                                              record.correct))
    fits = tuple(IntervalFit(subject, task, compared, standard, found,
                             fit("weibull", found, GUESS, None))
                 for (task, subject, compared, standard), answered in sorted(pairs.items())
                 for found in [points(answered)])
    measures: list[AcrossMeasure] = []
    for task in sorted({f.task for f in fits}):
        mine = [f for f in fits if f.task == task]
        measures += [across(task, "weber_fraction", "", [(f.subject, f.weber.value) for f in mine],
                            context.settings),
                     across(task, "threshold", mine[0].unit,
                            [(f.subject, f.threshold.value) for f in mine], context.settings)]
    return TwoIntervals(fits, tuple(measures), context.settings)


class TwoIntervalAnalysis(AnalysisDefaults):
    """The two interval analysis (`pinarray.analysis.seam.ParadigmAnalysis`)."""

    name = "two_interval"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return two_intervals(trials, context)


ANALYSIS = TwoIntervalAnalysis()
