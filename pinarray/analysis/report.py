"""Write an analysis folder: CSV tables, figures (PNG and PDF), and ``summary.md`` linking them."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.adaptive.posterior import ThresholdPosterior, ThresholdStatus
from pinarray.analysis import captions
from pinarray.analysis.chance import DIRECTION_CHANCE
from pinarray.analysis.lab_report import lab_captions, lab_sections, lab_tables
from pinarray.analysis.load import RunSelection
from pinarray.analysis.mixed import FrequencyEffect
from pinarray.analysis.stats import CATEGORIES, CATEGORY_LABELS, Proportion
from pinarray.analysis.strokes import StrokeTable
from pinarray.analysis.study import Study
from pinarray.analysis.subjects import AcrossSubjects, IntervalMethod, IntervalSettings
from pinarray.analysis.tables import number, write_tables
from pinarray.analysis.thresholds import (
    ALL_SUBJECTS,
    NotFitted,
    Thresholds,
    fit_method_text,
    interval_name,
    parameter_and_unit,
    threshold_definition,
)


@dataclass(frozen=True)
class Report:
    """What `write_report` wrote."""

    summary: Path
    tables: tuple[Path, ...]
    figures: tuple[Path, ...]


def interval_text(interval: tuple[float, float]) -> str:
    low, high = interval
    return "n/a (one subject)" if math.isnan(low) else f"[{number(low)}, {number(high)}]"


def _pooled(p: Proportion) -> str:
    return f"{number(p.pct)} % {interval_text(p.interval_pct)} ({p.successes}/{p.trials})"


def measure_text(m: AcrossSubjects, method: IntervalMethod) -> str:
    """``mean % [interval] (N subjects, n trials)``, the chosen interval."""
    return (f"{number(m.mean_pct)} % {interval_text(m.interval_pct(method))} "
            f"({m.subjects} subj., {m.trials} trials)")


def _interval_heads(settings: IntervalSettings) -> list[str]:
    """The subject-level interval columns: the bootstrap, and the t interval if asked for."""
    t = ["t interval (may pass 0-100 %)"] if settings.method is IntervalMethod.T else []
    return [*t, "bootstrap interval"]


def _interval_cells(m: AcrossSubjects, settings: IntervalSettings) -> list[str]:
    t = [interval_text(m.t_interval_pct)] if settings.method is IntervalMethod.T else []
    return [*t, interval_text(m.bootstrap_interval_pct)]


def _row(cells: Sequence[object]) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def run_lines(runs: RunSelection) -> list[str]:
    """The runs left out and the runs counted with a caveat, one line each."""
    lines = []
    for run in runs.excluded:
        hint = "; --include-incomplete counts it" if run.counted else ""
        lines.append(f"left out: {run.label}: {run.incomplete_reason} "
                     f"({run.counted} counted trial(s)){hint}")
    for run in runs.incomplete_included:
        lines.append(f"counted on request: {run.label}: {run.incomplete_reason}")
    for run in runs.without_manifest:
        lines.append(f"counted without a manifest (completeness unknown): {run.label}")
    for run in runs.included:
        if run.duplicates:
            lines.append(f"{run.label}: trial(s) {', '.join(map(str, run.duplicates))} finished "
                         f"twice; the first ok row counts")
    return lines


def _methods(study: Study) -> list[str]:
    settings = study.subject_level.settings
    lines = ["## Methods", "",
             "- **Unit: the subject.** For every measure each subject's own percentage is "
             "computed; the tables give their mean across subjects with the "
             f"{settings.describe()}; figures draw it."
             + (f" The {settings.describe(IntervalMethod.BOOTSTRAP)} is given beside it."
                if settings.method is IntervalMethod.T else
                " A percentile bootstrap of few subjects is narrower than its nominal "
                "coverage; the t interval (`--interval t`) is not bounded by 0 and 100 %."),
             "- **Trial-pooled** numbers (every trial of every subject counted together, 95 % "
             "Wilson interval) are given beside them and labelled so: they treat trials as "
             "independent, which they are not when subjects differ, so their intervals are "
             "too narrow for claims about people.",
             "- Localisation answers fall into correct, error A-D or **nothing felt**; every "
             "percentage is of all trials, nothing felt included."]
    if study.chance:
        lines.append(f"- **Chance**: {study.chance.definition()}; the chance of each error class "
                     "is the share of nameable pins in that class, averaged over the "
                     "stimulated pins "
                     f"({', '.join(map(str, study.chance.stimulated_pins))}).")
    if study.motion_trials:
        lines.append(f"- Motion chance: direction right {100 * DIRECTION_CHANCE:.0f} % (left or "
                     "right named at random; 'unsure' counts as not right). Feeling motion has "
                     "no chance level; the no-wave trials are its false-alarm baseline.")
    if study.pooled.localisation:
        lines.append("- **Frequency effect**: mixed-effects logistic regression, "
                     "correct ~ log2(frequency) + (1 | subject), fitted by maximum likelihood "
                     "(adaptive Gauss-Hermite quadrature); nothing felt counts as not correct.")
    return lines + [""]


def _localisation(study: Study) -> list[str]:
    level = study.subject_level
    method = level.settings.method
    chance = study.chance
    lines = ["## Localisation", "",
             f"Correct localisation, mean of per-subject percentages with the "
             f"{level.settings.describe()}:", "",
             _row(["frequency", "subjects", "trials", "correct (subject mean)",
                   *_interval_heads(level.settings), "trial-pooled [Wilson 95 %]", "chance"]),
             "|---" * (6 + len(_interval_heads(level.settings))) + "|"]
    for row in level.localisation:
        m = row.share("correct")
        lines.append(_row([f"{row.frequency_hz:g} Hz", m.subjects, m.trials,
                           f"{number(m.mean_pct)} %", *_interval_cells(m, level.settings),
                           _pooled(m.pooled),
                           f"{number(100 * chance.correct, 2) if chance else 'n/a'} %"]))
    lines += ["", f"Every answer category, mean of per-subject percentages "
              f"[{level.settings.describe()}]:",
              "", "| frequency | " + " | ".join(CATEGORY_LABELS[c] for c in CATEGORIES) + " |",
              "|---" * (len(CATEGORIES) + 1) + "|"]
    for row in level.localisation:
        lines.append(f"| {row.frequency_hz:g} Hz | " + " | ".join(
            f"{number(row.share(c).mean_pct)} % {interval_text(row.share(c).interval_pct(method))}"
            for c in CATEGORIES) + " |")
    if chance:
        lines.append("| chance | " + " | ".join(
            f"{number(100 * chance.fractions[c], 2)} %" if c in chance.fractions else "-"
            for c in CATEGORIES) + " |")
    lines += ["", "Correct per subject (their own trials; each subject counts once in the means "
              "above):", "",
              "| subject | " + " | ".join(f"{r.frequency_hz:g} Hz" for r in level.localisation)
              + " |", "|---" * (len(level.localisation) + 1) + "|"]
    for summary in study.per_subject:
        if summary.localisation:
            by_frequency = {r.frequency_hz: r.correct for r in summary.localisation}
            cells = [by_frequency.get(r.frequency_hz, Proportion(0, 0))
                     for r in level.localisation]
            lines.append(f"| {summary.subjects[0]} | " + " | ".join(
                f"{number(p.pct)} % ({p.successes}/{p.trials})" if p.trials else "-"
                for p in cells) + " |")
    effect = study.frequency_effect
    lines += ["", f"**Frequency effect** (test: mixed-effects logistic regression): "
              f"{effect.describe()}."]
    if isinstance(effect, FrequencyEffect):
        lines.append("Model's correct rate for a typical subject (random effect 0): " + ", ".join(
            f"{f:g} Hz {p:.1f} %" for f, p in zip(effect.frequencies_hz,
                                                  effect.typical_subject_pct, strict=True)) + ".")
    stimulated = [(pin, m) for pin, m in enumerate(level.pins, start=1) if m.subjects]
    if stimulated:
        top = max(m.mean_pct for _, m in stimulated)
        best = [str(pin) for pin, m in stimulated if m.mean_pct == top]
        lines.append(f"Best localised pin(s), mean of per-subject percentages over all "
                     f"frequencies (descriptive, not a test): {', '.join(best)} "
                     f"({number(top)} %).")
    return lines + [""]


def _motion(study: Study) -> list[str]:
    level = study.subject_level
    motion = level.motion
    rows = [("felt a moving dot (wave trials)", motion.felt, "-"),
            ("direction right (of the wave trials felt)", motion.direction_right,
             f"{100 * DIRECTION_CHANCE:.0f} %"),
            ("felt motion on no-wave trials (false alarms)", motion.no_wave_felt, "-")]
    heads = _interval_heads(level.settings)
    lines = ["## Apparent motion", "",
             _row(["measure", "subjects", "trials", "subject mean", *heads,
                   "trial-pooled [Wilson 95 %]", "chance"]), "|---" * (6 + len(heads)) + "|"]
    for name, m, chance in rows:
        lines.append(_row([name, m.subjects, m.trials, f"{number(m.mean_pct)} %",
                           *_interval_cells(m, level.settings), _pooled(m.pooled), chance]))
    return lines + [""]


def _thresholds(found: Thresholds) -> list[str]:
    settings = found.settings
    lines = ["## Thresholds (adaptive procedures)", "",
             "- **Each procedure's own estimate**, from its last counted row: a staircase's "
             "mean of its last reversals (`reversal_mean`; n/a before its first reversal, no "
             "interval); QUEST+'s posterior mean with its 95 % credible interval "
             "(`questplus_posterior`). Catch trials move no procedure and are left out.",
             "- **Fit** per subject and task over every counted trial of its procedures "
             "pooled (`bayes_weibull`, or `bayes_logistic` where an intensity is 0 or below), "
             f"guess rate as the rows state it: a {fit_method_text()}. The threshold is "
             f"{threshold_definition('weibull', found.per_subject[0].guess_rate)} (each "
             "subject's lapse rate and percent correct at the threshold are in "
             "thresholds.csv). Where a subject's answers cannot place the threshold, the "
             "table gives words instead of a number: *below the lowest value tested*, *above "
             "the highest value tested* or *not estimable*.",
             f"- **Across subjects** (subject `{ALL_SUBJECTS}` in thresholds.csv): the mean of "
             f"the subjects' thresholds with the {interval_name(settings)}; a subject without an "
             "estimate is left out, a subject with several runs of a procedure counts once "
             "(the mean of their estimates).", "",
             _row(["task", "parameter", "unit", "method", "procedure", "subjects", "trials",
                   "subject mean", "interval"]), "|---" * 9 + "|"]
    for m in found.across:
        low, high = m.interval(settings.method)
        interval = ("n/a (fewer than two subjects)" if math.isnan(low)
                    else f"[{number(low, 3)}, {number(high, 3)}]")
        lines.append(_row([m.task, *parameter_and_unit(m.adapted_parameter), f"`{m.method}`",
                           m.procedure, m.subjects, m.n_trials, number(m.mean, 3), interval]))
    notes = []
    for s in found.per_subject:
        match s.fit:
            case NotFitted(reason=reason):
                notes.append(f"- subject {s.subject}, task {s.task}: no fit: {reason}")
            case ThresholdPosterior(status=ThresholdStatus.ESTIMATED):
                pass
            case fit:
                bound = {ThresholdStatus.BELOW: f" (below {number(fit.ci_high, 3)})",
                         ThresholdStatus.ABOVE: f" (above {number(fit.ci_low, 3)})"}
                notes.append(f"- subject {s.subject}, task {s.task}: threshold "
                             f"**{fit.status.value}**{bound.get(fit.status, '')}, tested "
                             f"{fit.lowest_tested:g}-{fit.highest_tested:g} {s.unit}; left out "
                             "of the across-subject mean")
    lines += ([""] + notes) if notes else []
    lines += ["", "Each subject's numbers: [thresholds.csv](thresholds.csv); its columns and "
              "the threshold's definition: [thresholds.json](thresholds.json).", ""]
    return lines


def _strokes(strokes: StrokeTable) -> list[str]:
    """The stimulus delivered: each pin's achieved stroke by frequency, or why there is none."""
    lines = ["## Stroke delivered", ""]
    if not strokes.measured:
        return lines + ["No stroke table: nothing was measured (results written before the "
                        "pins' motion was measured, or servos that report no position).", ""]
    if strokes.rows:
        lines += ["Each pin's achieved stroke (a trial's smallest peak-to-peak over its cycles) "
                  "over the trials at each frequency, every measured localisation row of the "
                  "counted runs (practice and invalid rows included):", "",
                  _row(["pin", "frequency", "commanded", "achieved min / median / max",
                        "median % of commanded", "trials", "short"]), "|---" * 7 + "|"]
        for r in strokes.rows:
            mm = "" if r.mm_per_step is None else f" ({r.mm(r.commanded_steps):.2f} mm)"
            lines.append(_row([r.pin, f"{r.frequency_hz:g} Hz", f"{r.commanded_steps} steps{mm}",
                               f"{r.achieved_min_steps} / {r.achieved_median_steps:g} / "
                               f"{r.achieved_max_steps} steps",
                               f"{number(r.share_pct(r.achieved_median_steps))} %", r.n_trials,
                               r.n_short]))
        lines += ["", "In steps and mm: [stroke_by_frequency.csv](stroke_by_frequency.csv)."]
    notes = []
    if strokes.motion_trials:
        notes.append(f"{strokes.motion_trials} trial(s) of waves, patterns, two intervals or "
                     "two pins with a measured stroke are not in the table: they have no single "
                     "pin and frequency (their strokes are in beh.tsv).")
    if strokes.not_measured:
        notes.append(f"{strokes.not_measured} localisation trial(s) sampled too sparsely to "
                     "judge a cycle are left out.")
    lines += ([""] + [f"- {note}" for note in notes]) if notes else []
    return lines + [""]


