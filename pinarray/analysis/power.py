"""How many subjects does a protocol need? Whole simulated studies, analysed per subject.

Each simulated study draws N subjects from the observer's population (between-subject spread
included), lets each answer the protocol's main trials (practice left out), and analyses the
study with subjects as the unit, as `pinarray analyse` does. Over many studies per N this gives

- **power curves**: how often each of the seed's findings comes out (criteria below), with a
  95 % Wilson interval for the Monte-Carlo error;
- **precision**: the across-subject mean correct rate per frequency (averaged over studies,
  which checks the observer's calibration), its spread from study to study, and the average
  half-width of the 95 % t interval a study of N subjects would report.

The criteria are defined in `CRITERIA`: some are significance tests (two-sided at `ALPHA`,
subjects as the unit), the others descriptive findings about the across-subject means (how
often they come out in the seed's order; no test). The paired t-test of the highest against
the lowest frequency is named so, not "frequency effect": `pinarray analyse`'s frequency
effect is a mixed-effects logistic regression over every frequency, whose fit (tenths of a
second each, and only from 6 subjects) is too slow to repeat for thousands of simulated
studies.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pinarray.analysis.observer import ObserverModel, SimulatedObserver
from pinarray.analysis.stats import CATEGORIES, Proportion
from pinarray.analysis.subjects import t_interval
from pinarray.grid import Grid
from pinarray.protocol import (
    Direction,
    LocalisationCondition,
    MotionAnswer,
    MotionCondition,
    Protocol,
)

ALPHA = 0.05
# Measured on the 2-core machine this was written on: a simulated subject's answer, and the
# analysis of one study (its tests and means).
ANSWER_NS = 25_000
STUDY_NS = 8_000_000
TARGET_POWER = 0.8
PAIRED_FREQUENCY = "highest vs lowest frequency (paired t)"


@dataclass(frozen=True)
class Criterion:
    """What finding a criterion counts, and whether it is a significance test."""

    definition: str
    test: bool


CRITERIA = {
    PAIRED_FREQUENCY: Criterion(
        "paired t-test of each subject's correct % at the highest against the lowest "
        "frequency: p < 0.05 and higher at the highest. Not the frequency effect `pinarray "
        "analyse` reports (a mixed-effects logistic regression over every frequency): a "
        "different test, whose power is not simulated here", test=True),
    "rising means": Criterion("the across-subject mean correct % rises strictly from each "
                              "frequency to the next", test=False),
    "error A on top": Criterion("the across-subject mean % of error A exceeds B, C and D at "
                                "every frequency", test=False),
    "pin best": Criterion("the pin the model localises best (pin 4 by default) has the highest "
                          "across-subject mean correct % over all frequencies, strictly (no "
                          "tie)", test=False),
    "direction above chance": Criterion("one-sample t-test of each subject's direction-right % "
                                        "(of the wave trials felt) against 50 %: p < 0.05 and "
                                        "above", test=True),
    "motion felt more on waves": Criterion("paired t-test of each subject's felt % on wave "
                                           "against no-wave trials: p < 0.05 and higher on "
                                           "waves", test=True),
}


@dataclass(frozen=True)
class Design:
    """The main trials of a protocol, as the observer needs them."""

    localisation: tuple[tuple[int, float], ...]  # (pin, frequency_hz) per trial
    motion: tuple[Direction, ...]  # per trial: the wave's direction (none: the no-wave control)
    grid: Grid
    directions: tuple[Direction, ...] = (Direction.LEFT, Direction.RIGHT)  # a subject may name

    @property
    def frequencies_hz(self) -> tuple[float, ...]:
        return tuple(sorted({f for _, f in self.localisation}))

    @property
    def pins(self) -> tuple[int, ...]:
        return tuple(sorted({p for p, _ in self.localisation}))


def protocol_design(protocol: Protocol) -> Design:
    """The protocol's main trials (one plan; order does not matter to the observer)."""
    from pinarray.plan import make_plan

    localisation, motion = [], []
    for trial in make_plan(protocol, 0).trials:
        if trial.practice:
            continue
        condition = trial.condition
        if isinstance(condition, LocalisationCondition):
            localisation.append((condition.pin, float(condition.frequency_hz)))
        elif isinstance(condition, MotionCondition):
            motion.append(condition.direction)
    return Design(tuple(localisation), tuple(motion), protocol.device.grid,
                  protocol.design.directions)


