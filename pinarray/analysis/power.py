"""How many subjects does a protocol need? Whole simulated studies, analysed per subject.

Each simulated study draws N subjects from the observer's population (between-subject spread
included), lets each answer the protocol's main trials (practice left out), and analyses the
study with subjects as the unit, as `pinarray analyse` does. Over many studies per N this gives

- **power curves**: how often each of the paradigm's findings comes out (its criteria), with a
  95 % Wilson interval for the Monte-Carlo error;
- **precision**: each across-subject mean (averaged over studies, which checks the observer's
  calibration), its spread from study to study, and the average half-width of the 95 % t
  interval a study of N subjects would report.

What a simulated subject answers and which findings count is the paradigm's
(`PowerModel`, from its room: `pinarray.analysis.seam.ParadigmAnalysis.power`): some criteria
are significance tests (two-sided at `ALPHA`, subjects as the unit), the others descriptive
findings about the across-subject means (how often they come out so; no test).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from pinarray.analysis.stats import Proportion
from pinarray.analysis.subjects import t_interval

ALPHA = 0.05
# Measured on the 2-core machine this was written on: a simulated subject's answer, and the
# analysis of one study (its tests and means).
ANSWER_NS = 25_000
STUDY_NS = 8_000_000
TARGET_POWER = 0.8


@dataclass(frozen=True)
class Criterion:
    """What finding a criterion counts, and whether it is a significance test."""

    definition: str
    test: bool


@runtime_checkable
class PowerModel(Protocol):
    """A paradigm's simulated studies of one protocol: its subjects and its criteria.

    Attributes
    ----------
    criteria : mapping of str to Criterion
        Every finding a study may show, by name (a name may end in a detail, e.g. ``pin 4
        best``: `criterion` finds its definition by the words before).
    answers : int
        Main trials one simulated subject answers.
    subject_sd : float
        How much simulated subjects differ (logit units), as the caption says it.
    """

    @property
    def criteria(self) -> Mapping[str, Criterion]: ...

    @property
    def answers(self) -> int: ...

    @property
    def subject_sd(self) -> float: ...

    def described(self) -> str:
        """How its subjects are drawn, after "simulated subjects drawn from the observer
        population with..." (one clause)."""
        ...

    def subject(self, rng: np.random.Generator) -> object:
        """One simulated subject's answers to the protocol's main trials, counted."""
        ...

    def study(self, subjects: Sequence[object]) -> StudyOutcome:
        """What one study of ``subjects`` finds."""
        ...


def t_test_p(values: Sequence[float], against: float = 0.0) -> float:
    """Two-sided p of a one-sample t-test of ``values`` against ``against``; NaN if n < 2."""
    from scipy.special import stdtr

    data = np.asarray(values, dtype=float) - against
    n = len(data)
    if n < 2:
        return math.nan
    sd = float(data.std(ddof=1))
    mean = float(data.mean())
    if sd == 0:
        return 1.0 if mean == 0 else 0.0
    t = mean / (sd / math.sqrt(n))
    return float(2 * stdtr(n - 1, -abs(t)))


def significant_above(values: Sequence[float], against: float = 0.0) -> bool:
    """Whether a two-sided t-test finds ``values`` above ``against`` at `ALPHA`."""
    p = t_test_p(values, against)
    return not math.isnan(p) and p < ALPHA and float(np.mean(values)) > against


@dataclass(frozen=True)
class StudyOutcome:
    """What one simulated study found: criterion -> found, and its subject-level means."""

    found: dict[str, bool] = field(default_factory=dict)
    means_pct: dict[str, float] = field(default_factory=dict)  # measure -> across-subject mean
    half_widths_pct: dict[str, float] = field(default_factory=dict)  # t interval half-width

    def record(self, name: str, values: Sequence[float]) -> None:
        """The across-subject mean of ``values`` and its t interval's half-width, as ``name``."""
        self.means_pct[name] = float(np.mean(values)) if len(values) else math.nan
        low, high = t_interval(values)
        self.half_widths_pct[name] = (high - low) / 2


