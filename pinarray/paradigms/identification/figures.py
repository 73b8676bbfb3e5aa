"""Identification's figure: a confusion matrix per task, as PNG and PDF with its caption."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pinarray.analysis.figures import plt, save
from pinarray.paradigms.identification.analysis import AcrossIdentification


def plot_identification(a: AcrossIdentification, caption: str, stem: Path) -> list[Path]:
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
    return save(figure, stem, caption)
