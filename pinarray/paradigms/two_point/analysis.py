"""Two-point discrimination's findings: the threshold distance per subject, from a fit.

Over each subject's counted rows of a task (status ok, not practice): the false-alarm rate,
"two" said of one pin, with its Wilson interval; and the proportion of "two" said of two pins
against their distance in mm (from the grid's pitch), fitted with a Bayesian Weibull whose
floor is that false-alarm rate and whose lapse rate is fitted (`pinarray.analysis.fits`). The
**threshold** is the fit's: the distance at which "two" has risen 1 - 1/e (63 %) of the way
from the false-alarm rate to 1 - lapse, the posterior's median with its 95 % credible
interval; where the answers cannot place it, words with the one bound they state. The
false-alarm rate is also given for each one-pin train, so that a lab roving the single pin's
stroke sees whether force told one from two. Across subjects (subject ``all``): the mean of
the subjects' values with the interval the analysis's settings name.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

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
from pinarray.analysis.seam import AnalysisDefaults, Context, Estimate, Findings
from pinarray.analysis.stats import Proportion
from pinarray.analysis.tables import ALL_SUBJECTS, number, write_csv
from pinarray.analysis.thresholds import NotFitted, interval_name
from pinarray.paradigms.two_point.rows import TwoPointRecord

# Checked once (issue 45's merge), not re-measured by `make bench`: 300 simulated subjects
# (thresholds 2-5 mm, false alarms 0-15 %, lapse rates 0-4 %) running protocols/two_point.yaml
# as tests/test_two_point.py simulates them; 3 more were below the lowest distance tested.
COVERAGE = "of the threshold for 94.3 % of those it placed (280 of 297)"
METHOD = ("Bayesian Weibull fit, as the adaptive designs' (pinarray.adaptive.posterior), of "
          "the proportion saying two of two pins against their distance (mm, from the grid's "
          "pitch), its floor the subject's false-alarm rate (two said of one pin), its lapse "
          "rate fitted: the threshold, the distance at which two has risen 63 % of the way "
          "from the floor to 1 - lapse, is the median of its posterior, the interval its 95 % "
          "equal-tailed credible interval; " + COVERAGE_TEXT.format(measured=COVERAGE))
COLUMNS = ("subject", "task", "threshold_mm", "ci_low", "ci_high", "status", "false_alarm",
           "false_alarm_ci_low", "false_alarm_ci_high", "one_pin_trials", "two_pin_trials",
           "n_trials")
STIMULUS_COLUMNS = ("task", "stimulus", "pins", "said_two", "trials", "pct", "ci_low_pct",
                    "ci_high_pct")
MOST_FALSE_ALARMS = 0.85  # a floor this high leaves a fit nothing to rise through


@dataclass(frozen=True)
class DistanceFit:
    """One subject's two-point answers of one task."""

    subject: str
    task: str
    one_pin: Proportion  # "two" said of one pin
    points: tuple[Point, ...]  # x: the distance in mm; hits: "two" said
    fit: Fit

    @property
    def trials(self) -> int:
        return self.one_pin.trials + sum(p.trials for p in self.points)

    @property
    def threshold(self) -> Estimate:
        """The threshold distance (mm) and its interval."""
        return threshold_estimate(self.fit)

    @property
    def false_alarm(self) -> Estimate:
        return self.one_pin.estimate

    def reported(self) -> tuple[tuple[str, str, Estimate], ...]:
        return (("threshold_mm", "mm", self.threshold), ("false_alarm", "", self.false_alarm))


def _n(value: float, digits: int = 3) -> str:
    return number(value, digits)


