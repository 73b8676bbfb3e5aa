"""Temporal order's findings: the PSS and JND per subject, from a psychometric fit.

Over each subject's counted rows of a task (status ok, not practice), fixed and adaptive
alike: the proportion of answers naming pin A first (the pin the protocol lists first)
against the SOA (B's onset minus A's, ms), a Bayesian logistic from 0 to 1 (guess and lapse
rates stated as 0: a lapse would pull both ends alike, which the fit's one-sided lapse cannot
say; `pinarray.analysis.fits`). The **PSS** is its 50 % point, the posterior's median with
its credible interval; the **JND** half the distance between its 25 % and 75 % points,
``ln 3 / slope``: ln 3 over the slope's posterior median, its interval from the slope's.
Where the answers cannot place a value it is given in words, with the one bound they state.
Across subjects (subject ``all``): the mean of the subjects' values with the interval the
analysis's settings name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from pinarray.adaptive.posterior import SLOPE_LOG_SD, SLOPE_MEDIAN, SlopeStatus, ThresholdStatus
from pinarray.analysis.fits import (
    ACROSS_TEXT,
    COVERAGE_TEXT,
    NO_FIT,
    NOT_FITTED,
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
    placed,
    points,
    threshold_estimate,
    write_sidecar,
)
from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.seam import AnalysisDefaults, Context, Estimate, EstimateStatus, Findings
from pinarray.analysis.tables import ALL_SUBJECTS, number, write_csv
from pinarray.analysis.thresholds import NotFitted, interval_name
from pinarray.paradigms.temporal_order.rows import TemporalOrderRecord

GUESS, LAPSE = 0.0, 0.0
METHOD = (
    "Bayesian logistic fit, as the adaptive designs' (pinarray.adaptive.posterior), of the "
    "proportion naming pin A first against the SOA (B's onset minus A's), from 0 to 1 (guess "
    "and lapse rates 0): the PSS, its 50 % point, is the median of its posterior over a grid "
    "of PSS x slope (slope prior log-normal around {median:g} per quarter of the SOA range "
    "tested, sd {sd:g} of its log; PSS prior flat across the SOAs tested, falling off "
    "beyond), the interval its 95 % equal-tailed credible interval; the JND, half the "
    "distance between the 25 % and 75 % points (ln 3 / slope), is ln 3 over the slope's "
    "posterior median, its interval from the slope's 95 % credible interval")
# Checked once (issue 40's merge), not re-measured by `make bench`: 900 simulated subjects
# (PSS -30 to 30 ms, JND 20-60 ms, lapse rates 0-0.04, symmetric) running protocols/toj.yaml
# as tests/analysis/test_lab_analysis.py simulates them.
COVERAGE = ("of the PSS for 94.2 % of them (848 of 900), of the JND for 94.8 % (853 of 900)")
COLUMNS = ("subject", "task", "pins", "pss_ms", "pss_ci_low", "pss_ci_high", "pss_status",
           "jnd_ms", "jnd_ci_low", "jnd_ci_high", "jnd_status", "n_trials")


def method_text() -> str:
    """How the PSS and JND are made, in a sentence."""
    return (f"{METHOD.format(median=SLOPE_MEDIAN, sd=SLOPE_LOG_SD)}; "
            f"{COVERAGE_TEXT.format(measured=COVERAGE)}")


class JndStatus(StrEnum):
    """Whether the answers place the JND (the slope's `SlopeStatus`, said of the JND)."""

    ESTIMATED = "estimated"
    BELOW = "below what the answers resolve"
    ABOVE = "above what the answers resolve"
    NOT_ESTIMABLE = "not estimable"


# The PSS where the JND has no upper bound: words, no number (issue 46: coin flips gave an
# "estimated" PSS beside a JND "above what the answers resolve").
PSS_UNRESOLVED = "not resolved: the answers may not follow the SOA (JND unbounded above)"
_JND_WORDS = {SlopeStatus.ESTIMATED: JndStatus.ESTIMATED, SlopeStatus.STEEPER: JndStatus.BELOW,
              SlopeStatus.SHALLOWER: JndStatus.ABOVE,
              SlopeStatus.NOT_ESTIMABLE: JndStatus.NOT_ESTIMABLE}
_JND_UNBOUNDED = frozenset({JndStatus.ABOVE.value, JndStatus.NOT_ESTIMABLE.value})


@dataclass(frozen=True)
class OrderFit:
    """One subject's temporal-order judgements of ``pins`` (A, B)."""

    subject: str
    task: str
    pins: tuple[int, ...]
    points: tuple[Point, ...]  # x: the SOA in ms, B's onset minus A's
    fit: Fit

    @property
    def trials(self) -> int:
        return sum(p.trials for p in self.points)

    def reported(self) -> tuple[tuple[str, str, Estimate], ...]:
        return (("pss_ms", "ms", self.pss), ("jnd_ms", "ms", self.jnd))

    @property
    def pss(self) -> Estimate:
        """The point of subjective simultaneity (ms) and its interval; not resolved where the
        answers do not show that they follow the SOA at all (the JND has no upper bound: a
        flat function has no 50 % point, and coin flips would place one anywhere)."""
        if self.jnd.words in _JND_UNBOUNDED:
            return Estimate(math.nan, math.nan, math.nan, EstimateStatus.NOT_RESOLVED,
                            PSS_UNRESOLVED)
        return threshold_estimate(self.fit)

    @property
    def jnd(self) -> Estimate:
        """Half the distance between the 25 % and 75 % points (ms) and its interval."""
        if isinstance(self.fit, NotFitted):
            return NO_FIT
        ln3 = math.log(3)
        status = _JND_WORDS[self.fit.slope_status]
        return placed(ln3 / self.fit.slope, ln3 / self.fit.slope_ci_high,
                      ln3 / self.fit.slope_ci_low,
                      has_low=status in (JndStatus.ESTIMATED, JndStatus.ABOVE),
                      has_high=status in (JndStatus.ESTIMATED, JndStatus.BELOW),
                      words=status.value)


def _n(value: float, digits: int = 3) -> str:
    return number(value, digits)


@dataclass(frozen=True)
class TemporalOrders(FittedFindings):
    """Every subject's temporal-order fits and their across-subject means (`Findings`)."""

    fits: tuple[OrderFit, ...]
    paradigm: str = "temporal_order"

    def counted(self) -> str:
        return f"{self.trials} temporal-order trials"

    def tables(self, out: Path) -> list[Path]:
        """``temporal_order.csv``: each subject's row, then the across-subject means (subject
        ``all``, the interval the settings name); and its sidecar ``temporal_order.json``."""
        rows: list[list[object]] = [
            [f.subject, f.task, " ".join(map(str, f.pins)), *map(_n, f.pss.numbers),
             f.pss.words, *map(_n, f.jnd.numbers), f.jnd.words, f.trials] for f in self.fits]
        for task in self.tasks():
            measures = self.measures_of(task)
            pss, jnd = measures["pss_ms"], measures["jnd_ms"]
            rows.append([ALL_SUBJECTS, task, "", _n(pss.mean), *map(_n, pss.interval), "n/a",
                         _n(jnd.mean), *map(_n, jnd.interval), "n/a", self.task_trials(task)])
        return [write_csv(out / "temporal_order.csv", COLUMNS, rows), _sidecar(out)]

    def sections(self) -> list[str]:
        lines = ["## Temporal order", "",
                 f"Per subject: a {method_text()}. Pin A is the first the protocol lists. Where "
                 "a subject's answers cannot place the PSS or the JND, the table gives words "
                 "with the one bound they state. Across subjects: the mean of the subjects "
                 f"with a number, with the {interval_name(self.settings)}.", "",
                 markdown_row(["subject", "task", "pins (A B)", "PSS (ms)", "JND (ms)",
                               "trials"]), "|---" * 6 + "|"]
        for f in self.fits:
            lines.append(markdown_row([f.subject, f.task, " ".join(map(str, f.pins)),
                                       estimate_text(f.pss, 1), estimate_text(f.jnd, 1),
                                       f.trials]))
        for task in self.tasks():
            measures = self.measures_of(task)
            pss, jnd = measures["pss_ms"], measures["jnd_ms"]
            lines.append(markdown_row([ALL_SUBJECTS, task, "",
                                       self.across_text(pss, 1),
                                       self.across_text(jnd, 1),
                                       self.task_trials(task)]))
        notes = not_fitted_notes([(f.subject, f.task, f.fit, [("PSS", f.pss), ("JND", f.jnd)])
                                  for f in self.fits])
        return lines + [*notes, "", "[temporal_order.csv](temporal_order.csv); its columns and "
                        "the method: [temporal_order.json](temporal_order.json).", ""]

    def lines(self) -> list[str]:
        return [f"temporal order {m.task}: mean {m.measure} {_n(m.mean)} over "
                f"{len(m.per_subject)} subject(s)" for m in self.across]

    def captions(self) -> dict[str, str]:
        return {f"temporal_order_{task}": self.caption(task)
                for task in self.tasks()}

    def caption(self, task: str) -> str:
        fits = [f for f in self.fits if f.task == task]
        measures = self.measures_of(task)
        return (f"Temporal-order judgement, task {task}: per subject, the proportion of trials "
                f"naming pin A ({fits[0].pins[0]}) first at each SOA (dot area: trials) and its "
                f"Bayesian logistic fit (guess and lapse rates 0) at the posterior medians, drawn "
                f"where the answers place the PSS. Mean PSS {number(measures['pss_ms'].mean, 1)} ms over "
                f"{len(measures['pss_ms'].per_subject)} subject(s), mean JND "
                f"{number(measures['jnd_ms'].mean, 1)} ms over {len(measures['jnd_ms'].per_subject)} "
                f"subject(s) ({interval_name(self.settings)} in summary.md); "
                f"{self.task_trials(task)} trials. Counted: main trials with status ok.")

    def figures(self, out: Path) -> list[Path]:
        import numpy as np

        from pinarray.analysis.figures import fitted_curves, plt, save

        drawn: list[Path] = []
        for task in self.tasks():
            fits = [f for f in self.fits if f.task == task]
            reach = max(abs(p.x) for f in fits for p in f.points)
            figure, axes = plt.subplots(figsize=(5.6, 3.8))
            fitted_curves(axes, [(f.subject, f.points, f.fit, f.pss) for f in fits],
                          np.linspace(-reach * 1.1, reach * 1.1, 300))
            axes.axhline(0.5, color="0.6", linestyle=":", linewidth=0.8)
            axes.axvline(0.0, color="0.6", linestyle=":", linewidth=0.8)
            a, b = fits[0].pins[0], fits[0].pins[1]
            axes.set_xlabel(f"SOA (ms): pin {b}'s onset minus pin {a}'s")
            axes.set_ylabel(f"proportion naming pin {a} first")
            axes.set_title(f"Temporal order, task {task} (pins {a} and {b})", fontsize=9)
            drawn += save(figure, out / f"temporal_order_{task}", self.caption(task))
        return drawn


def _sidecar(out: Path) -> Path:
    """``temporal_order.json``: each column of the table described, with the fit's method."""
    jnd_words = {JndStatus.ESTIMATED.value: THRESHOLD_WORDS["estimated"],
                 JndStatus.BELOW.value: "the answers do not bound the slope from above (e.g. "
                 "every answer right at every SOA tested): only jnd_ci_high",
                 JndStatus.ABOVE.value: "the answers do not bound the slope from below (e.g. "
                 "answers at chance): only jnd_ci_low",
                 **{k: v for k, v in THRESHOLD_WORDS.items()
                    if k in (ThresholdStatus.NOT_ESTIMABLE.value, NOT_FITTED, "n/a")}}
    columns: dict[str, dict[str, object]] = {
        "subject": {"Description": f"the subject; {ALL_SUBJECTS}: the across-subject mean"},
        "task": {"Description": "the task"},
        "pins": {"Description": "pin A then pin B, as the protocol lists them"},
        "pss_ms": {"Description": "the point of subjective simultaneity, the SOA (B's onset "
                   "minus A's) at which pin A is named first half the time: " + method_text()
                   + "; n/a where pss_status gives words instead" + ACROSS_TEXT, "Units": "ms"},
        **bounds_columns("pss_", "ms"),
        "pss_status": {"Description": "whether the answers place the PSS",
                       "Levels": {**THRESHOLD_WORDS, PSS_UNRESOLVED: "the JND has no upper "
                                  "bound: the answers need not depend on the SOA, so no 50 % "
                                  "point is placed"}},
        "jnd_ms": {"Description": "the just noticeable difference: half the distance between "
                   "the SOAs at which pin A is named first 25 % and 75 % of the time; n/a where "
                   "jnd_status gives words instead" + ACROSS_TEXT, "Units": "ms"},
        **bounds_columns("jnd_", "ms"),
        "jnd_status": {"Description": "whether the answers place the JND", "Levels": jnd_words},
        "n_trials": {"Description": "the counted trials behind the numbers"}}
    return write_sidecar(out / "temporal_order.json", columns)


def temporal_orders(trials: Sequence[LoadedTrial], context: Context) -> TemporalOrders:
    """The temporal-order rows of ``trials`` (those that count), fitted per subject and across."""
    pairs: dict[tuple[str, str, tuple[int, ...]], list[tuple[float, bool]]] = {}
    for trial in trials:
        record = trial.record
        if (isinstance(record, TemporalOrderRecord) and record.counts
                and record.named_a_first is not None):
            pairs.setdefault((record.task, trial.subject, record.pins), []).append(
                (record.soa_ns / 1e6, record.named_a_first))
    fits = tuple(OrderFit(subject, task, pins, found, fit("logistic", found, GUESS, LAPSE))
                 for (task, subject, pins), answered in sorted(pairs.items())
                 for found in [points(answered)])
    measures: list[AcrossMeasure] = []
    for task in sorted({f.task for f in fits}):
        mine = [f for f in fits if f.task == task]
        measures += [across(task, "pss_ms", "ms", [(f.subject, f.pss.value) for f in mine],
                            context.settings),
                     across(task, "jnd_ms", "ms", [(f.subject, f.jnd.value) for f in mine],
                            context.settings)]
    return TemporalOrders(fits, tuple(measures), context.settings)


class TemporalOrderAnalysis(AnalysisDefaults):
    """The temporal order analysis (`pinarray.analysis.seam.ParadigmAnalysis`)."""

    name = "temporal_order"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return temporal_orders(trials, context)


ANALYSIS = TemporalOrderAnalysis()