@dataclass(frozen=True)
class SubjectCounts:
    """One simulated subject's answers, counted."""

    categories: np.ndarray  # [frequency index, category index] counts, `CATEGORIES` order
    pin_correct: np.ndarray  # [pin - 1]
    pin_trials: np.ndarray
    wave: int
    felt: int
    right: int
    no_wave: int
    no_wave_felt: int


def simulate_subject(design: Design, observer: SimulatedObserver) -> SubjectCounts:
    """Let one simulated subject answer every main trial of ``design``."""
    grid = design.grid
    frequencies = design.frequencies_hz
    categories = np.zeros((len(frequencies), len(CATEGORIES)), dtype=int)
    pin_correct = np.zeros(grid.pin_count, dtype=int)
    pin_trials = np.zeros(grid.pin_count, dtype=int)
    for pin, frequency_hz in design.localisation:
        answer = observer.respond_localisation(pin, frequency_hz)
        verdict = "none" if answer is None else grid.classify(pin, answer).value
        categories[frequencies.index(frequency_hz), CATEGORIES.index(verdict)] += 1
        pin_trials[pin - 1] += 1
        pin_correct[pin - 1] += verdict == "correct"
    wave = felt = right = no_wave = no_wave_felt = 0
    for direction in design.motion:
        said = observer.respond_motion(direction, design.directions)
        if direction == Direction.NONE:
            no_wave += 1
            no_wave_felt += said != MotionAnswer.NONE
        else:
            wave += 1
            felt += said != MotionAnswer.NONE
            right += said.value == direction.value  # named the way the wave went
    return SubjectCounts(categories, pin_correct, pin_trials, wave, felt, right, no_wave,
                         no_wave_felt)


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


def _significant_above(values: Sequence[float], against: float = 0.0) -> bool:
    p = t_test_p(values, against)
    return not math.isnan(p) and p < ALPHA and float(np.mean(values)) > against


@dataclass(frozen=True)
class StudyOutcome:
    """What one simulated study found: criterion -> found, and its subject-level means."""

    found: dict[str, bool]
    means_pct: dict[str, float]  # measure -> across-subject mean
    half_widths_pct: dict[str, float]  # measure -> t interval half-width


def analyse_study(design: Design, subjects: Sequence[SubjectCounts],
                  best_pin: int | None) -> StudyOutcome:
    """The criteria and precision measures of one study, subjects as the unit."""
    found: dict[str, bool] = {}
    means: dict[str, float] = {}
    widths: dict[str, float] = {}

    def record(name: str, values: Sequence[float]) -> None:
        means[name] = float(np.mean(values)) if len(values) else math.nan
        low, high = t_interval(values)
        widths[name] = (high - low) / 2

    frequencies = design.frequencies_hz
    if frequencies:
        counts = np.array([s.categories for s in subjects])  # subject x frequency x category
        shares = 100 * counts / counts.sum(axis=2, keepdims=True)
        correct = shares[:, :, 0]
        for i, f in enumerate(frequencies):
            record(f"correct at {f:g} Hz", correct[:, i])
        mean_correct = correct.mean(axis=0)
        if len(frequencies) > 1:
            found[PAIRED_FREQUENCY] = _significant_above(correct[:, -1] - correct[:, 0])
            found["rising means"] = bool(np.all(np.diff(mean_correct) > 0))
        errors = shares[:, :, 1:5].mean(axis=0)  # frequency x A..D
        found["error A on top"] = bool(np.all(errors[:, 0] > errors[:, 1:].max(axis=1)))
        if best_pin is not None:
            pin_trials = np.array([s.pin_trials for s in subjects])
            pin_correct = np.array([s.pin_correct for s in subjects])
            stimulated = pin_trials[0] > 0
            pin_means = (100 * pin_correct[:, stimulated] / pin_trials[:, stimulated]).mean(axis=0)
            pins = [int(p) + 1 for p in np.flatnonzero(stimulated)]
            top = pin_means.max()
            found[f"pin {best_pin} best"] = bool(
                pin_means[pins.index(best_pin)] == top and np.sum(pin_means == top) == 1)
    if design.motion:
        felt = [100 * s.felt / s.wave for s in subjects if s.wave]
        direction = [100 * s.right / s.felt for s in subjects if s.felt]
        record("motion felt", felt)
        record("direction right of felt", direction)
        found["direction above chance"] = _significant_above(direction, 50.0)
        paired = [100 * s.felt / s.wave - 100 * s.no_wave_felt / s.no_wave for s in subjects
                  if s.wave and s.no_wave]
        if paired:
            found["motion felt more on waves"] = _significant_above(paired)
    return StudyOutcome(found, means, widths)


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
    model: ObserverModel
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