def _lab_trials(study: Study) -> str:
    """``, 28 identification trials``...: the lab's paradigms' counted trials, if any."""
    counts = {"identification": sum(s.confusion.trials
                                    for s in study.identification.per_subject),
              "two-interval": sum(f.trials for f in study.judgements.intervals),
              "temporal-order": sum(f.trials for f in study.judgements.orders)}
    return "".join(f", {n} {name} trials" for name, n in counts.items() if n)


def summary_markdown(study: Study, tables: Sequence[Path], figures: Sequence[Path],
                     figures_skipped: bool = False) -> str:
    """The report page: runs, methods, subject-level tables, figures with captions, links
    (``figures_skipped``: the analysis was asked for none, and the page says so)."""
    subjects = study.subjects
    runs = study.runs
    lines = ["# Pin-array results", "",
             f"{len(runs.included)} run(s) counted, {len(subjects)} subject(s): "
             f"{', '.join(subjects) or 'none'}; {study.localisation_trials} localisation and "
             f"{study.motion_trials} motion trials{_lab_trials(study)}. {captions.COUNTED} A "
             "trial finished twice in one run counts once.", ""]
    notes = run_lines(runs)
    lines += ["## Runs", ""] + ([f"- {line}" for line in notes] if notes else
                                ["- every run found is completed and counted"]) + [
        "", "All runs and why each was counted or left out: [runs.csv](runs.csv).", ""]
    lines += _methods(study)
    if study.pooled.localisation:
        lines += _localisation(study)
    if study.motion_trials:
        lines += _motion(study)
    if study.thresholds.found:
        lines += _thresholds(study.thresholds)
    settings = study.subject_level.settings
    lines += lab_sections(study.identification, study.judgements, settings)
    lines += _strokes(study.strokes)
    pngs = [p for p in figures if p.suffix == ".png"]
    if pngs:
        lines += ["## Figures", ""]
        threshold_captions = captions.threshold_captions(study.thresholds) | lab_captions(
            study.identification.across, study.judgements, settings)
        for n, png in enumerate(pngs, start=1):
            caption = (captions.CAPTIONS[png.stem](study) if png.stem in captions.CAPTIONS
                       else threshold_captions[png.stem])
            lines += [f"![{png.stem}]({png.name})", "",
                      f"*Figure {n}.* {caption} Vector: [{png.stem}.pdf]({png.stem}.pdf).", ""]
    elif figures_skipped:
        lines += ["## Figures", "", "Not drawn: analysed with `--no-figures`.", ""]
    lines += ["## Tables", ""] + [f"- [{p.name}]({p.name})" for p in tables] + [""]
    return "\n".join(lines)