@dataclass(frozen=True)
class PowerPoint:
    """How often one criterion was met by studies of ``subjects`` subjects."""

    criterion: str
    subjects: int
    met: Proportion  # studies meeting it, of all studies


@dataclass(frozen=True)
class PrecisionPoint:
    """One measure over studies of ``subjects`` subjects, in percent."""

    measure: str
    subjects: int
    mean_pct: float  # the across-subject mean, averaged over studies
    sd_pct: float  # its standard deviation from study to study
    t_half_width_pct: float  # average half-width of a study's 95 % t interval


@dataclass(frozen=True)
class PowerCurves:
    """Power and precision per number of subjects, and how they were simulated."""

    protocol: str
    model: PowerModel
    studies: int
    seed: int
    points: tuple[PowerPoint, ...]
    precision: tuple[PrecisionPoint, ...]

    @property
    def criteria(self) -> list[str]:
        return list(dict.fromkeys(p.criterion for p in self.points))

    @property
    def subject_counts(self) -> list[int]:
        return sorted({p.subjects for p in self.points} | {p.subjects for p in self.precision})

    def enough_subjects(self, criterion: str) -> int | None:
        """The fewest subjects tried with power >= `TARGET_POWER` for ``criterion``."""
        for point in sorted(self.points, key=lambda p: p.subjects):
            if point.criterion == criterion and point.met.successes >= TARGET_POWER * point.met.trials:
                return point.subjects
        return None

    def table_lines(self) -> list[str]:
        counts = self.subject_counts
        width = max([len(c) for c in self.criteria] + [len(p.measure) for p in self.precision]
                    + [24])
        lines = [f"{'power (% of studies)':<{width}} " + " ".join(f"{n:>7}" for n in counts)
                 + "   >=80 % from"]
        for criterion in self.criteria:
            by_n = {p.subjects: p.met.pct for p in self.points if p.criterion == criterion}
            enough = self.enough_subjects(criterion)
            lines.append(f"{criterion:<{width}} "
                         + " ".join(f"{by_n.get(n, math.nan):>7.0f}" for n in counts)
                         + f"   {enough if enough else '-':>4}")
        measures = list(dict.fromkeys(p.measure for p in self.precision))
        if measures:
            lines += ["", "precision: mean of the across-subject means over studies (their SD "
                      "from study to study) [average 95 % t interval half-width], in %",
                      (f"{'subjects':>8}  " + "".join(f"{m:<26}" for m in measures)).rstrip()]
            cells = {(p.measure, p.subjects): p for p in self.precision}
            for n in counts:
                lines.append((f"{n:>8}  " + "".join(
                    f"{cells[m, n].mean_pct:5.1f} ({cells[m, n].sd_pct:4.1f}) "
                    f"[±{cells[m, n].t_half_width_pct:4.1f}]".ljust(26) if (m, n) in cells
                    else "-".ljust(26) for m in measures)).rstrip())
        return lines


def power_seconds(model: PowerModel, subject_counts: Sequence[int], studies: int) -> float:
    """About how long `power_study` takes, s: `ANSWER_NS` per simulated answer and
    `STUDY_NS` per study analysed (measured on the 2-core machine this was written on)."""
    answers = studies * sum(subject_counts) * model.answers
    return (answers * ANSWER_NS + studies * len(subject_counts) * STUDY_NS) / 1e9


def power_study(name: str, model: PowerModel, subject_counts: Sequence[int], studies: int,
                seed: int, progress: Callable[[int], object] = lambda done: None) -> PowerCurves:
    """Simulate ``studies`` studies of protocol ``name`` for each number of subjects; one seed
    makes it repeatable. ``progress`` hears how many simulated subjects (of every study) are
    done after each study."""
    rng = np.random.default_rng(seed)
    points, precision = [], []
    done = 0
    for n in subject_counts:
        outcomes = []
        for _ in range(studies):
            outcomes.append(model.study([model.subject(rng) for _ in range(n)]))
            done += n
            progress(done)
        for criterion in outcomes[0].found:
            met = sum(o.found.get(criterion, False) for o in outcomes)
            points.append(PowerPoint(criterion, n, Proportion(met, studies)))
        for measure in outcomes[0].means_pct:
            means = np.array([o.means_pct[measure] for o in outcomes])
            widths = np.array([o.half_widths_pct[measure] for o in outcomes])
            precision.append(PrecisionPoint(measure, n, float(np.nanmean(means)),
                                            float(np.nanstd(means, ddof=1)),
                                            float(np.nanmean(widths))
                                            if np.isfinite(widths).any() else math.nan))
    return PowerCurves(name, model, studies, seed, tuple(points), tuple(precision))