def power_seconds(design: Design, subject_counts: Sequence[int], studies: int) -> float:
    """About how long `power_study` takes, s: `ANSWER_NS` per simulated answer and
    `STUDY_NS` per study analysed (measured on the 2-core machine this was written on)."""
    answers = studies * sum(subject_counts) * (len(design.localisation) + len(design.motion))
    return (answers * ANSWER_NS + studies * len(subject_counts) * STUDY_NS) / 1e9


def power_study(protocol: Protocol, model: ObserverModel, subject_counts: Sequence[int],
                studies: int, seed: int,
                progress: Callable[[int], object] = lambda done: None) -> PowerCurves:
    """Simulate ``studies`` studies for each number of subjects; one seed makes it repeatable.
    ``progress`` hears how many simulated subjects (of every study) are done after each study."""
    design = protocol_design(protocol)
    best_pin = None
    if design.localisation:
        accuracy = np.mean([model.expected_pin_accuracy(f).ravel()
                            for f in design.frequencies_hz], axis=0)
        best_pin = max(design.pins, key=lambda p: accuracy[p - 1])
    rng = np.random.default_rng(seed)
    points, precision = [], []
    done = 0
    for n in subject_counts:
        outcomes = []
        for _ in range(studies):
            outcomes.append(analyse_study(design, [
                simulate_subject(design, SimulatedObserver(model, rng)) for _ in range(n)],
                best_pin))
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
    return PowerCurves(protocol.name, model, studies, seed, tuple(points), tuple(precision))


def caption(curves: PowerCurves) -> str:
    tests = [c for c in curves.criteria if _criterion(c).test]
    descriptive = [c for c in curves.criteria if not _criterion(c).test]
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
            f"{curves.model.subject_sd_logit:g} logit units. {' '.join(kinds)} Criteria "
            f"defined in power.md. Dashed: {100 * TARGET_POWER:.0f} % power.")


def _criterion(name: str) -> Criterion:
    return CRITERIA["pin best" if name.startswith("pin ") else name]


def power_markdown(curves: PowerCurves, figure: str) -> str:
    """The power page: how it was simulated, the criteria, the table and the figure."""
    lines = [f"# How many subjects? Protocol '{curves.protocol}'", "",
             f"{curves.studies} simulated studies per number of subjects (seed {curves.seed}); "
             f"simulated subjects drawn from the observer population with a between-subject "
             f"SD of {curves.model.subject_sd_logit:g} logit units, calibrated on pins "
             f"{', '.join(map(str, curves.model.pins))}. Each study is analysed with subjects "
             "as the unit.", "", "## Criteria", ""]
    lines += [f"- **{c}** ({'test' if _criterion(c).test else 'descriptive, not a test'}): "
              f"{_criterion(c).definition}" for c in curves.criteria]
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
                             curves.model.subject_sd_logit])
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
