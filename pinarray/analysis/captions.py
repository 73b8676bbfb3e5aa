"""Figure captions: what is drawn, N (subjects and trials), the unit, and the interval method.

Captions are plain text, written under each figure and into ``summary.md``, so a figure taken
out of the report still says what it shows.
"""

from __future__ import annotations

import math

from pinarray.adaptive.posterior import ThresholdStatus
from pinarray.analysis.chance import DIRECTION_CHANCE
from pinarray.analysis.study import Study
from pinarray.analysis.subjects import AcrossSubjects
from pinarray.analysis.thresholds import (
    NotFitted,
    SubjectThresholds,
    Thresholds,
    fit_method_text,
    threshold_definition,
)

COUNTED = "Counted: main trials with status ok."


def _n(measure: AcrossSubjects) -> str:
    return f"N = {measure.subjects} subject(s), {measure.trials} trials"


def _localisation_n(study: Study) -> str:
    level = study.subject_level
    return (f"N = {len(level.localisation_subjects)} subject(s), "
            f"{study.localisation_trials} trials")


def correct_by_frequency(study: Study) -> str:
    settings = study.subject_level.settings
    chance = study.chance
    chance_text = f" Dashed line: {chance.definition()}." if chance else ""
    return (f"Correct localisation by frequency. Bars: mean of per-subject percentages "
            f"(unit: subject; {_localisation_n(study)}); error bars: {settings.describe()}; "
            f"grey lines: individual subjects; under each bar: its mean, subjects and "
            f"trials.{chance_text} {COUNTED}")


def error_types(study: Study) -> str:
    settings = study.subject_level.settings
    return (f"Localisation answers by type, % of all trials at each frequency (correct answers "
            f"are the rest). A: adjacent on the same row or column; B: diagonal neighbour; "
            f"C: same row or column, not adjacent; D: neither; nothing felt: no pin named. "
            f"Bars: mean of per-subject percentages (unit: subject; {_localisation_n(study)}); "
            f"error bars: {settings.describe()}. Black ticks: chance share of each error class "
            f"for a subject naming any of {len(study.chance.answer_pins) if study.chance else 0} "
            f"pins at random, averaged over the stimulated pins. {COUNTED}")


def confusion_matrix(study: Study) -> str:
    return (f"Confusion matrix, trial-pooled: every trial of every subject counted together "
            f"(unit: trial; {_localisation_n(study)}, all frequencies). Each row is one "
            f"stimulated pin and adds up to 100 % of its trials, including the 'nothing felt' "
            f"column. Pins numbered 1-16 as the subject feels them (1 bottom-left). {COUNTED}")


def pin_accuracy(study: Study) -> str:
    return (f"Correct localisation per pin, drawn as the subject feels the grid (pin 1 "
            f"bottom-left, pin numbers 1-based). Each cell: mean of per-subject percentages "
            f"for that pin (unit: subject; {_localisation_n(study)}, all frequencies); grey "
            f"cells were never stimulated. {COUNTED}")


def motion(study: Study) -> str:
    settings = study.subject_level.settings
    level = study.subject_level.motion
    return (f"Apparent motion. Bars: mean of per-subject percentages (unit: subject); error "
            f"bars: {settings.describe()}; under each bar: its mean, subjects and trials; "
            f"grey dots: individual subjects. Felt a moving dot: % of wave trials "
            f"({_n(level.felt)}). Direction right: % of the wave trials on which motion was "
            f"felt ({_n(level.direction_right)}); dashed line: chance "
            f"{100 * DIRECTION_CHANCE:.0f} % (left or right named at random; 'unsure' counts "
            f"as not right). Felt on no-wave trials: the false-alarm baseline "
            f"({_n(level.no_wave_felt)}). {COUNTED}")


def stroke_by_frequency(study: Study) -> str:
    rows = study.strokes.rows
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


CAPTIONS = {
    "correct_by_frequency": correct_by_frequency,
    "error_types": error_types,
    "confusion_matrix": confusion_matrix,
    "pin_accuracy": pin_accuracy,
    "motion": motion,
    "stroke_by_frequency": stroke_by_frequency,
}


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