def caption(curves: PowerCurves) -> str:
    tests = [c for c in curves.criteria if _criterion(curves, c).test]
    descriptive = [c for c in curves.criteria if not _criterion(curves, c).test]
    kinds = []
    if tests:
        kinds.append(f"Tests, two-sided at p < {ALPHA:g} with subjects as the unit: "
                     f"{'; '.join(tests)}.")
    if descriptive:
        kinds.append(f"Descriptive findings, not tests (how often the across-subject means "
                     f"came out so): {'; '.join(descriptive)}.")
    return (f"Power to find each effect against the number of subjects, for protocol "
            f"'{curves.protocol}': share of {curves.studies} simulated studies per point "
            f"(seed {curves.seed}) in which it was found; shaded: 95 % Wilson interval of that "
            f"share (Monte-Carlo error). Simulated subjects differ with an SD of "
            f"{curves.model.subject_sd:g} logit units. {' '.join(kinds)} Criteria "
            f"defined in power.md. Dashed: {100 * TARGET_POWER:.0f} % power.")


def _criterion(curves: PowerCurves, name: str) -> Criterion:
    criteria = curves.model.criteria
    return criteria[name] if name in criteria else criteria[name.split()[0] + " best"]


def power_markdown(curves: PowerCurves, figure: str) -> str:
    """The power page: how it was simulated, the criteria, the table and the figure."""
    lines = [f"# How many subjects? Protocol '{curves.protocol}'", "",
             f"{curves.studies} simulated studies per number of subjects (seed {curves.seed}); "
             f"simulated subjects drawn from the observer population with "
             f"{curves.model.described()}. Each study is analysed with subjects as the unit.",
             "", "## Criteria", ""]
    kinds = {True: "test", False: "descriptive, not a test"}
    lines += [f"- **{c}** ({kinds[_criterion(curves, c).test]}): "
              f"{_criterion(curves, c).definition}" for c in curves.criteria]
    lines += ["", "## Results", "", "```", *curves.table_lines(), "```", "",
              f"![power curves]({figure})", "", f"*{caption(curves)}*", ""]
    return "\n".join(lines)


def write_power(curves: PowerCurves, out: Path) -> list[Path]:
    """power.md, power.csv, precision.csv and power_curves.png/.pdf in ``out``."""
    import csv

    from pinarray.analysis.plots import plot_power

    out.mkdir(parents=True, exist_ok=True)
    table = out / "power.csv"
    with open(table, "w", encoding="utf-8", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["criterion", "subjects", "studies", "met", "power_pct",
                         "mc_wilson95_low_pct", "mc_wilson95_high_pct", "seed",
                         "subject_sd_logit"])
        for p in curves.points:
            low, high = p.met.interval_pct
            writer.writerow([p.criterion, p.subjects, p.met.trials, p.met.successes,
                             f"{p.met.pct:.1f}", f"{low:.1f}", f"{high:.1f}", curves.seed,
                             curves.model.subject_sd])
    precision = out / "precision.csv"
    with open(precision, "w", encoding="utf-8", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["measure", "subjects", "studies", "mean_of_subject_means_pct",
                         "sd_across_studies_pct", "mean_t95_half_width_pct"])
        for q in curves.precision:
            writer.writerow([q.measure, q.subjects, curves.studies, f"{q.mean_pct:.2f}",
                             f"{q.sd_pct:.2f}", f"{q.t_half_width_pct:.2f}"])
    figures = plot_power(curves, out / "power_curves", caption(curves))
    page = out / "power.md"
    page.write_text(power_markdown(curves, figures[0].name), encoding="utf-8")
    return [page, table, precision, *figures]
