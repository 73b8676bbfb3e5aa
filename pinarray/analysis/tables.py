"""CSV tables of a `Study`: subject-level tables with their interval(s) and the trial-pooled one.

Every table says its unit in its columns: ``subject_mean_pct`` and its ``bootstrap``
interval have subjects as the unit (the interval level and the bootstrap's seed and
resample count are columns too, so a table read alone still says how it was made); the
``t`` interval, which may pass 0 or 100 %, is a column only when it was asked for;
``trial_pooled_*`` columns count every trial alike (Wilson interval). Pins, rows and
columns are numbered from 1 (row 1 at the bottom, column 1 on the left), as the lab does.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path

from pinarray.adaptive.posterior import ThresholdStatus
from pinarray.analysis.chance import DIRECTION_CHANCE
from pinarray.analysis.load import RunSelection
from pinarray.analysis.mixed import FitSkipped, FrequencyEffect
from pinarray.analysis.stats import CATEGORIES, Proportion
from pinarray.analysis.strokes import StrokeTable
from pinarray.analysis.study import Study
from pinarray.analysis.subjects import AcrossSubjects, IntervalMethod, IntervalSettings
from pinarray.analysis.thresholds import (
    ALL_SUBJECTS,
    POOLED_PROCEDURES,
    NotFitted,
    SubjectThresholds,
    ThresholdMethod,
    Thresholds,
    fit_method_text,
    parameter_and_unit,
    threshold_definition,
)


def number(value: float, digits: int = 1) -> str:
    """A table cell: fixed decimals, or "n/a" for NaN (BIDS spelling)."""
    return "n/a" if math.isnan(value) else f"{value:.{digits}f}"


def _write(path: Path, header: Sequence[str], rows: Sequence[Sequence[object]]) -> Path:
    with open(path, "w", encoding="utf-8", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(header)
        writer.writerows(rows)
    return path


write_csv = _write  # the lab's paradigms' tables (`pinarray.analysis.lab_report`) too


def _level(settings: IntervalSettings) -> str:
    return f"{100 * settings.level:g}"


def measure_header(settings: IntervalSettings) -> list[str]:
    lv = _level(settings)
    t = [f"t{lv}_low_pct", f"t{lv}_high_pct"] if settings.method is IntervalMethod.T else []
    return ["subjects", "trials", "subject_mean_pct", "subject_sd_pct", *t,
            f"bootstrap{lv}_low_pct", f"bootstrap{lv}_high_pct",
            "bootstrap_seed", "bootstrap_resamples", "trial_pooled_pct",
            "trial_pooled_wilson95_low_pct", "trial_pooled_wilson95_high_pct"]


def measure_cells(m: AcrossSubjects, settings: IntervalSettings) -> list[object]:
    pooled = m.pooled
    t = m.t_interval_pct if settings.method is IntervalMethod.T else ()
    return [m.subjects, m.trials, number(m.mean_pct), number(m.sd_pct),
            *(number(v) for v in t), *(number(v) for v in m.bootstrap_interval_pct),
            settings.bootstrap_seed, settings.bootstrap_resamples, number(pooled.pct),
            *(number(v) for v in pooled.interval_pct)]


def _pct(p: Proportion) -> str:
    return number(p.pct)


def localisation_tables(study: Study, out: Path) -> list[Path]:
    level = study.subject_level
    settings = level.settings
    chance = study.chance.fractions if study.chance else {}
    means = [[f"{row.frequency_hz:g}", category, *measure_cells(row.share(category), settings),
              number(100 * chance[category], 2) if category in chance else "n/a"]
             for row in level.localisation for category in CATEGORIES]
    per_subject = [[s.subjects[0], f"{row.frequency_hz:g}", row.trials,
                    *(row.count(c) for c in CATEGORIES), *(_pct(row.share(c)) for c in CATEGORIES)]
                   for s in study.per_subject for row in s.localisation]
    grid = study.grid
    pins = []
    for pin in grid.pins:
        row, column = grid.cell(pin)
        m = level.pins[pin - 1]
        pins.append([pin, row + 1, column + 1, *measure_cells(m, settings)])
    confusion = study.pooled.confusion
    answers = [f"answer_{p}" for p in grid.pins] + ["nothing_felt"]
    return [
        _write(out / "localisation_subject_level.csv",
               ["frequency_hz", "category", *measure_header(settings), "chance_pct"], means),
        _write(out / "localisation_per_subject.csv",
               ["subject", "frequency_hz", "trials", *CATEGORIES,
                *(f"{c}_pct" for c in CATEGORIES)], per_subject),
        _write(out / "pin_accuracy.csv", ["pin", "row", "column", *measure_header(settings)],
               pins),
        _write(out / "confusion_matrix.csv", ["stimulated_pin", *answers, "trials"],
               [[pin, *confusion[pin - 1], int(confusion[pin - 1].sum())]
                for pin in grid.pins if confusion[pin - 1].sum()]),
    ]


def motion_tables(study: Study, out: Path) -> list[Path]:
    settings = study.subject_level.settings
    motion = study.subject_level.motion
    rows = [["felt_on_wave_trials", *measure_cells(motion.felt, settings), "n/a"],
            ["direction_right_of_felt", *measure_cells(motion.direction_right, settings),
             number(100 * DIRECTION_CHANCE, 2)],
            ["felt_on_no_wave_trials", *measure_cells(motion.no_wave_felt, settings), "n/a"]]
    per_subject = [[s.subjects[0], s.motion.felt.trials, s.motion.felt.successes,
                    _pct(s.motion.felt), s.motion.direction_right.successes,
                    _pct(s.motion.direction_right), s.motion.no_wave_felt.trials,
                    s.motion.no_wave_felt.successes, _pct(s.motion.no_wave_felt)]
                   for s in study.per_subject
                   if s.motion.felt.trials or s.motion.no_wave_felt.trials]
    return [
        _write(out / "motion_subject_level.csv",
               ["measure", *measure_header(settings), "chance_pct"], rows),
        _write(out / "motion_per_subject.csv",
               ["subject", "wave_trials", "felt", "felt_pct", "direction_right",
                "direction_right_pct_of_felt", "no_wave_trials", "no_wave_felt",
                "no_wave_felt_pct"], per_subject),
    ]


def frequency_effect_table(effect: FrequencyEffect | FitSkipped, out: Path) -> Path:
    header = ["model", "status", "subjects", "trials", "odds_ratio_per_doubling",
              "odds_ratio_wald95_low", "odds_ratio_wald95_high", "slope_logit_per_doubling",
              "slope_se", "subject_sd_logit", "lrt_chi2", "lrt_p", "wald_p", "log_likelihood",
              "typical_subject_pct_by_frequency", "note"]
    model = "correct ~ log2(frequency) + (1 | subject), binomial logit, adaptive Gauss-Hermite ML"
    match effect:
        case FrequencyEffect():
            low, high = effect.odds_ratio_interval
            typical = "; ".join(f"{f:g} Hz {p:.1f}" for f, p in
                                zip(effect.frequencies_hz, effect.typical_subject_pct, strict=True))
            row = [model, "fitted" if effect.converged else "fitted, not converged",
                   effect.subjects, effect.trials, number(effect.odds_ratio_per_doubling, 3),
                   number(low, 3), number(high, 3), number(effect.slope_per_doubling, 4),
                   number(effect.slope_se, 4), number(effect.subject_sd_logit, 4),
                   number(effect.lrt_statistic, 3), f"{effect.lrt_p:.3g}", f"{effect.wald_p:.3g}",
                   number(effect.log_likelihood, 3), typical, ""]
        case FitSkipped():
            row = [model, "not fitted", *["n/a"] * 13, effect.reason]
    return _write(out / "frequency_effect.csv", header, [row])


THRESHOLD_COLUMNS = ("subject", "task", "parameter", "unit", "method", "threshold", "ci_low",
                     "ci_high", "n_trials", "procedure", "status", "guess_rate", "lapse_rate",
                     "pct_correct_at_threshold")


def _fit_cells(s: SubjectThresholds) -> list[str]:
    """The fit's threshold, interval, status, guess and lapse rates and the percent correct at
    the threshold: numbers only where the answers place them (`ThresholdStatus`)."""
    match s.fit:
        case NotFitted():
            return ["n/a"] * 3 + ["not fitted", number(s.guess_rate, 3), "n/a", "n/a"]
        case fit:
            estimated = fit.status is ThresholdStatus.ESTIMATED
            low = estimated or fit.status is ThresholdStatus.ABOVE
            high = estimated or fit.status is ThresholdStatus.BELOW
            return [number(fit.threshold if estimated else math.nan, 3),
                    number(fit.ci_low if low else math.nan, 3),
                    number(fit.ci_high if high else math.nan, 3), fit.status.value,
                    number(fit.guess, 3), number(fit.lapse, 3),
                    number(100 * fit.probability_at_threshold, 1)]


def thresholds_table(found: Thresholds, out: Path) -> Path:
    """``thresholds.csv``: each subject's procedures and fit, then the across-subject means
    (subject ``all``, the interval the settings name); thresholds in the parameter's unit.
    Its sidecar ``thresholds.json`` (`thresholds_sidecar`) says what each column is."""
    rows: list[list[object]] = []
    for s in found.per_subject:
        head = [s.subject, s.task, s.parameter, s.unit]
        for estimate in s.procedures:
            rows.append([*head, estimate.method, number(estimate.threshold, 3),
                         number(estimate.ci_low, 3), number(estimate.ci_high, 3),
                         estimate.n_trials, s.label(estimate), "n/a", number(s.guess_rate, 3),
                         "n/a", "n/a"])
        fitted = _fit_cells(s)
        rows.append([*head, s.fit_method, *fitted[:3], s.fit_trials, POOLED_PROCEDURES,
                     *fitted[3:]])
    for m in found.across:
        parameter, unit = parameter_and_unit(m.adapted_parameter)
        rows.append([ALL_SUBJECTS, m.task, parameter, unit, m.method, number(m.mean, 3),
                     *(number(v, 3) for v in m.interval(found.settings.method)), m.n_trials,
                     m.procedure, "n/a", "n/a", "n/a", "n/a"])
    return _write(out / "thresholds.csv", THRESHOLD_COLUMNS, rows)


def thresholds_sidecar(found: Thresholds, out: Path) -> Path:
    """``thresholds.json``: each column of thresholds.csv described (BIDS style:
    Description, Units, Levels), the fit's method and the threshold's definition."""
    units = sorted({s.unit for s in found.per_subject})
    guesses = sorted({s.guess_rate for s in found.per_subject})
    kinds = sorted({s.fit.kind for s in found.per_subject if not isinstance(s.fit, NotFitted)})
    intensity = "the adapted parameter's unit (column unit)"
    columns = {
        "subject": {"Description": f"the subject; {ALL_SUBJECTS}: the across-subject mean"},
        "task": {"Description": "the task of the adaptive design"},
        "parameter": {"Description": "the adapted parameter, without its unit"},
        "unit": {"Description": "the adapted parameter's unit", "Levels": units},
        "method": {"Description": "where the threshold comes from", "Levels": {
            ThresholdMethod.REVERSAL_MEAN.value: "a staircase's mean of its last reversals: the "
            "intensity its rule converges on (1-up/2-down: 70.7 % correct), not the fit's "
            "threshold",
            ThresholdMethod.QUESTPLUS_POSTERIOR.value: "QUEST+'s posterior mean over its own "
            "grid, with its 95 % credible interval",
            ThresholdMethod.BAYES_WEIBULL.value: fit_method_text("weibull"),
            ThresholdMethod.BAYES_LOGISTIC.value: fit_method_text("logistic") + " (where an "
            "intensity is 0 or below)"}},
        "threshold": {"Description": "the threshold; for the fit, " + "; ".join(
            threshold_definition(kind, guess) for kind in kinds or ["weibull"]
            for guess in guesses) + "; n/a where the status gives words instead",
            "Units": intensity},
        "ci_low": {"Description": "the 2.5 % point of the 95 % interval (for status 'above the "
                   "highest value tested': the threshold is above it with 95 % posterior "
                   "probability); n/a where there is none", "Units": intensity},
        "ci_high": {"Description": "the 97.5 % point of the 95 % interval (for status 'below "
                    "the lowest value tested': the threshold is below it with 95 % "
                    "posterior probability); n/a where there is none", "Units": intensity},
        "n_trials": {"Description": "the counted trials behind the number"},
        "procedure": {"Description": f"the procedure; {POOLED_PROCEDURES}: the fit over all of "
                      "the subject's procedures"},
        "status": {"Description": "whether the subject's answers place the fit's threshold",
                   "Levels": {
                       ThresholdStatus.ESTIMATED.value: "a threshold and its 95 % interval",
                       ThresholdStatus.BELOW.value: "the answers cannot bound it from below "
                       "(e.g. every answer right): only ci_high, an upper bound",
                       ThresholdStatus.ABOVE.value: "the answers cannot bound it from above "
                       "(e.g. every answer at chance or wrong): only ci_low, a lower bound",
                       ThresholdStatus.NOT_ESTIMABLE.value: "the answers bound it neither "
                       "from below nor from above",
                       "not fitted": "no fit (the report says why)",
                       "n/a": "a procedure's own estimate or an across-subject mean"}},
        "guess_rate": {"Description": "the guess rate as the rows state it (0 to 1)"},
        "lapse_rate": {"Description": "the fit's lapse rate, the median of its posterior (0 "
                       "to 1)"},
        "pct_correct_at_threshold": {"Description": "the fitted function's percent correct "
                                     "at its threshold (guess rate and fitted lapse rate)",
                                     "Units": "%"},
    }
    path = out / "thresholds.json"
    path.write_text(json.dumps(columns, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


STROKE_COLUMNS = ("pin", "frequency_hz", "stroke_commanded_steps", "stroke_commanded_mm",
                  "achieved_min_steps", "achieved_median_steps", "achieved_max_steps",
                  "achieved_min_mm", "achieved_median_mm", "achieved_max_mm",
                  "achieved_min_pct_of_commanded", "achieved_median_pct_of_commanded",
                  "n_trials", "n_short")


def stroke_table(strokes: StrokeTable, out: Path) -> Path:
    """``stroke_by_frequency.csv``: each pin's achieved stroke (each trial's smallest
    peak-to-peak over its cycles) over the trials at each frequency, in steps, mm and % of
    the commanded stroke; ``n_short``: trials with a cycle below the stroke tolerance."""
    rows = []
    for r in strokes.rows:
        achieved = (r.achieved_min_steps, r.achieved_median_steps, r.achieved_max_steps)
        rows.append([r.pin, f"{r.frequency_hz:g}", r.commanded_steps,
                     number(r.mm(r.commanded_steps), 3), r.achieved_min_steps,
                     f"{r.achieved_median_steps:g}", r.achieved_max_steps,
                     *(number(r.mm(steps), 3) for steps in achieved),
                     number(r.share_pct(r.achieved_min_steps)),
                     number(r.share_pct(r.achieved_median_steps)), r.n_trials, r.n_short])
    return _write(out / "stroke_by_frequency.csv", STROKE_COLUMNS, rows)


def runs_table(runs: RunSelection, out: Path) -> Path:
    rows = []
    for run, included in ([(r, True) for r in runs.included]
                          + [(r, False) for r in runs.excluded]):
        p = run.paths
        rows.append([p.subject, p.session, p.task, p.run, run.source, run.status, run.counted,
                     " ".join(map(str, run.duplicates)), "yes" if included else "no",
                     run.incomplete_reason or ""])
    rows.sort(key=lambda r: str(r[4]))
    return _write(out / "runs.csv", ["subject", "session", "task", "run", "file",
                                     "manifest_status", "counted_trials",
                                     "trials_finished_twice", "included", "incomplete_reason"],
                  rows)


def write_tables(study: Study, out: Path) -> list[Path]:
    """Every table for which there are trials, and the runs table always."""
    tables = []
    if study.pooled.localisation:
        tables += localisation_tables(study, out)
        tables.append(frequency_effect_table(study.frequency_effect, out))
    if study.motion_trials:
        tables += motion_tables(study, out)
    if study.thresholds.found:
        tables.append(thresholds_table(study.thresholds, out))
        tables.append(thresholds_sidecar(study.thresholds, out))
    if study.strokes.rows:
        tables.append(stroke_table(study.strokes, out))
    tables.append(runs_table(study.runs, out))
    return tables
