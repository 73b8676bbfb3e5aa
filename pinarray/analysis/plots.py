"""PNG figures of a `Summary`, drawn headless (matplotlib's Agg backend, no display needed).

The first three mirror the seed's figures: 9.13 (correct localisation by frequency), 9.15
(error types by frequency) and 9.17 (motion felt, direction right). Bars carry 95 % Wilson
intervals where the seed showed bare percentages, because a handful of subjects gives wide
ones.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # before pyplot: a lab PC over SSH, or CI, has no display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pinarray.analysis.stats import ERROR_CLASSES, Proportion, Summary  # noqa: E402
from pinarray.grid import DEFAULT_GRID, Grid  # noqa: E402

DPI = 150


def _save(figure, path: Path) -> Path:
    figure.tight_layout()
    figure.savefig(path, dpi=DPI)
    plt.close(figure)
    return path


def _error_bars(proportions: list[Proportion]) -> np.ndarray:
    """Distances from each percentage down and up to its interval, as errorbar wants them."""
    bars = np.zeros((2, len(proportions)))
    for i, p in enumerate(proportions):
        low, high = p.interval_pct
        if not math.isnan(p.pct):
            bars[:, i] = (p.pct - low, high - p.pct)
    return bars


def _frequency_labels(summary: Summary) -> list[str]:
    return [f"{row.frequency_hz:g} Hz" for row in summary.localisation]


def plot_correct_by_frequency(summary: Summary, path: Path) -> Path:
    """Fig. 9.13: percent correct localisation per frequency, with 95 % intervals."""
    figure, axes = plt.subplots(figsize=(4.5, 3.5))
    correct = [row.correct for row in summary.localisation]
    x = np.arange(len(correct))
    axes.bar(x, [p.pct for p in correct], yerr=_error_bars(correct), capsize=4,
             color="#4C72B0")
    for xi, p in zip(x, correct, strict=True):
        axes.annotate(f"{p.pct:.1f} %\nn={p.trials}", (xi, 2), ha="center", color="white",
                      fontsize=8)
    axes.set_xticks(x, _frequency_labels(summary))
    axes.set_ylim(0, 100)
    axes.set_ylabel("correct localisation (%)")
    axes.set_title(f"Correct localisation ({summary.group})")
    return _save(figure, path)


def plot_error_types(summary: Summary, path: Path) -> Path:
    """Fig. 9.15: percent of trials answered with each error class A-D, per frequency."""
    figure, axes = plt.subplots(figsize=(5.5, 3.5))
    rows = summary.localisation
    width = 0.8 / len(ERROR_CLASSES)
    x = np.arange(len(rows))
    for i, error_class in enumerate(ERROR_CLASSES):
        axes.bar(x + (i - 1.5) * width, [row.error_pct(error_class) for row in rows], width,
                 label=f"error {error_class}")
    axes.set_xticks(x, _frequency_labels(summary))
    axes.set_ylabel("trials (%)")
    axes.set_title(f"Localisation errors by type ({summary.group})")
    axes.legend(fontsize=8)
    return _save(figure, path)


def plot_motion(summary: Summary, path: Path) -> Path:
    """Fig. 9.17: percent of wave trials felt as motion, and of those the direction right."""
    motion = summary.motion
    bars = [motion.felt, motion.direction_right]
    figure, axes = plt.subplots(figsize=(4.5, 3.5))
    axes.bar([0, 1], [p.pct for p in bars], yerr=_error_bars(bars), capsize=4,
             color=["#55A868", "#C44E52"])
    for xi, p in enumerate(bars):
        axes.annotate(f"{p.pct:.0f} %\n{p.successes}/{p.trials}", (xi, 2), ha="center",
                      color="white", fontsize=8)
    axes.set_xticks([0, 1], ["felt a moving dot", "direction right\n(of those felt)"])
    axes.set_ylim(0, 100)
    axes.set_ylabel("%")
    axes.set_title(f"Apparent motion ({summary.group})")
    return _save(figure, path)


def plot_confusion(summary: Summary, path: Path) -> Path:
    """Stimulated pin (rows) against reported pin (columns), as percent of each row."""
    counts = summary.confusion
    with np.errstate(invalid="ignore", divide="ignore"):
        shares = 100 * counts / counts.sum(axis=1, keepdims=True)
    figure, axes = plt.subplots(figsize=(5.5, 4.8))
    image = axes.imshow(shares, cmap="viridis", vmin=0, vmax=100)
    ticks = np.arange(counts.shape[0])
    axes.set_xticks(ticks, [str(t + 1) for t in ticks], fontsize=7)
    axes.set_yticks(ticks, [str(t + 1) for t in ticks], fontsize=7)
    axes.set_xlabel("reported pin")
    axes.set_ylabel("stimulated pin")
    axes.set_title(f"Confusion matrix, % of each row ({summary.group})")
    figure.colorbar(image, ax=axes, label="% of trials")
    return _save(figure, path)


def plot_pin_map(summary: Summary, path: Path, grid: Grid = DEFAULT_GRID) -> Path:
    """Percent correct per pin, drawn as the subject feels the grid (pin 1 bottom-left)."""
    accuracy = summary.pin_accuracy_pct
    figure, axes = plt.subplots(figsize=(4.2, 3.8))
    image = axes.imshow(np.ma.masked_invalid(accuracy), origin="lower", cmap="magma",
                        vmin=0, vmax=100)
    for row in range(grid.rows):
        for column in range(grid.columns):
            value = accuracy[row, column]
            text = "-" if math.isnan(value) else f"{value:.0f} %"
            axes.text(column, row, f"pin {grid.pin_at(row, column)}\n{text}", ha="center",
                      va="center", fontsize=7, color="grey" if math.isnan(value) else "cyan")
    axes.set_xticks([])
    axes.set_yticks([])
    axes.set_title(f"Correct localisation per pin ({summary.group})")
    figure.colorbar(image, ax=axes, label="% correct")
    return _save(figure, path)


FIGURES = {
    "correct_by_frequency": plot_correct_by_frequency,
    "error_types": plot_error_types,
    "motion": plot_motion,
    "confusion_matrix": plot_confusion,
    "pin_accuracy": plot_pin_map,
}
