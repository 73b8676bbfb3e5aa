"""Figure captions of the adaptive designs' figures: what is drawn, N (trials), the method.

Captions are plain text, written under each figure and into ``summary.md``, so a figure taken
out of the report still says what it shows; each paradigm's room captions its own figures.
"""

from __future__ import annotations

from pinarray.adaptive.posterior import ThresholdStatus
from pinarray.analysis.thresholds import (
    NotFitted,
    SubjectThresholds,
    Thresholds,
    fit_method_text,
    threshold_definition,
)

COUNTED = "Counted: main trials with status ok."


def threshold_track(found: SubjectThresholds) -> str:
    unit = "" if found.unit == "n/a" else f" ({found.unit})"
    return (f"Adaptive tracks of subject {found.subject}, task {found.task}: the "
            f"{found.parameter}{unit} presented on each counted trial of each procedure, in "
            f"the procedure's own order. Filled circles: answers counted correct; crosses: "
            f"wrong; rings: staircase reversals. Dashed line: the procedure's final estimate "
            f"(staircase: mean of its last reversals; QUEST+: posterior mean, shaded: its 95 % "
            f"credible interval). Catch trials move no procedure and are not drawn. {COUNTED}")


def threshold_fit(found: SubjectThresholds) -> str:
    unit = "" if found.unit == "n/a" else f" ({found.unit})"
    match found.fit:
        case NotFitted(reason=reason):
            fitted = f"No function fitted: {reason}."
        case fit:
            where = ("vertical line: the threshold, bar: its 95 % credible interval"
                     if fit.status is ThresholdStatus.ESTIMATED
                     else f"no threshold drawn: {fit.status.value}")
            fitted = (f"Line: the {fit.kind} at the posterior medians of threshold, slope and "
                      f"lapse rate ({fit.lapse:.2f}); {where}. Threshold: "
                      f"{threshold_definition(fit.kind, fit.guess)}. Method: "
                      f"{fit_method_text(fit.kind)}.")
    return (f"Psychometric function of subject {found.subject}, task {found.task}: proportion "
            f"of answers counted correct at each {found.parameter}{unit}, every procedure's "
            f"counted trials pooled ({found.fit_trials} trials); marker area grows with the "
            f"trials at that intensity. {fitted} Dashed line: the guess rate. {COUNTED}")


def threshold_captions(thresholds: Thresholds) -> dict[str, str]:
    """The caption of every threshold figure, by its file name without the extension."""
    captions = {}
    for found in thresholds.per_subject:
        captions[f"track_{found.stem}"] = threshold_track(found)
        captions[f"fit_{found.stem}"] = threshold_fit(found)
    return captions
