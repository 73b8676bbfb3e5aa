"""Figures of a `Study`, drawn headless (matplotlib's Agg backend), each as PNG and PDF.

The first three mirror the seed's figures: 9.13 (correct localisation by frequency), 9.15
(error types by frequency, here with "nothing felt" beside A-D) and 9.17 (motion felt,
direction right). Bars are means of per-subject percentages with the across-subject interval
the settings name; chance levels are drawn. Colours are the Okabe-Ito palette, which stays
distinguishable with the common colour-vision deficiencies; colour maps are viridis. Each
figure carries its caption (`pinarray.analysis.captions`) under the axes. Past 400 lines:
the figures share one style (palette, sizes, saving), which a split would have to repeat.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # before pyplot: a lab PC over SSH, or CI, has no display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pinarray.adaptive.posterior import ThresholdStatus  # noqa: E402
from pinarray.analysis import captions  # noqa: E402
from pinarray.analysis.chance import DIRECTION_CHANCE  # noqa: E402
from pinarray.analysis.stats import CATEGORIES, CATEGORY_LABELS  # noqa: E402
from pinarray.analysis.study import Study  # noqa: E402
from pinarray.analysis.subjects import AcrossSubjects, IntervalMethod  # noqa: E402
from pinarray.analysis.thresholds import (  # noqa: E402
    NotFitted,
    SubjectThresholds,
    ThresholdMethod,
)
from pinarray.protocol.response import MeasuredResponse  # noqa: E402

DPI = 150
FORMATS = ("png", "pdf")  # raster for a quick look, vector for the paper
# Okabe & Ito (2008), "Color universal design".
OKABE_ITO = {"black": "#000000", "orange": "#E69F00", "sky": "#56B4E9", "green": "#009E73",
             "yellow": "#F0E442", "blue": "#0072B2", "vermillion": "#D55E00",
             "purple": "#CC79A7"}
CATEGORY_COLOURS = {"correct": OKABE_ITO["blue"], "A": OKABE_ITO["orange"],
                    "B": OKABE_ITO["sky"], "C": OKABE_ITO["green"], "D": OKABE_ITO["purple"],
                    "none": OKABE_ITO["yellow"]}
CHANCE_COLOUR = OKABE_ITO["vermillion"]
_CAPTION_FONT = 7


def _save(figure, stem: Path, caption: str) -> list[Path]:
    """Write ``stem``.png and .pdf with ``caption`` wrapped under the axes."""
    width_in = figure.get_size_inches()[0]
    lines = textwrap.wrap(caption, width=int(width_in * 17))
    height_in = figure.get_size_inches()[1]
    figure.set_size_inches(width_in, height_in + 0.13 * len(lines))
    bottom = (0.13 * len(lines) + 0.1) / figure.get_size_inches()[1]
    figure.tight_layout(rect=(0, bottom, 1, 1))
    figure.text(0.01, 0.01, "\n".join(lines), fontsize=_CAPTION_FONT, ha="left", va="bottom")
    paths = []
    for ext in FORMATS:
        path = stem.with_suffix(f".{ext}")
        # No creation date in the PDF: the same results give the same bytes.
        figure.savefig(path, dpi=DPI, metadata={"CreationDate": None} if ext == "pdf" else None)
        paths.append(path)
    plt.close(figure)
    return paths


def _bar_errors(measures: Sequence[AcrossSubjects], method: IntervalMethod) -> np.ndarray:
    """Distances from each mean down and up to its interval, as errorbar wants them."""
    bars = np.zeros((2, len(measures)))
    for i, m in enumerate(measures):
        low, high = m.interval_pct(method)
        if not (math.isnan(low) or math.isnan(m.mean_pct)):
            bars[:, i] = (m.mean_pct - low, high - m.mean_pct)
    return bars


def _subject_dots(axes, xs: Sequence[float] | np.ndarray, measures: Sequence[AcrossSubjects],
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


def _means(measures: Sequence[AcrossSubjects]) -> list[float]:
    return [0.0 if math.isnan(m.mean_pct) else m.mean_pct for m in measures]


def _label_bars(axes, x: np.ndarray, names: Sequence[str], measures: Sequence[AcrossSubjects],
                digits: int) -> None:
    """Each bar's name, mean, subjects and trials under the axis, as its tick label.

    Under the axis, not on the bar: inside the axes any place a label could take is crossed,
    for some results, by a subject's line or dot or an error bar.
    """
    axes.set_xticks(x, [f"{name}\n{m.mean_pct:.{digits}f} %\n{m.subjects} subj., "
                        f"{m.trials} trials" for name, m in zip(names, measures, strict=True)],
                    fontsize=7)


def plot_correct_by_frequency(study: Study, stem: Path) -> list[Path]:
    """Fig. 9.13: correct localisation per frequency, subjects as the unit, with chance."""
    level = study.subject_level
    method = level.settings.method
    correct = [row.share("correct") for row in level.localisation]
    x = np.arange(len(correct))
    # Room under each bar for its label (about 0.9 in at 7 pt), however many frequencies.
    figure, axes = plt.subplots(figsize=(max(5.0, 1.2 + 0.9 * len(x)), 3.8))
    axes.bar(x, _means(correct), yerr=_bar_errors(correct, method), capsize=4,
             color=CATEGORY_COLOURS["correct"], alpha=0.85, zorder=1)
    _subject_dots(axes, x, correct, connect=True)
    _label_bars(axes, x, [f"{row.frequency_hz:g} Hz" for row in level.localisation], correct, 1)
    if study.chance:
        axes.axhline(100 * study.chance.correct, color=CHANCE_COLOUR, linestyle="--",
                     linewidth=1.2, label=f"chance {100 * study.chance.correct:.2f} %")
        axes.legend(fontsize=7, loc="upper left")
    axes.set_ylim(0, 100)
    axes.set_ylabel("correct localisation (% of trials)")
    axes.set_title("Correct localisation by frequency")
    return _save(figure, stem, captions.correct_by_frequency(study))


def plot_error_types(study: Study, stem: Path) -> list[Path]:
    """Fig. 9.15: each error class A-D and "nothing felt", % of trials per frequency."""
    level = study.subject_level
    method = level.settings.method
    kinds = [c for c in CATEGORIES if c != "correct"]
    width = 0.8 / len(kinds)
    x = np.arange(len(level.localisation))
    figure, axes = plt.subplots(figsize=(7.4, 3.8))
    for i, kind in enumerate(kinds):
        measures = [row.share(kind) for row in level.localisation]
        offset = x + (i - (len(kinds) - 1) / 2) * width
        axes.bar(offset, _means(measures), width, yerr=_bar_errors(measures, method), capsize=2,
                 color=CATEGORY_COLOURS[kind], edgecolor="black", linewidth=0.4,
                 label=CATEGORY_LABELS[kind], error_kw={"linewidth": 0.8})
        if study.chance and kind in study.chance.fractions:
            axes.scatter(offset, [100 * study.chance.fractions[kind]] * len(x), marker="_",
                         s=120, color="black", zorder=5,
                         label="chance" if i == 0 else None)
    axes.set_xticks(x, [f"{row.frequency_hz:g} Hz" for row in level.localisation])
    axes.set_ylim(0, None)
    axes.set_ylabel("% of trials")
    axes.set_title("Localisation errors by type, and nothing felt")
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(figure, stem, captions.error_types(study))


def plot_confusion(study: Study, stem: Path) -> list[Path]:
    """Stimulated pin (rows) against answer (columns, "nothing felt" last), % of each row."""
    counts = study.pooled.confusion
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
    return _save(figure, stem, captions.confusion_matrix(study))


def plot_pin_map(study: Study, stem: Path) -> list[Path]:
    """Correct % per pin as the subject feels the grid (pin 1 bottom-left), subjects as unit."""
    grid = study.grid
    pins = study.subject_level.pins
    means = np.array([m.mean_pct for m in pins]).reshape(grid.rows, grid.columns)
    figure, axes = plt.subplots(figsize=(4.6, 4.2))
    image = axes.imshow(np.ma.masked_invalid(means), origin="lower", cmap="viridis", vmin=0,
                        vmax=100)
    axes.set_facecolor("0.85")
    for row in range(grid.rows):
        for column in range(grid.columns):
            pin = grid.pin_at(row, column)
            m = pins[pin - 1]
            text = (f"pin {pin}\n-" if not m.subjects
                    else f"pin {pin}\n{m.mean_pct:.0f} %\n{m.subjects} subj.")
            light = not m.subjects or m.mean_pct > 60
            axes.text(column, row, text, ha="center", va="center", fontsize=7,
                      color="black" if light else "white")
    axes.set_xticks([])
    axes.set_yticks([])
    axes.set_title("Correct localisation per pin")
    figure.colorbar(image, ax=axes, label="% correct (mean over subjects)")
    return _save(figure, stem, captions.pin_accuracy(study))


def plot_motion(study: Study, stem: Path) -> list[Path]:
    """Fig. 9.17: motion felt on wave trials, direction right of those, felt on no-wave."""
    level = study.subject_level
    motion = level.motion
    measures = [motion.felt, motion.direction_right, motion.no_wave_felt]
    x = np.arange(3)
    figure, axes = plt.subplots(figsize=(5.0, 3.9))
    axes.bar(x, _means(measures), yerr=_bar_errors(measures, level.settings.method), capsize=4,
             color=[OKABE_ITO["green"], OKABE_ITO["blue"], OKABE_ITO["sky"]], alpha=0.9)
    _subject_dots(axes, x, measures, connect=False)
    _label_bars(axes, x, ["felt a moving dot\n(wave trials)", "direction right\n(of those felt)",
                          "felt motion\n(no-wave trials)"], measures, 0)
    axes.hlines(100 * DIRECTION_CHANCE, 0.55, 1.45, color=CHANCE_COLOUR, linestyle="--",
                linewidth=1.2, label=f"chance {100 * DIRECTION_CHANCE:.0f} %")
    axes.legend(fontsize=7, loc="upper right")
    axes.set_ylim(0, 100)
    axes.set_ylabel("% of trials")
    axes.set_title("Apparent motion")
    return _save(figure, stem, captions.motion(study))


def plot_power(curves, stem: Path, caption: str) -> list[Path]:
    """Power against the number of subjects, one line per criterion, Monte-Carlo band shaded."""
    from pinarray.analysis.power import TARGET_POWER

    colours = [OKABE_ITO[c] for c in ("blue", "orange", "green", "purple", "vermillion", "sky")]
    markers = ["o", "s", "^", "D", "v", "P"]
    figure, axes = plt.subplots(figsize=(6.0, 4.0))
    for i, criterion in enumerate(curves.criteria):
        points = sorted((p for p in curves.points if p.criterion == criterion),
                        key=lambda p: p.subjects)
        n = [p.subjects for p in points]
        bands = np.array([p.met.interval_pct for p in points])
        colour = colours[i % len(colours)]
        axes.fill_between(n, bands[:, 0], bands[:, 1], color=colour, alpha=0.15, linewidth=0)
        axes.plot(n, [p.met.pct for p in points], marker=markers[i % len(markers)],
                  color=colour, label=criterion, markersize=4)
    axes.axhline(100 * TARGET_POWER, color="black", linestyle="--", linewidth=0.8)
    axes.set_xticks(curves.subject_counts)
    axes.set_xlabel("subjects")
    axes.set_ylabel("power (% of simulated studies)")
    axes.set_ylim(0, 100)
    axes.set_title(f"How many subjects? ({curves.protocol})")
    axes.legend(fontsize=7, loc="lower right")
    return _save(figure, stem, caption)


def _parameter_label(found: SubjectThresholds) -> str:
    return found.parameter + ("" if found.unit == "n/a" else f" ({found.unit})")


def plot_track(found: SubjectThresholds, stem: Path) -> list[Path]:
    """Each procedure's track: intensity by trial, correct and wrong, reversals, its estimate."""
    procedures = found.procedures
    figure, axes_list = plt.subplots(len(procedures), 1, squeeze=False,
                                     figsize=(6.0, 1.2 + 1.9 * len(procedures)))
    for axes, estimate in zip(axes_list[:, 0], procedures, strict=True):
        trials = np.arange(1, estimate.n_trials + 1)
        intensity = np.array([p.intensity for p in estimate.track])
        correct = np.array([p.correct for p in estimate.track], dtype=bool)
        reversal = np.array([p.reversal for p in estimate.track], dtype=bool)
        axes.plot(trials, intensity, color="0.6", linewidth=0.8, zorder=1)
        axes.scatter(trials[correct], intensity[correct], s=14, color=OKABE_ITO["blue"],
                     label="correct", zorder=3)
        axes.scatter(trials[~correct], intensity[~correct], s=18, marker="x",
                     color=OKABE_ITO["vermillion"], label="wrong", zorder=3)
        if reversal.any():
            axes.scatter(trials[reversal], intensity[reversal], s=70, facecolors="none",
                         edgecolors="black", linewidths=0.8, label="reversal", zorder=4)
        if not math.isnan(estimate.threshold):
            axes.axhline(estimate.threshold, color=OKABE_ITO["green"], linestyle="--",
                         linewidth=1.2, label=f"estimate {estimate.threshold:.4g}", zorder=2)
        if estimate.method is ThresholdMethod.QUESTPLUS_POSTERIOR \
                and not math.isnan(estimate.ci_low):
            axes.axhspan(estimate.ci_low, estimate.ci_high, color=OKABE_ITO["green"],
                         alpha=0.12, linewidth=0, label="95 % credible interval")
        kind = ("QUEST+" if estimate.method is ThresholdMethod.QUESTPLUS_POSTERIOR
                else "staircase")
        axes.set_title(f"{found.label(estimate)} ({kind}, {estimate.n_trials} trials)",
                       fontsize=8)
        axes.set_ylabel(_parameter_label(found), fontsize=8)
        axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes_list[-1, 0].set_xlabel("trial of the procedure")
    figure.suptitle(f"Adaptive tracks: subject {found.subject}, task {found.task}", fontsize=9)
    return _save(figure, stem, captions.threshold_track(found))


