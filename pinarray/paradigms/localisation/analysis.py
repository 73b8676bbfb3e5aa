"""Localisation's findings: correct answers and error classes by frequency with subjects as the
unit, each pin's accuracy, the confusion matrix, chance levels, the frequency effect, and the
stroke each pin achieved; their tables, sections of ``summary.md``, printout and figures.

The counts are `pinarray.paradigms.localisation.stats`'; the frequency effect a mixed-effects
logistic regression (`frequency_effect`); the strokes are the rows' own (`strokes`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.power import PowerModel
from pinarray.analysis.seam import AnalysisDefaults, Context, Estimate, Findings, Reported
from pinarray.analysis.stats import Proportion
from pinarray.analysis.subjects import AcrossSubjects, IntervalMethod, IntervalSettings
from pinarray.analysis.tables import (
    ALL_SUBJECTS,
    interval_cells,
    interval_heads,
    interval_text,
    markdown_row,
    measure_cells,
    measure_header,
    measure_text,
    number,
    pooled_text,
    write_csv,
)
from pinarray.grid import Grid
from pinarray.journal.records import TrialRecord
from pinarray.paradigms.localisation.frequency_effect import (
    Cell,
    FitSkipped,
    FrequencyEffect,
    fit_frequency_effect,
)
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.paradigms.localisation.stats import (
    CATEGORIES,
    CATEGORY_LABELS,
    LocalisationChance,
    SubjectLevel,
    Summary,
    localisation_chance,
    subject_level,
    summarise,
    summarise_subjects,
)
from pinarray.paradigms.localisation.strokes import StrokeTable, stroke_table
from pinarray.protocol.model import Protocol

COUNTED = "Counted: main trials with status ok."
STROKE_COLUMNS = ("pin", "frequency_hz", "stroke_commanded_steps", "stroke_commanded_mm",
                  "achieved_min_steps", "achieved_median_steps", "achieved_max_steps",
                  "achieved_min_mm", "achieved_median_mm", "achieved_max_mm",
                  "achieved_min_pct_of_commanded", "achieved_median_pct_of_commanded",
                  "n_trials", "n_short")
FIGURES = ("correct_by_frequency", "error_types", "confusion_matrix", "pin_accuracy")


def share_estimate(m: AcrossSubjects, method: IntervalMethod) -> Estimate:
    """An across-subject percentage as an estimate (its interval NaN with one subject)."""
    low, high = m.interval_pct(method)
    return Estimate.of(m.mean_pct, low, high)


@dataclass(frozen=True)
class Localisations:
    """What localisation rows show (`pinarray.analysis.seam.Findings`)."""

    pooled: Summary
    per_subject: tuple[Summary, ...]
    level: SubjectLevel
    chance: LocalisationChance | None
    frequency_effect: FrequencyEffect | FitSkipped
    strokes: StrokeTable
    grid: Grid
    paradigm: str = "localisation"

    @property
    def settings(self) -> IntervalSettings:
        return self.level.settings

    @property
    def trials(self) -> int:
        return sum(r.trials for r in self.pooled.localisation)

    @property
    def estimates(self) -> tuple[Reported, ...]:
        method = self.settings.method
        found = [Reported("", s.subjects[0], f"correct_pct_{r.frequency_hz:g}hz", "%", r.trials,
                          Estimate.of(r.correct.pct))
                 for s in self.per_subject for r in s.localisation]
        found += [Reported("", ALL_SUBJECTS, f"correct_pct_{r.frequency_hz:g}hz", "%",
                           r.share("correct").trials, share_estimate(r.share("correct"), method))
                  for r in self.level.localisation]
        return tuple(found)

    def counted(self) -> str:
        return f"{self.trials} localisation trials"

    def methods(self) -> list[str]:
        lines = ["- Localisation answers fall into correct, error A-D or **nothing felt**; every "
                 "percentage is of all trials, nothing felt included."]
        if self.chance:
            lines.append(f"- **Chance**: {self.chance.definition()}; the chance of each error "
                         "class is the share of nameable pins in that class, averaged over the "
                         "stimulated pins "
                         f"({', '.join(map(str, self.chance.stimulated_pins))}).")
        if self.pooled.localisation:
            lines.append("- **Frequency effect**: mixed-effects logistic regression, "
                         "correct ~ log2(frequency) + (1 | subject), fitted by maximum "
                         "likelihood (adaptive Gauss-Hermite quadrature); nothing felt counts "
                         "as not correct.")
        return lines

    # -- tables ------------------------------------------------------------------------------

    def tables(self, out: Path) -> list[Path]:
        tables = []
        if self.pooled.localisation:
            tables += self._localisation_tables(out)
            tables.append(self._frequency_effect_table(out))
        if self.strokes.rows:
            tables.append(self._stroke_table(out))
        return tables

    def _localisation_tables(self, out: Path) -> list[Path]:
        level, settings = self.level, self.settings
        chance = self.chance.fractions if self.chance else {}
        means = [[f"{r.frequency_hz:g}", category, *measure_cells(r.share(category), settings),
                  number(100 * chance[category], 2) if category in chance else "n/a"]
                 for r in level.localisation for category in CATEGORIES]
        per_subject = [[s.subjects[0], f"{r.frequency_hz:g}", r.trials,
                        *(r.count(c) for c in CATEGORIES),
                        *(number(r.share(c).pct) for c in CATEGORIES)]
                       for s in self.per_subject for r in s.localisation]
        grid = self.grid
        pins = []
        for pin in grid.pins:
            at_row, column = grid.cell(pin)
            pins.append([pin, at_row + 1, column + 1,
                         *measure_cells(level.pins[pin - 1], settings)])
        confusion = self.pooled.confusion
        answers = [f"answer_{p}" for p in grid.pins] + ["nothing_felt"]
        return [
            write_csv(out / "localisation_subject_level.csv",
                      ["frequency_hz", "category", *measure_header(settings), "chance_pct"],
                      means),
            write_csv(out / "localisation_per_subject.csv",
                      ["subject", "frequency_hz", "trials", *CATEGORIES,
                       *(f"{c}_pct" for c in CATEGORIES)], per_subject),
            write_csv(out / "pin_accuracy.csv",
                      ["pin", "row", "column", *measure_header(settings)], pins),
            write_csv(out / "confusion_matrix.csv", ["stimulated_pin", *answers, "trials"],
                      [[pin, *confusion[pin - 1], int(confusion[pin - 1].sum())]
                       for pin in grid.pins if confusion[pin - 1].sum()]),
        ]

    def _frequency_effect_table(self, out: Path) -> Path:
        header = ["model", "status", "subjects", "trials", "odds_ratio_per_doubling",
                  "odds_ratio_wald95_low", "odds_ratio_wald95_high", "slope_logit_per_doubling",
                  "slope_se", "subject_sd_logit", "lrt_chi2", "lrt_p", "wald_p",
                  "log_likelihood", "typical_subject_pct_by_frequency", "note"]
        model = ("correct ~ log2(frequency) + (1 | subject), binomial logit, adaptive "
                 "Gauss-Hermite ML")
        match self.frequency_effect:
            case FrequencyEffect() as effect:
                low, high = effect.odds_ratio_interval
                typical = "; ".join(f"{f:g} Hz {p:.1f}" for f, p in
                                    zip(effect.frequencies_hz, effect.typical_subject_pct,
                                        strict=True))
                cells = [model, "fitted" if effect.converged else "fitted, not converged",
                         effect.subjects, effect.trials, number(effect.odds_ratio_per_doubling, 3),
                         number(low, 3), number(high, 3), number(effect.slope_per_doubling, 4),
                         number(effect.slope_se, 4), number(effect.subject_sd_logit, 4),
                         number(effect.lrt_statistic, 3), f"{effect.lrt_p:.3g}",
                         f"{effect.wald_p:.3g}", number(effect.log_likelihood, 3), typical, ""]
            case FitSkipped() as skipped:
                cells = [model, "not fitted", *["n/a"] * 13, skipped.reason]
        return write_csv(out / "frequency_effect.csv", header, [cells])

    def _stroke_table(self, out: Path) -> Path:
        return write_stroke_table(self.strokes, out)

    # -- the summary -------------------------------------------------------------------------

    def sections(self) -> list[str]:
        lines = self._localisation() if self.pooled.localisation else []
        return lines + self._strokes()

    def _localisation(self) -> list[str]:
        level, settings = self.level, self.settings
        method = settings.method
        chance = self.chance
        heads = interval_heads(settings)
        lines = ["## Localisation", "",
                 f"Correct localisation, mean of per-subject percentages with the "
                 f"{settings.describe()}:", "",
                 markdown_row(["frequency", "subjects", "trials", "correct (subject mean)", *heads,
                      "trial-pooled [Wilson 95 %]", "chance"]),
                 "|---" * (6 + len(heads)) + "|"]
        for r in level.localisation:
            m = r.share("correct")
            lines.append(markdown_row([f"{r.frequency_hz:g} Hz", m.subjects, m.trials,
                              f"{number(m.mean_pct)} %", *interval_cells(m, settings),
                              pooled_text(m.pooled),
                              f"{number(100 * chance.correct, 2) if chance else 'n/a'} %"]))
        lines += ["", f"Every answer category, mean of per-subject percentages "
                  f"[{settings.describe()}]:",
                  "", "| frequency | " + " | ".join(CATEGORY_LABELS[c] for c in CATEGORIES) + " |",
                  "|---" * (len(CATEGORIES) + 1) + "|"]
        for r in level.localisation:
            lines.append(f"| {r.frequency_hz:g} Hz | " + " | ".join(
                f"{number(r.share(c).mean_pct)} % {interval_text(r.share(c).interval_pct(method))}"
                for c in CATEGORIES) + " |")
        if chance:
            lines.append("| chance | " + " | ".join(
                f"{number(100 * chance.fractions[c], 2)} %" if c in chance.fractions else "-"
                for c in CATEGORIES) + " |")
        lines += ["", "Correct per subject (their own trials; each subject counts once in the "
                  "means above):", "",
                  "| subject | " + " | ".join(f"{r.frequency_hz:g} Hz" for r in level.localisation)
                  + " |", "|---" * (len(level.localisation) + 1) + "|"]
        for summary in self.per_subject:
            if summary.localisation:
                by_frequency = {r.frequency_hz: r.correct for r in summary.localisation}
                cells = [by_frequency.get(r.frequency_hz, Proportion(0, 0))
                         for r in level.localisation]
                lines.append(f"| {summary.subjects[0]} | " + " | ".join(
                    f"{number(p.pct)} % ({p.successes}/{p.trials})" if p.trials else "-"
                    for p in cells) + " |")
        effect = self.frequency_effect
        lines += ["", f"**Frequency effect** (test: mixed-effects logistic regression): "
                  f"{effect.describe()}."]
        if isinstance(effect, FrequencyEffect):
            lines.append("Model's correct rate for a typical subject (random effect 0): "
                         + ", ".join(f"{f:g} Hz {p:.1f} %" for f, p in
                                     zip(effect.frequencies_hz, effect.typical_subject_pct,
                                         strict=True)) + ".")
        stimulated = [(pin, m) for pin, m in enumerate(level.pins, start=1) if m.subjects]
        if stimulated:
            top = max(m.mean_pct for _, m in stimulated)
            best = [str(pin) for pin, m in stimulated if m.mean_pct == top]
            lines.append(f"Best localised pin(s), mean of per-subject percentages over all "
                         f"frequencies (descriptive, not a test): {', '.join(best)} "
                         f"({number(top)} %).")
        return lines + [""]

    def _strokes(self) -> list[str]:
        """The stimulus delivered: each pin's achieved stroke by frequency, or why there is
        none."""
        strokes = self.strokes
        lines = ["## Stroke delivered", ""]
        if not strokes.measured:
            return lines + ["No stroke table: nothing was measured (results written before "
                            "the pins' motion was measured, or servos that report no "
                            "position).", ""]
        if strokes.rows:
            lines += ["Each pin's achieved stroke (a trial's smallest peak-to-peak over its "
                      "cycles) over the trials at each frequency, every measured localisation "
                      "row of the counted runs (practice and invalid rows included):", "",
                      markdown_row(["pin", "frequency", "commanded", "achieved min / median / max",
                           "median % of commanded", "trials", "short"]), "|---" * 7 + "|"]
            for r in strokes.rows:
                mm = "" if r.mm_per_step is None else f" ({r.mm(r.commanded_steps):.2f} mm)"
                lines.append(markdown_row([r.pin, f"{r.frequency_hz:g} Hz",
                                  f"{r.commanded_steps} steps{mm}",
                                  f"{r.achieved_min_steps} / {r.achieved_median_steps:g} / "
                                  f"{r.achieved_max_steps} steps",
                                  f"{number(r.share_pct(r.achieved_median_steps))} %",
                                  r.n_trials, r.n_short]))
            lines += ["", "In steps and mm: [stroke_by_frequency.csv](stroke_by_frequency.csv)."]
        if strokes.not_measured:
            lines += ["", f"- {strokes.not_measured} localisation trial(s) sampled too sparsely "
                          "to judge a cycle are left out."]
        return lines + [""]

    def lines(self) -> list[str]:
        level, settings = self.level, self.settings
        if not level.localisation:
            return []
        lines = [f"correct localisation, mean of per-subject % [{settings.describe()}]; "
                 "trial-pooled % [95 % Wilson]:"]
        for r in level.localisation:
            m = r.share("correct")
            low, high = m.pooled.interval_pct
            chance = f"; chance {100 * self.chance.correct:.2f} %" if self.chance else ""
            lines.append(f"  {r.frequency_hz:g} Hz: {measure_text(m, settings.method)}; "
                         f"trial-pooled {m.pooled.pct:.1f} % [{low:.1f}, {high:.1f}]{chance}")
        lines.append("frequency effect (mixed-effects logistic regression): "
                     f"{self.frequency_effect.describe()}")
        return lines

    # -- figures -----------------------------------------------------------------------------

    def captions(self) -> dict[str, str]:
        from pinarray.paradigms.localisation import figures

        found = {name: getattr(figures, f"{name}_caption")(self) for name in FIGURES
                 if self.pooled.localisation}
        if self.strokes.rows:
            found["stroke_by_frequency"] = figures.stroke_by_frequency_caption(self)
        return found

    def figures(self, out: Path) -> list[Path]:
        from pinarray.paradigms.localisation import figures

        drawn: list[Path] = []
        if self.pooled.localisation:
            for name in FIGURES:
                drawn += figures.FIGURES[name](self, out / name)
        if self.strokes.rows:
            drawn += figures.plot_stroke_by_frequency(self, out / "stroke_by_frequency")
        return drawn


def write_stroke_table(strokes: StrokeTable, out: Path) -> Path:
    """``stroke_by_frequency.csv``: each pin's achieved stroke (each trial's smallest
    peak-to-peak over its cycles) over the trials at each frequency, in steps, mm and % of
    the commanded stroke; ``n_short``: trials with a cycle below the stroke tolerance."""
    rows = []
    for r in strokes.rows:
        achieved = (r.achieved_min_steps, r.achieved_median_steps, r.achieved_max_steps)
        rows.append([r.pin, f"{r.frequency_hz:g}", r.commanded_steps,
                     number(r.mm(r.commanded_steps), 3), r.achieved_min_steps,
                     f"{r.achieved_median_steps:g}", r.achieved_max_steps,
                     *(number(r.mm(steps), 3) for steps in achieved),
                     number(r.share_pct(r.achieved_min_steps)),
                     number(r.share_pct(r.achieved_median_steps)), r.n_trials, r.n_short])
    return write_csv(out / "stroke_by_frequency.csv", STROKE_COLUMNS, rows)


def localisations(trials: Sequence[LoadedTrial], context: Context) -> Localisations:
    """What the localisation rows of ``trials`` show (the counted ones; strokes: every
    measured row of the included runs)."""
    grid = context.grid
    pooled, *per_subject = summarise_subjects(
        ((t.subject, t.record) for t in trials if isinstance(t.record, LocalisationRecord)),
        grid)
    stimulated = [pin for pin in grid.pins if pooled.pin_trials.flat[pin - 1]]
    chance = localisation_chance(stimulated, context.answer_pins, grid) if stimulated else None
    cells = [Cell(s.subjects[0], r.frequency_hz, r.correct.successes, r.trials)
             for s in per_subject for r in s.localisation]
    strokes = stroke_table((record, run.mm_per_step) for run in context.runs.included
                           for record in run.records)
    return Localisations(pooled, tuple(per_subject), subject_level(per_subject,
                                                                   context.settings),
                         chance, fit_frequency_effect(cells), strokes, grid)


class LocalisationAnalysis(AnalysisDefaults):
    """The localisation analysis (`pinarray.analysis.seam.ParadigmAnalysis`)."""

    name = "localisation"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return localisations(trials, context)

    def power(self, protocol: Protocol, model: str) -> PowerModel:
        from pinarray.paradigms.localisation.observer import parse_observer
        from pinarray.paradigms.localisation.power import power

        return power(protocol, parse_observer(model).for_protocol(protocol))

    def session_lines(self, records: Sequence[TrialRecord]) -> list[str]:
        lines = []
        for r in summarise(list(records), group="session").localisation:
            low, high = r.correct.interval_pct
            errors = ", ".join(f"{c} {r.error_pct(c):.0f} %" for c in "ABCD")
            if r.none_felt:  # its own category, shown whenever it happened
                errors += f", nothing felt {r.share('none').pct:.0f} %"
            lines.append(f"{r.frequency_hz:g} Hz: {r.correct.pct:.1f} % correct "
                         f"({r.correct.successes}/{r.trials}, 95 % CI {low:.0f}-{high:.0f} %); "
                         f"{errors}")
        return lines


ANALYSIS = LocalisationAnalysis()