def write_figures(study: Study, out: Path) -> list[Path]:
    """Each figure for which there are trials, as PNG and PDF."""
    from pinarray.analysis import plots

    drawn: list[Path] = []
    if study.pooled.localisation:
        for name in ("correct_by_frequency", "error_types", "confusion_matrix", "pin_accuracy"):
            drawn += plots.FIGURES[name](study, out / name)
    if study.motion_trials:
        drawn += plots.plot_motion(study, out / "motion")
    if study.strokes.rows:
        drawn += plots.plot_stroke_by_frequency(study, out / "stroke_by_frequency")
    for found in study.thresholds.per_subject:
        drawn += plots.plot_track(found, out / f"track_{found.stem}")
        drawn += plots.plot_fit(found, out / f"fit_{found.stem}")
    if study.identification.found or study.judgements.found:
        from pinarray.analysis.lab_plots import lab_figures

        drawn += lab_figures(study.identification.across, study.judgements,
                             study.subject_level.settings, out)
    return drawn


def write_report(study: Study, out: Path, figures: bool = True) -> Report:
    """Write tables, figures (unless ``figures`` is False) and ``summary.md`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    tables = write_tables(study, out)
    tables[-1:-1] = lab_tables(study.identification, study.judgements,
                               study.subject_level.settings, out)  # runs.csv stays last
    drawn = write_figures(study, out) if figures else []
    path = out / "summary.md"
    path.write_text(summary_markdown(study, tables, drawn, figures_skipped=not figures), encoding="utf-8")
    return Report(path, tuple(tables), tuple(drawn))
