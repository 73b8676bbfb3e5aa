"""Localisation's figures, each as PNG and PDF with its caption: correct answers by frequency
(the seed's Fig. 9.13), error types by frequency (9.15, with "nothing felt" beside A-D), the
confusion matrix, each pin's accuracy as the subject feels the grid, and each pin's achieved
stroke by frequency."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pinarray.analysis.figures import (
    CHANCE_COLOUR,
    OKABE_ITO,
    bar_errors,
    label_bars,
    means,
    plt,
    save,
    subject_dots,
)
from pinarray.analysis.subjects import AcrossSubjects
from pinarray.paradigms.localisation.analysis import COUNTED, Localisations
from pinarray.paradigms.localisation.stats import CATEGORIES, CATEGORY_LABELS

CATEGORY_COLOURS = {"correct": OKABE_ITO["blue"], "A": OKABE_ITO["orange"],
                    "B": OKABE_ITO["sky"], "C": OKABE_ITO["green"], "D": OKABE_ITO["purple"],
                    "none": OKABE_ITO["yellow"]}


def _n(found: Localisations) -> str:
    return (f"N = {len(found.level.localisation_subjects)} subject(s), "
            f"{found.trials} trials")


def correct_by_frequency_caption(found: Localisations) -> str:
    chance = found.chance
    chance_text = f" Dashed line: {chance.definition()}." if chance else ""
    return (f"Correct localisation by frequency. Bars: mean of per-subject percentages "
            f"(unit: subject; {_n(found)}); error bars: {found.settings.describe()}; "
            f"grey lines: individual subjects; under each bar: its mean, subjects and "
            f"trials.{chance_text} {COUNTED}")


def error_types_caption(found: Localisations) -> str:
    return (f"Localisation answers by type, % of all trials at each frequency (correct answers "
            f"are the rest). A: adjacent on the same row or column; B: diagonal neighbour; "
            f"C: same row or column, not adjacent; D: neither; nothing felt: no pin named. "
            f"Bars: mean of per-subject percentages (unit: subject; {_n(found)}); "
            f"error bars: {found.settings.describe()}. Black ticks: chance share of each error "
            f"class for a subject naming any of "
            f"{len(found.chance.answer_pins) if found.chance else 0} pins at random, averaged "
            f"over the stimulated pins. {COUNTED}")


def confusion_matrix_caption(found: Localisations) -> str:
    return (f"Confusion matrix, trial-pooled: every trial of every subject counted together "
            f"(unit: trial; {_n(found)}, all frequencies). Each row is one "
            f"stimulated pin and adds up to 100 % of its trials, including the 'nothing felt' "
            f"column. Pins numbered 1-16 as the subject feels them (1 bottom-left). {COUNTED}")


def pin_accuracy_caption(found: Localisations) -> str:
    return (f"Correct localisation per pin, drawn as the subject feels the grid (pin 1 "
            f"bottom-left, pin numbers 1-based). Each cell: mean of per-subject percentages "
            f"for that pin (unit: subject; {_n(found)}, all frequencies); grey "
            f"cells were never stimulated. {COUNTED}")


def stroke_by_frequency_caption(found: Localisations) -> str:
    rows = found.strokes.rows
    commanded = ", ".join(
        f"{steps} steps" + ("" if math.isnan(mm) else f" ({mm:.2f} mm)")
        for steps, mm in sorted({(r.commanded_steps, r.mm(r.commanded_steps)) for r in rows}))
    return (f"Achieved stroke by frequency, each pin its own line: a trial's achieved stroke is "
            f"the smallest peak-to-peak of the pin's sampled position over the trial's cycles. "
            f"Points: the median over trials as a percentage of the commanded stroke "
            f"({commanded}); bars: the smallest and largest trial; dashed: 100 %. "
            f"N = {sum(r.n_trials for r in rows)} trials of {len({r.pin for r in rows})} "
            f"pin(s): every localisation row of the counted runs whose stroke was measured, "
            f"practice and invalid rows included.")


def plot_correct_by_frequency(found: Localisations, stem: Path) -> list[Path]:
    """Fig. 9.13: correct localisation per frequency, subjects as the unit, with chance."""
    level = found.level
    correct: list[AcrossSubjects] = [r.share("correct") for r in level.localisation]
    x = np.arange(len(correct))
    # Room under each bar for its label (about 0.9 in at 7 pt), however many frequencies.
    figure, axes = plt.subplots(figsize=(max(5.0, 1.2 + 0.9 * len(x)), 3.8))
    axes.bar(x, means(correct), yerr=bar_errors(correct, found.settings.method), capsize=4,
             color=CATEGORY_COLOURS["correct"], alpha=0.85, zorder=1)
    subject_dots(axes, x, correct, connect=True)
    label_bars(axes, x, [f"{r.frequency_hz:g} Hz" for r in level.localisation], correct, 1)
    if found.chance:
        axes.axhline(100 * found.chance.correct, color=CHANCE_COLOUR, linestyle="--",
                     linewidth=1.2, label=f"chance {100 * found.chance.correct:.2f} %")
        axes.legend(fontsize=7, loc="upper left")
    axes.set_ylim(0, 100)
    axes.set_ylabel("correct localisation (% of trials)")
    axes.set_title("Correct localisation by frequency")
    return save(figure, stem, correct_by_frequency_caption(found))


def plot_error_types(found: Localisations, stem: Path) -> list[Path]:
    """Fig. 9.15: each error class A-D and "nothing felt", % of trials per frequency."""
    level = found.level
    kinds = [c for c in CATEGORIES if c != "correct"]
    width = 0.8 / len(kinds)
    x = np.arange(len(level.localisation))
    figure, axes = plt.subplots(figsize=(7.4, 3.8))
    for i, kind in enumerate(kinds):
        measures = [r.share(kind) for r in level.localisation]
        offset = x + (i - (len(kinds) - 1) / 2) * width
        axes.bar(offset, means(measures), width,
                 yerr=bar_errors(measures, found.settings.method), capsize=2,
                 color=CATEGORY_COLOURS[kind], edgecolor="black", linewidth=0.4,
                 label=CATEGORY_LABELS[kind], error_kw={"linewidth": 0.8})
        if found.chance and kind in found.chance.fractions:
            axes.scatter(offset, [100 * found.chance.fractions[kind]] * len(x), marker="_",
                         s=120, color="black", zorder=5, label="chance" if i == 0 else None)
    axes.set_xticks(x, [f"{r.frequency_hz:g} Hz" for r in level.localisation])
    axes.set_ylim(0, None)
    axes.set_ylabel("% of trials")
    axes.set_title("Localisation errors by type, and nothing felt")
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return save(figure, stem, error_types_caption(found))


def plot_confusion(found: Localisations, stem: Path) -> list[Path]:
    """Stimulated pin (rows) against answer (columns, "nothing felt" last), % of each row."""
    counts = found.pooled.confusion
    stimulated = [i for i in range(counts.shape[0]) if counts[i].sum()]
    rows = counts[stimulated]
    shares = 100 * rows / rows.sum(axis=1, keepdims=True)
    figure, axes = plt.subplots(figsize=(7.0, 1.6 + 0.32 * len(stimulated)))
    image = axes.imshow(shares, cmap="viridis", vmin=0, vmax=100, aspect="auto")
    for r in range(shares.shape[0]):
        for c in range(shares.shape[1]):
            if rows[r, c]:
                axes.text(c, r, f"{shares[r, c]:.0f}", ha="center", va="center", fontsize=6,
                          color="black" if shares[r, c] > 60 else "white")
    pin_count = counts.shape[0]
    axes.set_xticks(np.arange(pin_count + 1),
                    [str(p) for p in range(1, pin_count + 1)] + ["nothing\nfelt"], fontsize=7)
    axes.set_yticks(np.arange(len(stimulated)), [str(i + 1) for i in stimulated], fontsize=7)
    axes.axvline(pin_count - 0.5, color="white", linewidth=1.5)
    axes.set_xlabel("answer (pin named)")
    axes.set_ylabel("stimulated pin")
    axes.set_title("Confusion matrix, % of each stimulated pin's trials (trial-pooled)")
    figure.colorbar(image, ax=axes, label="% of trials", fraction=0.04)
    return save(figure, stem, confusion_matrix_caption(found))


def plot_pin_map(found: Localisations, stem: Path) -> list[Path]:
    """Correct % per pin as the subject feels the grid (pin 1 bottom-left), subjects as unit."""
    grid = found.grid
    pins = found.level.pins
    mean = np.array([m.mean_pct for m in pins]).reshape(grid.rows, grid.columns)
    figure, axes = plt.subplots(figsize=(4.6, 4.2))
    image = axes.imshow(np.ma.masked_invalid(mean), origin="lower", cmap="viridis", vmin=0,
                        vmax=100)
    axes.set_facecolor("0.85")
    for at_row in range(grid.rows):
        for column in range(grid.columns):
            pin = grid.pin_at(at_row, column)
            m = pins[pin - 1]
            text = (f"pin {pin}\n-" if not m.subjects
                    else f"pin {pin}\n{m.mean_pct:.0f} %\n{m.subjects} subj.")
            light = not m.subjects or m.mean_pct > 60
            axes.text(column, at_row, text, ha="center", va="center", fontsize=7,
                      color="black" if light else "white")
    axes.set_xticks([])
    axes.set_yticks([])
    axes.set_title("Correct localisation per pin")
    figure.colorbar(image, ax=axes, label="% correct (mean over subjects)")
    return save(figure, stem, pin_accuracy_caption(found))


def plot_stroke_by_frequency(found: Localisations, stem: Path) -> list[Path]:
    """Each pin's achieved stroke by frequency, as % of the commanded one: the median over the
    trials, bars from the smallest to the largest, one line per pin and commanded stroke."""
    colours = list(OKABE_ITO.values())[1:] + [OKABE_ITO["black"]]
    markers = ["o", "s", "^", "D", "v", "P", "X", "*"]
    rows = found.strokes.rows
    lines = sorted({(r.pin, r.commanded_steps) for r in rows})
    figure, axes = plt.subplots(figsize=(6.4, 4.0))
    for i, (pin, commanded) in enumerate(lines):
        mine = sorted((r for r in rows if (r.pin, r.commanded_steps) == (pin, commanded)),
                      key=lambda r: r.frequency_hz)
        # Side by side within a frequency, so that the pins' bars do not hide each other.
        hz = [r.frequency_hz * 2 ** ((i - (len(lines) - 1) / 2) * 0.02) for r in mine]
        middle = np.array([r.share_pct(r.achieved_median_steps) for r in mine])
        spread = np.array([[m - r.share_pct(r.achieved_min_steps) for m, r in zip(middle, mine,
                                                                               strict=True)],
                           [r.share_pct(r.achieved_max_steps) - m for m, r in zip(middle, mine,
                                                                               strict=True)]])
        label = f"pin {pin}" + (f", {commanded} steps" if len({c for _, c in lines}) > 1 else "")
        axes.errorbar(hz, middle, yerr=spread, color=colours[i % len(colours)],
                      marker=markers[(i // len(colours)) % len(markers)], markersize=4,
                      capsize=2, linewidth=0.9, label=label)
    axes.axhline(100, color="black", linestyle="--", linewidth=0.8)
    axes.set_xscale("log", base=2)
    frequencies = sorted({r.frequency_hz for r in rows})
    axes.set_xticks(frequencies, [f"{f:g}" for f in frequencies])
    axes.minorticks_off()
    axes.set_xlabel("frequency (Hz)")
    axes.set_ylabel("achieved stroke (% of commanded)")
    axes.set_ylim(0, 110)
    axes.set_title("Achieved stroke by frequency")
    axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                ncol=1 + len(lines) // 16)
    return save(figure, stem, stroke_by_frequency_caption(found))


FIGURES: dict[str, Callable[[Localisations, Path], list[Path]]] = {
    "correct_by_frequency": plot_correct_by_frequency,
    "error_types": plot_error_types,
    "confusion_matrix": plot_confusion,
    "pin_accuracy": plot_pin_map,
}
