"""The lab's paradigms in the analysis folder: their CSV tables and their sections of
``summary.md`` (identification; two intervals; temporal order), and their figures' captions
(the figures: `lab_plots`, which imports matplotlib)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from pinarray.analysis.identification import AcrossIdentification, Identifications
from pinarray.analysis.judgements import IntervalFit, Judgements, OrderFit
from pinarray.analysis.subjects import IntervalSettings
from pinarray.analysis.tables import number, write_csv
from pinarray.analysis.thresholds import ALL_SUBJECTS, NotFitted, parameter_and_unit

IDENTIFICATION_COLUMNS = ("subject", "task", "n_trials", "percent_correct", "it_bits",
                          "it_bias_bits", "it_corrected_bits", "it_max_bits", "ci_low", "ci_high")
CONFUSION_COLUMNS = ("task", "presented", "answered", "n_trials", "percent_of_presented")
TWO_INTERVAL_COLUMNS = ("subject", "task", "parameter", "unit", "standard", "threshold",
                        "ci_low", "ci_high", "weber_fraction", "weber_ci_low", "weber_ci_high",
                        "difference_75pct", "n_trials")
TEMPORAL_ORDER_COLUMNS = ("subject", "task", "pins", "pss_ms", "pss_ci_low", "pss_ci_high",
                          "jnd_ms", "n_trials")


def _n(value: float, digits: int = 3) -> str:
    return number(value, digits)


def lab_tables(identification: Identifications, judgements: Judgements,
               settings: IntervalSettings, out: Path) -> list[Path]:
    """``identification.csv`` and ``identification_confusion.csv``, ``two_interval.csv``,
    ``temporal_order.csv``: each subject's row, then the across-subject means (subject
    ``all``, with the interval the settings name in ``ci_low``/``ci_high``)."""
    tables = []
    if identification.found:
        rows: list[list[object]] = []
        for s in identification.per_subject:
            c = s.confusion
            rows.append([s.subject, s.task, c.trials, _n(c.percent_correct, 1), _n(c.it_bits),
                         _n(c.it_bias_bits), _n(c.it_corrected_bits), _n(c.it_max_bits), "", ""])
        for a in identification.across:
            for measure, mean, (low, high) in a.means:
                row = {"percent_correct": "", "it_bits": "", "it_corrected_bits": ""}
                row[measure] = _n(mean, 1 if measure == "percent_correct" else 3)
                rows.append([ALL_SUBJECTS, a.task, a.trials, row["percent_correct"],
                             row["it_bits"], "", row["it_corrected_bits"],
                             _n(a.pooled.it_max_bits), _n(low), _n(high)])
        tables.append(write_csv(out / "identification.csv", IDENTIFICATION_COLUMNS, rows))
        cells = []
        for a in identification.across:
            percent = a.pooled.row_percentages()
            for i, presented in enumerate(a.pooled.presented):
                for j, answered in enumerate(a.pooled.answered):
                    cells.append([a.task, presented, answered, int(a.pooled.counts[i, j]),
                                  _n(float(percent[i, j]), 1)])
        tables.append(write_csv(out / "identification_confusion.csv", CONFUSION_COLUMNS, cells))
    if judgements.intervals:
        rows = [[f.subject, f.task, *parameter_and_unit(f.compared), f"{f.standard:g}",
                 *map(_n, f.threshold), *map(_n, f.weber), _n(f.difference_75), f.trials]
                for f in judgements.intervals]
        for m in judgements.across:
            if m.measure == "weber_fraction":
                rows.append([ALL_SUBJECTS, m.task, "", "", "", "", "", "", _n(m.mean),
                             *map(_n, m.interval), "", _trials(judgements, m.task)])
        tables.append(write_csv(out / "two_interval.csv", TWO_INTERVAL_COLUMNS, rows))
    if judgements.orders:
        rows = [[f.subject, f.task, " ".join(map(str, f.pins)), *map(_n, f.pss), _n(f.jnd_ms),
                 f.trials] for f in judgements.orders]
        across = {(m.task, m.measure): m for m in judgements.across}
        for task in sorted({f.task for f in judgements.orders}):
            pss, jnd = across[(task, "pss_ms")], across[(task, "jnd_ms")]
            rows.append([ALL_SUBJECTS, task, "", _n(pss.mean), *map(_n, pss.interval),
                         _n(jnd.mean), _trials(judgements, task)])
        tables.append(write_csv(out / "temporal_order.csv", TEMPORAL_ORDER_COLUMNS, rows))
    return tables


def _trials(judgements: Judgements, task: str) -> int:
    fits: list[IntervalFit | OrderFit] = [*judgements.intervals, *judgements.orders]
    return sum(f.trials for f in fits if f.task == task)


def _row(cells: Sequence[object]) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def _interval(low: float, high: float) -> str:
    return "n/a (one subject)" if math.isnan(low) else f"[{_n(low)}, {_n(high)}]"


def lab_sections(identification: Identifications, judgements: Judgements,
                 settings: IntervalSettings) -> list[str]:
    """The summary's sections of the lab's paradigms (none without their rows)."""
    lines: list[str] = []
    if identification.found:
        lines += ["## Identification", "",
                  "Per subject: percent correct and the information transferred (IT, bits) "
                  "from the confusion matrix of patterns presented and answers given. IT is "
                  "biased upward when there are few trials per cell (Miller 1955): its "
                  "first-order bias, (R - 1)(C - 1) / (2 n ln 2) bits for R patterns, C "
                  "answers and n trials, is given beside it, and subtracted in the corrected "
                  f"IT; read both as bounds. Across subjects: the mean with the "
                  f"{settings.describe()}.", "",
                  _row(["task", "subjects", "trials", "percent correct", "IT (bits)",
                        "IT corrected (bits)", "IT max (bits)"]), "|---" * 7 + "|"]
        for a in identification.across:
            means = {m: (mean, interval) for m, mean, interval in a.means}
            cells = [f"{_n(means[m][0], 1 if m == 'percent_correct' else 3)} "
                     f"{_interval(*means[m][1])}" for m in ("percent_correct", "it_bits",
                                                            "it_corrected_bits")]
            lines.append(_row([a.task, a.subjects, a.trials, *cells, _n(a.pooled.it_max_bits)]))
        lines += ["", "Per subject, and the pooled confusion matrices: "
                  "[identification.csv](identification.csv), "
                  "[identification_confusion.csv](identification_confusion.csv).", ""]
    if judgements.intervals:
        lines += ["## Two intervals", "",
                  "Per subject and standard: a Weibull fit (guess rate 1/2, lapse fitted within "
                  "0-0.1) of the proportion naming the interval with the higher value against "
                  "the difference from the standard, through the adaptive designs' fitting; its "
                  "threshold (81.6 % correct without lapses) with a "
                  f"{judgements.resamples}-resample parametric bootstrap interval (seed "
                  f"{judgements.seed}); the Weber fraction is the threshold over the standard. "
                  f"Across subjects: the mean with the {settings.describe()}.", "",
                  _row(["subject", "task", "standard", "threshold", "Weber fraction",
                        "75 % difference", "trials"]), "|---" * 7 + "|"]
        for f in judgements.intervals:
            name, unit = parameter_and_unit(f.compared)
            threshold, low, high = f.threshold
            weber = f.weber
            lines.append(_row([f.subject, f.task, f"{name} {f.standard:g} {unit}",
                               f"{_n(threshold)} {_interval(low, high)}",
                               f"{_n(weber[0])} {_interval(*weber[1:])}",
                               _n(f.difference_75), f.trials]))
        for m in judgements.across:
            if m.measure == "weber_fraction":
                lines.append(_row([ALL_SUBJECTS, m.task, "", "",
                                   f"{_n(m.mean)} {_interval(*m.interval)}", "",
                                   _trials(judgements, m.task)]))
        lines += [*_not_fitted(judgements.intervals), "",
                  "[two_interval.csv](two_interval.csv).", ""]
    if judgements.orders:
        lines += ["## Temporal order", "",
                  "Per subject: a logistic fit (guess and lapse rates 0) of the proportion "
                  "naming pin A (the first the protocol lists) first against the SOA (B's onset "
                  "minus A's), through the adaptive designs' fitting. PSS: its 50 % point, "
                  f"with a {judgements.resamples}-resample parametric bootstrap interval; JND: "
                  "half the distance between its 25 % and 75 % points. Across subjects: the "
                  f"mean with the {settings.describe()}.", "",
                  _row(["subject", "task", "pins (A B)", "PSS (ms)", "JND (ms)", "trials"]),
                  "|---" * 6 + "|"]
        for order in judgements.orders:
            pss, low, high = order.pss
            lines.append(_row([order.subject, order.task, " ".join(map(str, order.pins)),
                               f"{_n(pss, 1)} {_interval(low, high)}", _n(order.jnd_ms, 1),
                               order.trials]))
        across = {(m.task, m.measure): m for m in judgements.across}
        for task in sorted({f.task for f in judgements.orders}):
            pss_m, jnd_m = across[(task, "pss_ms")], across[(task, "jnd_ms")]
            lines.append(_row([ALL_SUBJECTS, task, "",
                               f"{_n(pss_m.mean, 1)} {_interval(*pss_m.interval)}",
                               f"{_n(jnd_m.mean, 1)} {_interval(*jnd_m.interval)}",
                               _trials(judgements, task)]))
        lines += [*_not_fitted(judgements.orders), "",
                  "[temporal_order.csv](temporal_order.csv).", ""]
    return lines


def lab_lines(identification: Identifications, judgements: Judgements) -> list[str]:
    """What `pinarray analyse` prints of the lab's paradigms: each task's across-subject means
    (the tables and summary.md give the intervals)."""
    lines = []
    for a in identification.across:
        means = {m: mean for m, mean, _ in a.means}
        lines.append(f"identification {a.task}: {_n(means['percent_correct'], 1)} % correct, "
                     f"information transferred {_n(means['it_bits'])} bits (corrected for its "
                     f"small-sample bias {_n(means['it_corrected_bits'])}) of "
                     f"{_n(a.pooled.it_max_bits)}, mean of {a.subjects} subject(s)")
    for m in judgements.across:
        if m.measure == "threshold":
            continue
        name = {"weber_fraction": "two intervals", "pss_ms": "temporal order",
                "jnd_ms": "temporal order"}[m.measure]
        lines.append(f"{name} {m.task}: mean {m.measure} {_n(m.mean)} over "
                     f"{len(m.per_subject)} subject(s)")
    return lines


def _not_fitted(fits: Sequence) -> list[str]:
    return ([""] + [f"- subject {f.subject}, task {f.task}: no fit: {f.fit.reason}"
                    for f in fits if isinstance(f.fit, NotFitted)]
            if any(isinstance(f.fit, NotFitted) for f in fits) else [])


# -- captions ----------------------------------------------------------------------------


def identification_caption(a: AcrossIdentification, settings: IntervalSettings) -> str:
    pooled = a.pooled
    return (f"Identification, task {a.task}: confusion matrix, trial-pooled (unit: trial; "
            f"N = {a.subjects} subject(s), {a.trials} trials). Each row is one pattern "
            f"presented and adds up to 100 % of its trials. Pooled: {pooled.percent_correct:.1f} "
            f"% correct, information transferred {pooled.it_bits:.2f} bits of "
            f"{pooled.it_max_bits:.2f} (biased upward by about {pooled.it_bias_bits:.2f} bits "
            f"with this many trials per cell). Subject-level means with the "
            f"{settings.describe()} are in summary.md. Counted: main trials with status ok.")


def two_interval_caption(task: str, judgements: Judgements, settings: IntervalSettings) -> str:
    fits = [f for f in judgements.intervals if f.task == task]
    weber = next(m for m in judgements.across if m.task == task and m.measure == "weber_fraction")
    return (f"Two-interval discrimination, task {task}: per subject, the proportion of "
            f"trials naming the interval with the higher value at each difference from the "
            f"standard (dot area: trials) and its Weibull fit (guess rate 1/2, dashed). "
            f"Mean Weber fraction {weber.mean:.3f} over {len(weber.per_subject)} subject(s) "
            f"({settings.describe()} in summary.md); "
            f"{sum(f.trials for f in fits)} trials. Counted: main trials with status ok.")


def temporal_order_caption(task: str, judgements: Judgements, settings: IntervalSettings) -> str:
    fits = [f for f in judgements.orders if f.task == task]
    measures = {m.measure: m for m in judgements.across if m.task == task}
    return (f"Temporal-order judgement, task {task}: per subject, the proportion of trials "
            f"naming pin A ({fits[0].pins[0]}) first at each SOA (dot area: trials) and its "
            f"logistic fit (guess and lapse rates 0). Mean PSS {measures['pss_ms'].mean:.1f} "
            f"ms, mean JND {measures['jnd_ms'].mean:.1f} ms over "
            f"{len(measures['pss_ms'].per_subject)} subject(s) ({settings.describe()} in "
            f"summary.md); {sum(f.trials for f in fits)} trials. Counted: main trials with "
            "status ok.")


def lab_captions(identification: Sequence[AcrossIdentification], judgements: Judgements,
                 settings: IntervalSettings) -> dict[str, str]:
    """Each figure of `lab_figures` by its file's stem, with its caption."""
    found = {f"identification_{a.task}": identification_caption(a, settings)
             for a in identification}
    for task in {f.task for f in judgements.intervals}:
        found[f"two_interval_{task}"] = two_interval_caption(task, judgements, settings)
    for task in {f.task for f in judgements.orders}:
        found[f"temporal_order_{task}"] = temporal_order_caption(task, judgements, settings)
    return found
