"""Write an analysis folder: CSV tables, figures (PNG and PDF), and ``summary.md`` linking them.

The page is assembled here from every paradigm's findings (its room's sections, tables and
figures: `pinarray.analysis.seam.Findings`), the adaptive designs' thresholds, and
``estimates.csv``: every estimate of every paradigm, each with its status.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.adaptive.posterior import ThresholdPosterior, ThresholdStatus
from pinarray.analysis import captions
from pinarray.analysis.load import RunSelection, countable_on_request
from pinarray.analysis.study import Study
from pinarray.analysis.subjects import IntervalMethod
from pinarray.analysis.tables import markdown_row, number, significant, write_csv, write_tables
from pinarray.analysis.thresholds import (
    ALL_SUBJECTS,
    NotFitted,
    Thresholds,
    fit_method_text,
    interval_name,
    parameter_and_unit,
    threshold_definition,
)

ESTIMATE_COLUMNS = ("paradigm", "task", "subject", "measure", "unit", "value", "ci_low",
                    "ci_high", "status", "words", "n_trials")


@dataclass(frozen=True)
class Report:
    """What `write_report` wrote."""

    summary: Path
    tables: tuple[Path, ...]
    figures: tuple[Path, ...]


def run_lines(runs: RunSelection) -> list[str]:
    """The runs left out and the runs counted with a caveat, one line each."""
    lines = []
    for run in runs.excluded:
        hint = "; --include-incomplete counts it" if countable_on_request(run) else ""
        lines.append(f"left out: {run.label}: {run.incomplete_reason} "
                     f"({run.counted} counted trial(s)){hint}")
    for run in runs.incomplete_included:
        lines.append(f"counted on request: {run.label}: {run.incomplete_reason}")
    for run in runs.without_manifest:
        lines.append(f"counted without a manifest (completeness unknown): {run.label}")
    return lines


def _methods(study: Study) -> list[str]:
    settings = study.settings
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
             "- **Estimates** carry their status ([estimates.csv](estimates.csv)): estimated "
             "(a value), bounded (only the bound the answers state) or not resolved (the "
             "answers place it nowhere), with the words for it."]
    for found in study.findings:
        lines += found.methods()
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
             markdown_row(["task", "parameter", "unit", "method", "procedure", "subjects", "trials",
                   "subject mean", "interval"]), "|---" * 9 + "|"]
    for m in found.across:
        low, high = m.interval(settings.method)
        interval = ("n/a (fewer than two subjects)" if math.isnan(low)
                    else f"[{number(low, 3)}, {number(high, 3)}]")
        lines.append(markdown_row([m.task, *parameter_and_unit(m.adapted_parameter), f"`{m.method}`",
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
                             f"{significant(fit.lowest_tested, 6)}-{significant(fit.highest_tested, 6)} {s.unit}; left out "
                             "of the across-subject mean")
    lines += ([""] + notes) if notes else []
    lines += ["", "Each subject's numbers: [thresholds.csv](thresholds.csv); its columns and "
              "the threshold's definition: [thresholds.json](thresholds.json).", ""]
    return lines


def summary_markdown(study: Study, tables: Sequence[Path], figures: Sequence[Path],
                     figures_skipped: bool = False) -> str:
    """The report page: runs, methods, each paradigm's sections, thresholds, figures with
    captions, links (``figures_skipped``: the analysis was asked for none, and the page says
    so)."""
    subjects = study.subjects
    runs = study.runs
    counted = [f.counted() for f in study.findings]
    trials = (", ".join(counted[:-1]) + " and " + counted[-1] if len(counted) > 1
              else counted[0] if counted else "no trials")
    lines = ["# Pin-array results", "",
             f"{len(runs.included)} run(s) counted, {len(subjects)} subject(s): "
             f"{', '.join(subjects) or 'none'}; {trials}. {captions.COUNTED} A trial finished "
             "twice in one run counts once.", ""]
    notes = run_lines(runs)
    lines += ["## Runs", ""] + ([f"- {line}" for line in notes] if notes else
                                ["- every run found is completed and counted"]) + [
        "", "All runs and why each was counted or left out: [runs.csv](runs.csv).", ""]
    lines += _methods(study)
    for found in study.findings:
        lines += found.sections()
    if study.thresholds.found:
        lines += _thresholds(study.thresholds)
    pngs = [p for p in figures if p.suffix == ".png"]
    if pngs:
        lines += ["## Figures", ""]
        known = captions.threshold_captions(study.thresholds)
        for found in study.findings:
            known |= found.captions()
        for n, png in enumerate(pngs, start=1):
            lines += [f"![{png.stem}]({png.name})", "",
                      f"*Figure {n}.* {known[png.stem]} Vector: [{png.stem}.pdf]"
                      f"({png.stem}.pdf).", ""]
    elif figures_skipped:
        lines += ["## Figures", "", "Not drawn: analysed with `--no-figures`.", ""]
    lines += ["## Tables", ""] + [f"- [{p.name}]({p.name})" for p in tables] + [""]
    return "\n".join(lines)


def write_figures(study: Study, out: Path) -> list[Path]:
    """Each figure for which there are trials, as PNG and PDF."""
    from pinarray.analysis import plots
    from pinarray.analysis.figures import house_layout

    drawn: list[Path] = []
    with house_layout():
        for found in study.findings:
            drawn += found.figures(out)
        for subject in study.thresholds.per_subject:
            drawn += plots.plot_track(subject, out / f"track_{subject.stem}")
            drawn += plots.plot_fit(subject, out / f"fit_{subject.stem}")
    return drawn


def estimates_table(study: Study, out: Path) -> Path:
    """``estimates.csv``: every estimate of every paradigm, each subject's and the
    across-subject ones (subject ``all``), with its status and the words for it."""
    rows = [[found.paradigm, r.task, r.subject, r.measure, r.unit,
             *(number(v, 4) for v in r.estimate.numbers), r.estimate.status.value,
             r.estimate.words, r.trials]
            for found in study.findings for r in found.estimates]
    return write_csv(out / "estimates.csv", ESTIMATE_COLUMNS, rows)


def write_report(study: Study, out: Path, figures: bool = True) -> Report:
    """Write tables, figures (unless ``figures`` is False) and ``summary.md`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    tables = [path for found in study.findings for path in found.tables(out)]
    tables += write_tables(study.thresholds, study.runs, out)
    tables[-1:-1] = [estimates_table(study, out)]  # runs.csv stays last
    drawn = write_figures(study, out) if figures else []
    path = out / "summary.md"
    path.write_text(summary_markdown(study, tables, drawn, figures_skipped=not figures),
                    encoding="utf-8")
    return Report(path, tuple(tables), tuple(drawn))