@dataclass(frozen=True)
class TwoPoints(FittedFindings):
    """Every subject's two-point fits, their across-subject means, and the false alarms of
    each one-pin train (`Findings`)."""

    fits: tuple[DistanceFit, ...]
    by_stimulus: tuple[tuple[str, str, Proportion], ...] = ()  # task, train, "two" of one pin
    paradigm: str = "two_point"

    def counted(self) -> str:
        return f"{self.trials} two-point trials"

    def tables(self, out: Path) -> list[Path]:
        """``two_point.csv``: each subject's row, then the across-subject means (subject
        ``all``); ``two_point_stimuli.csv``: "two" said of one pin, by train; their sidecar."""
        rows: list[list[object]] = [
            [f.subject, f.task, *map(_n, f.threshold.numbers), f.threshold.words,
             *map(_n, f.false_alarm.numbers), f.one_pin.trials,
             f.trials - f.one_pin.trials, f.trials] for f in self.fits]
        for task in self.tasks():
            measures = self.measures_of(task)
            threshold, false_alarm = measures["threshold_mm"], measures["false_alarm"]
            rows.append([ALL_SUBJECTS, task, _n(threshold.mean), *map(_n, threshold.interval),
                         "n/a", _n(false_alarm.mean), *map(_n, false_alarm.interval), "", "",
                         self.task_trials(task)])
        stimuli = [[task, stimulus, "one", said.successes, said.trials, _n(said.pct, 1),
                    *(_n(v, 1) for v in said.interval_pct)]
                   for task, stimulus, said in self.by_stimulus]
        return [write_csv(out / "two_point.csv", COLUMNS, rows),
                write_csv(out / "two_point_stimuli.csv", STIMULUS_COLUMNS, stimuli),
                _sidecar(out)]

    def sections(self) -> list[str]:
        lines = ["## Two points", "",
                 f"Per subject: a {METHOD}. Where a subject's answers cannot place the "
                 "threshold, the table gives words with the one bound they state. Across "
                 f"subjects: the mean of the subjects with a number, with the "
                 f"{interval_name(self.settings)}.", "",
                 markdown_row(["subject", "task", "threshold (mm)", "two said of one pin",
                               "trials"]), "|---" * 5 + "|"]
        for f in self.fits:
            lines.append(markdown_row([f.subject, f.task, estimate_text(f.threshold, 2),
                                       estimate_text(f.false_alarm, 2), f.trials]))
        for task in self.tasks():
            measures = self.measures_of(task)
            threshold, false_alarm = measures["threshold_mm"], measures["false_alarm"]
            lines.append(markdown_row([
                ALL_SUBJECTS, task,
                self.across_text(threshold, 2),
                self.across_text(false_alarm, 2),
                self.task_trials(task)]))
        notes = not_fitted_notes([(f.subject, f.task, f.fit, [("threshold", f.threshold)])
                                  for f in self.fits])
        if len({s for t, s, _ in self.by_stimulus}) > 1:
            notes += ["", "Two said of one pin, by train (a stronger single pin said two more "
                      "often is an intensity cue): " + "; ".join(
                          f"{task} {stimulus} {said.successes}/{said.trials}"
                          for task, stimulus, said in self.by_stimulus) + "."]
        return lines + [*notes, "", "[two_point.csv](two_point.csv), "
                        "[two_point_stimuli.csv](two_point_stimuli.csv); their columns and "
                        "the method: [two_point.json](two_point.json).", ""]

    def lines(self) -> list[str]:
        return [f"two points {m.task}: mean {m.measure} {_n(m.mean)} over "
                f"{len(m.per_subject)} subject(s)" for m in self.across]

    def captions(self) -> dict[str, str]:
        return {f"two_point_{task}": self.caption(task) for task in self.tasks()}

    def caption(self, task: str) -> str:
        threshold = self.measures_of(task)["threshold_mm"]
        return (f"Two-point discrimination, task {task}: per subject, the proportion of two-pin "
                f"trials answered two at each distance (dot area: trials; at 0 mm, one-pin "
                f"trials) and its Bayesian Weibull fit at the posterior medians, drawn where the "
                f"answers place the threshold. Mean threshold {number(threshold.mean, 2)} mm over "
                f"{len(threshold.per_subject)} subject(s) ({interval_name(self.settings)} in "
                f"summary.md); {self.task_trials(task)} trials. Counted: main trials with "
                f"status ok.")

    def figures(self, out: Path) -> list[Path]:
        import numpy as np

        from pinarray.analysis.figures import fitted_curves, plt, save

        drawn: list[Path] = []
        for task in self.tasks():
            fits = [f for f in self.fits if f.task == task]
            top = max((p.x for f in fits for p in f.points), default=1.0)
            figure, axes = plt.subplots(figsize=(5.6, 3.8))
            fitted_curves(axes, [(f.subject, (Point(0.0, f.one_pin.successes, f.one_pin.trials),
                                              *f.points) if f.one_pin.trials else f.points,
                                  f.fit, f.threshold) for f in fits],
                          np.linspace(1e-6, top * 1.1, 300))
            axes.set_xlabel("distance between the two pins (mm; 0: one pin)")
            axes.set_ylabel("proportion answered two")
            axes.set_title(f"Two points, task {task}", fontsize=9)
            drawn += save(figure, out / f"two_point_{task}", self.caption(task))
        return drawn