def plot_fit(found: SubjectThresholds, stem: Path) -> list[Path]:
    """The fitted psychometric function over the proportion correct at each intensity, its
    threshold with the credible interval, and the threshold's definition."""
    x = np.array([b.intensity for b in found.bins])
    counts = np.array([b.trials for b in found.bins])
    figure, axes = plt.subplots(figsize=(5.4, 3.8))
    axes.scatter(x, [b.proportion for b in found.bins], s=8 + 90 * counts / counts.max(),
                 color=OKABE_ITO["blue"], alpha=0.75, linewidths=0, zorder=3,
                 label="proportion correct")
    axes.axhline(found.guess_rate, color=CHANCE_COLOUR, linestyle="--", linewidth=1.0,
                 label=f"guess rate {found.guess_rate:g}")
    match found.fit:
        case NotFitted():
            pass
        case fit:
            estimated = fit.status is ThresholdStatus.ESTIMATED
            low = min(float(x.min()), fit.ci_low) if estimated else float(x.min())
            high = max(float(x.max()), fit.ci_high) if estimated else float(x.max())
            grid = np.linspace(max(low, 1e-9) if fit.kind == "weibull" else low, high, 300)
            axes.plot(grid, fit.function.probability(grid), color="black", linewidth=1.2,
                      label=f"{fit.kind} (posterior medians)", zorder=2)
            level = fit.probability_at_threshold
            if estimated:
                axes.axvline(fit.threshold, color=OKABE_ITO["green"], linewidth=1.0,
                             label=f"threshold {fit.threshold:.4g} ({100 * level:.1f} % correct)")
                axes.errorbar([fit.threshold], [level],
                              xerr=[[fit.threshold - fit.ci_low], [fit.ci_high - fit.threshold]],
                              color=OKABE_ITO["green"], capsize=3, linewidth=1.0, fmt="none",
                              label="95 % credible interval")
            else:
                bound = {ThresholdStatus.BELOW: f"\n(below {fit.ci_high:.4g}: 95 % upper bound)",
                         ThresholdStatus.ABOVE: f"\n(above {fit.ci_low:.4g}: 95 % lower bound)"}
                axes.text(0.02, 0.02, f"threshold {fit.status.value}{bound.get(fit.status, '')}",
                          transform=axes.transAxes, fontsize=7, color=OKABE_ITO["vermillion"])
            share = "63.2 %" if fit.kind == "weibull" else "50 %"
            axes.text(1.03, 0.0, f"threshold: {share} of the way\nfrom guess rate {fit.guess:g} "
                      f"to\n1 - lapse rate ({1 - fit.lapse:.2f}):\n{100 * level:.1f} % correct",
                      transform=axes.transAxes, fontsize=6, va="bottom")
    axes.set_ylim(-0.02, 1.02)
    axes.set_xlabel(_parameter_label(found))
    axes.set_ylabel("proportion counted correct")
    axes.set_title(f"Psychometric function: subject {found.subject}, task {found.task}",
                   fontsize=9)
    axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(figure, stem, captions.threshold_fit(found))


