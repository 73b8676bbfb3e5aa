"""Figures of the lab's paradigms, each as PNG and PDF with its caption: a confusion matrix
per identification task; per two-interval and per temporal-order task, every subject's
proportions and fitted function."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pinarray.adaptive.posterior import ThresholdPosterior
from pinarray.analysis.identification import AcrossIdentification
from pinarray.analysis.judgements import IntervalFit, Judgements, OrderFit
from pinarray.analysis.lab_report import (
    identification_caption,
    temporal_order_caption,
    two_interval_caption,
)
from pinarray.analysis.plots import OKABE_ITO, _save, plt
from pinarray.analysis.subjects import IntervalSettings

_COLOURS = [OKABE_ITO[c] for c in ("blue", "orange", "green", "purple", "sky", "vermillion")]


def plot_identification(a: AcrossIdentification, settings: IntervalSettings,
                        stem: Path) -> list[Path]:
    """Patterns presented (rows) against answers (columns), % of each row."""
    pooled = a.pooled
    shares = pooled.row_percentages()
    figure, axes = plt.subplots(figsize=(1.8 + 0.55 * len(pooled.answered),
                                         1.6 + 0.4 * len(pooled.presented)))
    image = axes.imshow(shares, cmap="viridis", vmin=0, vmax=100, aspect="auto")
    for r in range(shares.shape[0]):
        for c in range(shares.shape[1]):
            if pooled.counts[r, c]:
                axes.text(c, r, f"{shares[r, c]:.0f}", ha="center", va="center", fontsize=7,
                          color="black" if shares[r, c] > 60 else "white")
    axes.set_xticks(np.arange(len(pooled.answered)), pooled.answered, fontsize=7, rotation=45)
    axes.set_yticks(np.arange(len(pooled.presented)), pooled.presented, fontsize=7)
    axes.set_xlabel("answer")
    axes.set_ylabel("presented")
    axes.set_title(f"{a.task}: % of each pattern's trials (trial-pooled)", fontsize=9)
    figure.colorbar(image, ax=axes, label="% of trials", fraction=0.05)
    return _save(figure, stem, identification_caption(a, settings))


def _curves(axes, fits: Sequence[IntervalFit | OrderFit], grid: np.ndarray) -> None:
    for n, found in enumerate(fits):
        colour = _COLOURS[n % len(_COLOURS)]
        x = np.array([p.x for p in found.points])
        trials = np.array([p.trials for p in found.points])
        axes.scatter(x, [p.proportion for p in found.points], s=8 + 60 * trials / trials.max(),
                     color=colour, alpha=0.7, linewidths=0)
        placed = found.threshold if isinstance(found, IntervalFit) else found.pss
        if isinstance(found.fit, ThresholdPosterior) and not math.isnan(placed.value):
            axes.plot(grid, found.fit.function.probability(grid), color=colour, linewidth=1.1,
                      label=f"subject {found.subject}")
        else:  # no curve where the answers place no threshold: the legend says why
            axes.plot([], [], color=colour, linewidth=1.1,
                      label=f"subject {found.subject}: {placed.words}")
    axes.set_ylim(-0.02, 1.02)
    axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def plot_two_interval(task: str, judgements: Judgements, settings: IntervalSettings,
                      stem: Path) -> list[Path]:
    """Every subject's proportion correct against the difference, with its Weibull."""
    fits = [f for f in judgements.intervals if f.task == task]
    top = max(p.x for f in fits for p in f.points)
    figure, axes = plt.subplots(figsize=(5.6, 3.8))
    _curves(axes, fits, np.linspace(1e-6, top * 1.1, 300))
    axes.axhline(0.5, color=OKABE_ITO["vermillion"], linestyle="--", linewidth=1.0)
    axes.set_xlabel(f"difference from the standard ({fits[0].unit})")
    axes.set_ylabel("proportion naming the higher interval")
    axes.set_title(f"Two intervals, task {task}", fontsize=9)
    return _save(figure, stem, two_interval_caption(task, judgements, settings))


def plot_temporal_order(task: str, judgements: Judgements, settings: IntervalSettings,
                        stem: Path) -> list[Path]:
    """Every subject's proportion naming pin A first against the SOA, with its logistic."""
    fits = [f for f in judgements.orders if f.task == task]
    reach = max(abs(p.x) for f in fits for p in f.points)
    figure, axes = plt.subplots(figsize=(5.6, 3.8))
    _curves(axes, fits, np.linspace(-reach * 1.1, reach * 1.1, 300))
    axes.axhline(0.5, color="0.6", linestyle=":", linewidth=0.8)
    axes.axvline(0.0, color="0.6", linestyle=":", linewidth=0.8)
    pins = " and ".join(map(str, fits[0].pins))
    axes.set_xlabel(f"SOA (ms): pin {fits[0].pins[1]}'s onset minus pin {fits[0].pins[0]}'s")
    axes.set_ylabel(f"proportion naming pin {fits[0].pins[0]} first")
    axes.set_title(f"Temporal order, task {task} (pins {pins})", fontsize=9)
    return _save(figure, stem, temporal_order_caption(task, judgements, settings))


def lab_figures(identification: Sequence[AcrossIdentification], judgements: Judgements,
                settings: IntervalSettings, out: Path) -> list[Path]:
    """Every figure of the lab's paradigms there are rows for."""
    drawn: list[Path] = []
    for a in identification:
        drawn += plot_identification(a, settings, out / f"identification_{a.task}")
    for task in sorted({f.task for f in judgements.intervals}):
        drawn += plot_two_interval(task, judgements, settings, out / f"two_interval_{task}")
    for task in sorted({f.task for f in judgements.orders}):
        drawn += plot_temporal_order(task, judgements, settings, out / f"temporal_order_{task}")
    return drawn