def _sidecar(out: Path) -> Path:
    """``two_point.json``: each column of both tables described, with the fit's method."""
    columns: dict[str, dict[str, object]] = {
        "subject": {"Description": f"the subject; {ALL_SUBJECTS}: the across-subject mean"},
        "task": {"Description": "the task"},
        "threshold_mm": {"Description": "the threshold distance: " + METHOD + "; n/a where the "
                         "status gives words instead" + ACROSS_TEXT, "Units": "mm"},
        **bounds_columns("", "mm"),
        "status": {"Description": "whether the answers place the threshold",
                   "Levels": THRESHOLD_WORDS},
        "false_alarm": {"Description": "the share of one-pin trials answered two" + ACROSS_TEXT},
        "false_alarm_ci_low": {"Description": "its 95 % Wilson interval's lower end"},
        "false_alarm_ci_high": {"Description": "its 95 % Wilson interval's upper end"},
        "one_pin_trials": {"Description": "the counted one-pin trials"},
        "two_pin_trials": {"Description": "the counted two-pin trials"},
        "n_trials": {"Description": "the counted trials behind the numbers"},
        "two_point_stimuli.csv": {"Description": "for each task and one-pin train: two said "
                                  "of one pin (said_two of trials, pct with its 95 % Wilson "
                                  "interval), pooled over subjects"}}
    return write_sidecar(out / "two_point.json", columns)


def two_points(trials: Sequence[LoadedTrial], context: Context) -> TwoPoints:
    """The two-point rows of ``trials`` (those that count), fitted per subject and across."""
    ones: dict[tuple[str, str], list[bool]] = {}
    twos: dict[tuple[str, str], list[tuple[float, bool]]] = {}
    stimuli: dict[tuple[str, str], list[bool]] = {}
    for trial in trials:
        record = trial.record
        if not (isinstance(record, TwoPointRecord) and record.counts
                and record.said_two is not None):
            continue
        key = (record.task, trial.subject)
        twos.setdefault(key, [])
        if len(record.pins) == 1:
            ones.setdefault(key, []).append(record.said_two)
            stimuli.setdefault((record.task, record.stimulus), []).append(record.said_two)
        else:
            twos[key].append((record.distance_mm, record.said_two))
    fits = []
    for (task, subject), answered in sorted(twos.items()):
        said = ones.get((task, subject), [])
        one_pin = Proportion(sum(said), len(said))
        floor = one_pin.successes / one_pin.trials if one_pin.trials else 0.0
        found = points(answered)
        fitted = (fit("weibull", found, floor, None) if floor < MOST_FALSE_ALARMS else NotFitted(
            f"two said of {one_pin.successes} of {one_pin.trials} one-pin trials: no rise "
            "left for the distance to explain"))
        fits.append(DistanceFit(subject, task, one_pin, found, fitted))
    measures: list[AcrossMeasure] = []
    for task in sorted({f.task for f in fits}):
        mine = [f for f in fits if f.task == task]
        measures += [across(task, "threshold_mm", "mm",
                            [(f.subject, f.threshold.value) for f in mine], context.settings),
                     across(task, "false_alarm", "",
                            [(f.subject, f.false_alarm.value) for f in mine], context.settings)]
    by_stimulus = tuple((task, stimulus, Proportion(sum(said), len(said)))
                        for (task, stimulus), said in sorted(stimuli.items()))
    return TwoPoints(tuple(fits), tuple(measures), context.settings, by_stimulus)


class TwoPointAnalysis(AnalysisDefaults):
    """The two-point analysis (`pinarray.analysis.seam.ParadigmAnalysis`)."""

    name = "two_point"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return two_points(trials, context)


ANALYSIS = TwoPointAnalysis()
