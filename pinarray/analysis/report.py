"""Write an analysis folder: CSV tables, PNG figures, and a one-page ``summary.md`` linking them."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

from pinarray.analysis.stats import ERROR_CLASSES, Proportion, Summary
from pinarray.grid import DEFAULT_GRID, Grid


def _pct(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:.1f}"


def _proportion_cells(p: Proportion) -> list[str]:
    low, high = p.interval_pct
    return [str(p.successes), _pct(p.pct), _pct(low), _pct(high)]


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[object]]) -> Path:
    with open(path, "w", encoding="utf-8", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def write_tables(summaries: Sequence[Summary], out: Path, grid: Grid = DEFAULT_GRID) -> list[Path]:
    """The CSV tables, every group (pooled first); the confusion matrix for the pooled group."""
    pooled = summaries[0]
    localisation = [
        [s.group, f"{row.frequency_hz:g}", row.trials, *_proportion_cells(row.correct),
         *(_pct(row.error_pct(c)) for c in ERROR_CLASSES),
         _pct(100 * row.none_felt / row.trials if row.trials else math.nan)]
        for s in summaries for row in s.localisation
    ]
    pins = [
        [s.group, pin, *grid.cell(pin), int(s.pin_trials.flat[pin - 1]),
         int(s.pin_correct.flat[pin - 1]), _pct(s.pin_accuracy_pct.flat[pin - 1])]
        for s in summaries for pin in grid.pins
    ]
    motion = [
        [s.group, s.motion.felt.trials, *_proportion_cells(s.motion.felt),
         *_proportion_cells(s.motion.direction_right), s.motion.no_wave_felt.trials,
         *_proportion_cells(s.motion.no_wave_felt)]
        for s in summaries
    ]
    confusion = [[pin, *pooled.confusion[pin - 1]] for pin in grid.pins]
    ci = ("pct", "ci_low_pct", "ci_high_pct")
    return [
        _write_csv(out / "localisation_by_frequency.csv",
                   ["group", "frequency_hz", "trials", "correct", *(f"correct_{c}" for c in ci),
                    *(f"error_{c}_pct" for c in ERROR_CLASSES), "none_felt_pct"], localisation),
        _write_csv(out / "pin_accuracy.csv",
                   ["group", "pin", "row", "column", "trials", "correct", "correct_pct"], pins),
        _write_csv(out / "motion.csv",
                   ["group", "wave_trials", "felt", *(f"felt_{c}" for c in ci),
                    "direction_right", *(f"direction_right_{c}" for c in ci),
                    "no_wave_trials", "no_wave_felt", *(f"no_wave_felt_{c}" for c in ci)],
                   motion),
        _write_csv(out / "confusion_matrix.csv",
                   ["stimulated_pin", *(f"reported_{p}" for p in grid.pins)], confusion),
    ]


def write_figures(pooled: Summary, out: Path, grid: Grid = DEFAULT_GRID) -> list[Path]:
    """PNG figures of the pooled group, only those for which there are trials."""
    from pinarray.analysis import plots

    drawn = []
    if pooled.localisation:
        drawn += [plots.plot_correct_by_frequency(pooled, out / "correct_by_frequency.png"),
                  plots.plot_error_types(pooled, out / "error_types.png"),
                  plots.plot_confusion(pooled, out / "confusion_matrix.png"),
                  plots.plot_pin_map(pooled, out / "pin_accuracy.png", grid)]
    if pooled.motion.felt.trials:
        drawn.append(plots.plot_motion(pooled, out / "motion.png"))
    return drawn


def _interval(p: Proportion) -> str:
    low, high = p.interval_pct
    return f"{_pct(p.pct)} % [{_pct(low)}, {_pct(high)}] ({p.successes}/{p.trials})"


def summary_markdown(summaries: Sequence[Summary], sources: Sequence[Path],
                     tables: Sequence[Path], figures: Sequence[Path]) -> str:
    """The one-page report: pooled numbers, per-subject correct rates, links to everything."""
    pooled = summaries[0]
    lines = ["# Pin-array results", "",
             f"{len(sources)} results file(s), {len(pooled.subjects)} subject(s): "
             f"{', '.join(pooled.subjects) or 'none'}. Counted: main trials with status ok. "
             "Percentages carry 95 % Wilson intervals.", ""]
    if pooled.localisation:
        lines += ["## Localisation (pooled)", "",
                  "| frequency | trials | correct | A | B | C | D | nothing felt |",
                  "|---|---|---|---|---|---|---|---|"]
        for row in pooled.localisation:
            none_pct = 100 * row.none_felt / row.trials
            lines.append(f"| {row.frequency_hz:g} Hz | {row.trials} | {_interval(row.correct)} | "
                         + " | ".join(f"{_pct(row.error_pct(c))} %" for c in ERROR_CLASSES)
                         + f" | {_pct(none_pct)} % |")
        lines += ["", "Error classes as % of all trials at that frequency: A adjacent on the "
                  "same row/column, B diagonal neighbour, C same row/column not adjacent, "
                  "D neither.", ""]
        per_subject = [s for s in summaries[1:] if s.localisation]
        if per_subject:
            lines += ["Correct per subject: " + "; ".join(
                f"{s.group} " + ", ".join(f"{r.frequency_hz:g} Hz {_pct(r.correct.pct)} %"
                                          for r in s.localisation) for s in per_subject), ""]
    motion = pooled.motion
    if motion.felt.trials:
        lines += ["## Apparent motion (pooled)", "",
                  f"- felt a moving dot on wave trials: {_interval(motion.felt)}",
                  f"- of those, named the direction right: {_interval(motion.direction_right)}",
                  f"- felt motion on no-wave trials: {_interval(motion.no_wave_felt)}", ""]
    if figures:
        lines += ["## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figures] + [""]
    lines += ["## Tables", ""] + [f"- [{p.name}]({p.name})" for p in tables] + [""]
    return "\n".join(lines)


def write_report(summaries: Sequence[Summary], sources: Sequence[Path], out: Path,
                 grid: Grid = DEFAULT_GRID) -> Path:
    """Write tables, figures and ``summary.md`` into ``out``; return the summary's path."""
    out.mkdir(parents=True, exist_ok=True)
    tables = write_tables(summaries, out, grid)
    figures = write_figures(summaries[0], out, grid)
    path = out / "summary.md"
    path.write_text(summary_markdown(summaries, sources, tables, figures), encoding="utf-8")
    return path
