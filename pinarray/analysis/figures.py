"""The figures' one style, drawn headless (matplotlib's Agg backend), each as PNG and PDF.

Bars are means of per-subject percentages with the across-subject interval the settings name;
chance levels are drawn. Colours are the Okabe-Ito palette, which stays distinguishable with
the common colour-vision deficiencies; colour maps are viridis. Each figure carries its
caption under the axes (`save`). Every paradigm's figures (its room's) and the adaptive
designs' (`pinarray.analysis.plots`) are drawn in it.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # before pyplot: a lab PC over SSH, or CI, has no display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pinarray.adaptive.posterior import ThresholdPosterior  # noqa: E402
from pinarray.analysis.fits import Fit, Point  # noqa: E402
from pinarray.analysis.seam import Estimate, EstimateStatus  # noqa: E402
from pinarray.analysis.subjects import AcrossSubjects, IntervalMethod  # noqa: E402

DPI = 150
FORMATS = ("png", "pdf")  # raster for a quick look, vector for the paper
# Okabe & Ito (2008), "Color universal design".
OKABE_ITO = {"black": "#000000", "orange": "#E69F00", "sky": "#56B4E9", "green": "#009E73",
             "yellow": "#F0E442", "blue": "#0072B2", "vermillion": "#D55E00",
             "purple": "#CC79A7"}
CHANCE_COLOUR = OKABE_ITO["vermillion"]
_CAPTION_FONT = 7


def save(figure, stem: Path, caption: str) -> list[Path]:
    """Write ``stem``.png and .pdf with ``caption`` wrapped under the axes."""
    compose(figure, caption)
    paths = []
    for ext in FORMATS:
        path = stem.with_suffix(f".{ext}")
        # No creation date in the PDF: the same results give the same bytes. The PNG's zlib
        # at level 1 rather than Pillow's 6: the same pixels, in a third less time and a
        # slightly smaller file (these figures' flat colours compress no better at 6).
        figure.savefig(path, dpi=DPI, **({"metadata": {"CreationDate": None}} if ext == "pdf"
                                         else {"pil_kwargs": {"compress_level": 1}}))
        paths.append(path)
    plt.close(figure)
    return paths


def compose(figure, caption: str) -> None:
    """Make room for ``caption`` under the axes, lay the figure out and write the caption
    there: the figure as `save` writes it."""
    width_in = figure.get_size_inches()[0]
    lines = textwrap.wrap(caption, width=int(width_in * 17))
    height_in = figure.get_size_inches()[1]
    figure.set_size_inches(width_in, height_in + 0.13 * len(lines))
    bottom = (0.13 * len(lines) + 0.1) / figure.get_size_inches()[1]
    lay_out(figure, rect=(0, bottom, 1, 1))
    figure.text(0.01, 0.01, "\n".join(lines), fontsize=_CAPTION_FONT, ha="left", va="bottom")


# What a lab's matplotlibrc may set that would lay the house figures out a second way: they are
# laid out by `lay_out` alone, with room for their captions.
_NO_LAYOUT_ENGINE = {"figure.autolayout": False, "figure.constrained_layout.use": False}


def house_layout():
    """Draw the figures inside this: each is laid out by `lay_out` alone, whatever layout engine
    a lab's matplotlibrc asks for (under ``figure.constrained_layout.use`` a figure with a colour
    bar refused `tight_layout` with a traceback; under ``figure.autolayout`` the engine laid the
    axes over the caption)."""
    return matplotlib.rc_context(_NO_LAYOUT_ENGINE)


def lay_out(figure, rect: tuple[float, float, float, float] = (0, 0, 1, 1)) -> None:
    """Lay the figure out once (`tight_layout` inside ``rect``) and leave it so.

    `tight_layout` leaves a placeholder layout engine on the figure, and `savefig` draws a
    figure that has one twice for each format, once without output "to make sure the layout
    works" (matplotlib's ``print_figure``): with the engine removed the files are byte for
    byte the same and a figure's two formats take about a fifth less time.
    """
    figure.tight_layout(rect=rect)
    # Removed, not replaced: with these unset, None means no engine whatever a matplotlibrc says.
    with house_layout():
        figure.set_layout_engine(None)


def bar_errors(measures: Sequence[AcrossSubjects], method: IntervalMethod) -> np.ndarray:
    """Distances from each mean down and up to its interval, as errorbar wants them."""
    bars = np.zeros((2, len(measures)))
    for i, m in enumerate(measures):
        low, high = m.interval_pct(method)
        if not (math.isnan(low) or math.isnan(m.mean_pct)):
            bars[:, i] = (m.mean_pct - low, high - m.mean_pct)
    return bars


def subject_dots(axes, xs: Sequence[float] | np.ndarray, measures: Sequence[AcrossSubjects],
                  connect: bool) -> None:
    """Each subject's own percentage as a small dot (and a line across x when ``connect``)."""
    subjects = sorted({s for m in measures for s, _ in m.per_subject})
    for n, subject in enumerate(subjects):
        points = [(x, dict(m.per_subject)[subject].pct) for x, m in zip(xs, measures, strict=True)
                  if subject in dict(m.per_subject)]
        jitter = (n - (len(subjects) - 1) / 2) * 0.2 / max(len(subjects), 1)
        px = [x + jitter for x, _ in points]
        py = [y for _, y in points]
        if connect:
            axes.plot(px, py, color="0.6", linewidth=0.6, zorder=2)
        axes.scatter(px, py, s=8, color="0.35", zorder=3, linewidths=0, clip_on=False)


def means(measures: Sequence[AcrossSubjects]) -> list[float]:
    return [0.0 if math.isnan(m.mean_pct) else m.mean_pct for m in measures]


def label_bars(axes, x: np.ndarray, names: Sequence[str], measures: Sequence[AcrossSubjects],
                digits: int) -> None:
    """Each bar's name, mean, subjects and trials under the axis, as its tick label.

    Under the axis, not on the bar: inside the axes any place a label could take is crossed,
    for some results, by a subject's line or dot or an error bar.
    """
    axes.set_xticks(x, [f"{name}\n{m.mean_pct:.{digits}f} %\n{m.subjects} subj., "
                        f"{m.trials} trials" for name, m in zip(names, measures, strict=True)],
                    fontsize=7)


CURVE_COLOURS = [OKABE_ITO[c] for c in ("blue", "orange", "green", "purple", "sky",
                                        "vermillion")]


def fitted_curves(axes: Any, fits: Sequence[tuple[str, Sequence[Point], Fit, Estimate]],
                  grid: np.ndarray) -> None:
    """Each subject's proportions (dot area: trials) and its fitted function, drawn where the
    answers place the estimate the curve stands for; else its words in the legend. ``fits``:
    (subject, points, fit, the placed estimate) each."""
    for n, (subject, found, fit, placed) in enumerate(fits):
        colour = CURVE_COLOURS[n % len(CURVE_COLOURS)]
        x = np.array([p.x for p in found])
        trials = np.array([p.trials for p in found])
        axes.scatter(x, [p.proportion for p in found], s=8 + 60 * trials / trials.max(),
                     color=colour, alpha=0.7, linewidths=0)
        if isinstance(fit, ThresholdPosterior) and placed.status is EstimateStatus.ESTIMATED:
            axes.plot(grid, fit.function.probability(grid), color=colour, linewidth=1.1,
                      label=f"subject {subject}")
        else:  # no curve where the answers place no value: the legend says why
            axes.plot([], [], color=colour, linewidth=1.1, label=f"subject {subject}: "
                                                                  f"{placed.words}")
    axes.set_ylim(-0.02, 1.02)
    axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))