FIGURES: dict[str, Callable[[Study, Path], list[Path]]] = {
    "correct_by_frequency": plot_correct_by_frequency,
    "error_types": plot_error_types,
    "confusion_matrix": plot_confusion,
    "pin_accuracy": plot_pin_map,
    "motion": plot_motion,
}


def plot_response(response: MeasuredResponse, stem: Path, title: str) -> list[Path]:
    """A servo's measured response: the achieved stroke (smallest over the cycles, median
    dotted) against frequency, one line per commanded stroke, the commanded one dashed."""
    colours = [OKABE_ITO[c] for c in ("blue", "orange", "green", "purple", "vermillion", "sky")]
    figure, axes = plt.subplots(figsize=(6.0, 4.0))
    strokes = sorted({p.commanded_steps for p in response.points})
    for i, stroke in enumerate(strokes):
        points = sorted((p for p in response.points if p.commanded_steps == stroke),
                        key=lambda p: p.frequency_hz)
        colour = colours[i % len(colours)]
        hz = [p.frequency_hz for p in points]
        axes.plot(hz, [p.achieved_steps for p in points], marker="o", markersize=4,
                  color=colour, label=f"{stroke} steps commanded")
        axes.plot(hz, [p.median_steps for p in points], linestyle=":", color=colour,
                  linewidth=0.8)
        axes.axhline(stroke, color=colour, linestyle="--", linewidth=0.6)
    axes.set_xlabel("frequency (Hz)")
    axes.set_ylabel("achieved stroke (steps)")
    axes.set_ylim(bottom=0)
    axes.set_title(title, fontsize=9)
    axes.legend(fontsize=7, loc="lower left")
    caption = (f"Measured response of pin {response.pin}'s {response.servo} servo (speed "
               f"{response.speed_steps_per_s} steps/s, acceleration register "
               f"{response.acceleration_register}, duty cycle {float(response.duty_cycle):g}, "
               f"{response.cycles} cycles a train): the smallest peak-to-peak of its sampled "
               "position over the cycles (solid), the median (dotted), the commanded stroke "
               "(dashed).")
    return _save(figure, stem, caption)


def plot_stroke_by_frequency(study: Study, stem: Path) -> list[Path]:
    """Each pin's achieved stroke by frequency, as % of the commanded one: the median over the
    trials, bars from the smallest to the largest, one line per pin and commanded stroke."""
    colours = list(OKABE_ITO.values())[1:] + [OKABE_ITO["black"]]
    markers = ["o", "s", "^", "D", "v", "P", "X", "*"]
    rows = study.strokes.rows
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
    axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), ncol=1 + len(lines) // 16)
    return _save(figure, stem, captions.stroke_by_frequency(study))
