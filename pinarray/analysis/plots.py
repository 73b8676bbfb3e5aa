"""Figures beside the paradigms' own: an adaptive design's tracks and fitted functions, power
curves, and a servo's measured response; in the house's style (`pinarray.analysis.figures`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pinarray.adaptive.posterior import ThresholdStatus
from pinarray.analysis import captions
from pinarray.analysis.figures import CHANCE_COLOUR, OKABE_ITO, plt, save
from pinarray.analysis.tables import significant
from pinarray.analysis.thresholds import NotFitted, SubjectThresholds, ThresholdMethod
from pinarray.protocol.response import MeasuredResponse


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
    return save(figure, stem, caption)


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
                         linewidth=1.2, label=f"estimate {significant(estimate.threshold)}", zorder=2)
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
    return save(figure, stem, captions.threshold_track(found))


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
                             label=f"threshold {significant(fit.threshold)} ({100 * level:.1f} % correct)")
                axes.errorbar([fit.threshold], [level],
                              xerr=[[fit.threshold - fit.ci_low], [fit.ci_high - fit.threshold]],
                              color=OKABE_ITO["green"], capsize=3, linewidth=1.0, fmt="none",
                              label="95 % credible interval")
            else:
                bound = {ThresholdStatus.BELOW: f"\n(below {significant(fit.ci_high)}: 95 % upper bound)",
                         ThresholdStatus.ABOVE: f"\n(above {significant(fit.ci_low)}: 95 % lower bound)"}
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
    return save(figure, stem, captions.threshold_fit(found))


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
    return save(figure, stem, caption)
