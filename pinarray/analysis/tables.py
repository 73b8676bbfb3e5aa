"""CSV tables of an analysis: their cells, the adaptive designs' thresholds, the runs counted.

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
from pinarray.analysis.load import RunSelection
from pinarray.analysis.stats import Proportion
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
    """A table cell: fixed decimals, or "n/a" for NaN (BIDS spelling); never "-0.000" (a
    value that rounds to zero is zero, whichever side it came from)."""
    return "n/a" if math.isnan(value) else _unsigned_zero(f"{value:.{digits}f}")


def significant(value: float, digits: int = 4) -> str:
    """A number in words or on a figure: ``digits`` significant digits (``g``), or "n/a"
    for NaN; never "-0" (as `number`). Every number `pinarray analyse` writes goes through
    this or `number`."""
    return "n/a" if math.isnan(value) else _unsigned_zero(f"{value:.{digits}g}")


def _unsigned_zero(text: str) -> str:
    """``text`` without the minus of a number shown as zero (``-0.0``: a small negative
    value rounded, or IEEE's negative zero)."""
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text


def _write(path: Path, header: Sequence[str], rows: Sequence[Sequence[object]]) -> Path:
    with open(path, "w", encoding="utf-8", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(header)
        writer.writerows(rows)
    return path


write_csv = _write  # every paradigm's tables too (its room's)


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


def write_tables(thresholds: Thresholds, runs: RunSelection, out: Path) -> list[Path]:
    """The adaptive designs' thresholds table (and its sidecar) if there are any, and the
    runs table always (each paradigm writes its own: `pinarray.analysis.seam.Findings`)."""
    tables = []
    if thresholds.found:
        tables.append(thresholds_table(thresholds, out))
        tables.append(thresholds_sidecar(thresholds, out))
    tables.append(runs_table(runs, out))
    return tables


# -- cells of the summary's tables -----------------------------------------------------------


def interval_text(interval: tuple[float, float]) -> str:
    """An across-subject interval of percentages, or why there is none."""
    low, high = interval
    return "n/a (one subject)" if math.isnan(low) else f"[{number(low)}, {number(high)}]"


def pooled_text(p: Proportion) -> str:
    """A trial-pooled percentage with its Wilson interval and counts."""
    return f"{number(p.pct)} % {interval_text(p.interval_pct)} ({p.successes}/{p.trials})"


def measure_text(m: AcrossSubjects, method: IntervalMethod) -> str:
    """``mean % [interval] (N subjects, n trials)``, the chosen interval."""
    return (f"{number(m.mean_pct)} % {interval_text(m.interval_pct(method))} "
            f"({m.subjects} subj., {m.trials} trials)")


def interval_heads(settings: IntervalSettings) -> list[str]:
    """The subject-level interval columns: the bootstrap, and the t interval if asked for."""
    t = ["t interval (may pass 0-100 %)"] if settings.method is IntervalMethod.T else []
    return [*t, "bootstrap interval"]


def interval_cells(m: AcrossSubjects, settings: IntervalSettings) -> list[str]:
    """A measure's cells under `interval_heads`."""
    t = [interval_text(m.t_interval_pct)] if settings.method is IntervalMethod.T else []
    return [*t, interval_text(m.bootstrap_interval_pct)]


def markdown_row(cells: Sequence[object]) -> str:
    """One row of a Markdown table."""
    return "| " + " | ".join(map(str, cells)) + " |"
