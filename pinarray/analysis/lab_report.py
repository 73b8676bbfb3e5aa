"""The lab's paradigms in the analysis folder: their CSV tables and their sections of
``summary.md`` (identification; two intervals; temporal order), and their figures' captions
(the figures: `lab_plots`, which imports matplotlib)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from pinarray.adaptive.posterior import ThresholdStatus
from pinarray.analysis.identification import AcrossIdentification, Identifications
from pinarray.analysis.judgements import (
    NOT_FITTED,
    Estimate,
    IntervalFit,
    JndStatus,
    Judgements,
    OrderFit,
    method_text,
)
from pinarray.analysis.subjects import IntervalSettings
from pinarray.analysis.tables import number, write_csv
from pinarray.analysis.thresholds import (
    ALL_SUBJECTS,
    NotFitted,
    interval_name,
    parameter_and_unit,
)

IDENTIFICATION_COLUMNS = ("subject", "task", "n_trials", "percent_correct", "it_bits",
                          "it_bias_bits", "it_corrected_bits", "it_max_bits", "ci_low", "ci_high")
CONFUSION_COLUMNS = ("task", "presented", "answered", "n_trials", "percent_of_presented")
TWO_INTERVAL_COLUMNS = ("subject", "task", "parameter", "unit", "standard", "threshold",
                        "ci_low", "ci_high", "status", "weber_fraction", "weber_ci_low",
                        "weber_ci_high", "difference_75pct", "n_trials")
TEMPORAL_ORDER_COLUMNS = ("subject", "task", "pins", "pss_ms", "pss_ci_low", "pss_ci_high",
                          "pss_status", "jnd_ms", "jnd_ci_low", "jnd_ci_high", "jnd_status",
                          "n_trials")


def _n(value: float, digits: int = 3) -> str:
    return number(value, digits)


def lab_tables(identification: Identifications, judgements: Judgements,
               settings: IntervalSettings, out: Path) -> list[Path]:
    """``identification.csv`` and ``identification_confusion.csv``, ``two_interval.csv``,
    ``temporal_order.csv`` (each of the last two with its sidecar, `judgement_sidecar`): each
    subject's row, then the across-subject means (subject ``all``, with the interval the
    settings name in ``ci_low``/``ci_high``)."""
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
                 *map(_n, f.threshold.numbers), f.threshold.words,
                 *map(_n, f.weber.numbers), _n(f.difference_75),
                 f.trials] for f in judgements.intervals]
        for m in judgements.across:
            if m.measure == "weber_fraction":
                rows.append([ALL_SUBJECTS, m.task, "", "", "", "", "", "", "n/a", _n(m.mean),
                             *map(_n, m.interval), "", _trials(judgements, m.task)])
        tables.append(write_csv(out / "two_interval.csv", TWO_INTERVAL_COLUMNS, rows))
        tables.append(judgement_sidecar("two_interval", out))
    if judgements.orders:
        rows = [[f.subject, f.task, " ".join(map(str, f.pins)), *map(_n, f.pss.numbers),
                 f.pss.words, *map(_n, f.jnd.numbers), f.jnd.words, f.trials]
                for f in judgements.orders]
        across = {(m.task, m.measure): m for m in judgements.across}
        for task in sorted({f.task for f in judgements.orders}):
            pss, jnd = across[(task, "pss_ms")], across[(task, "jnd_ms")]
            rows.append([ALL_SUBJECTS, task, "", _n(pss.mean), *map(_n, pss.interval), "n/a",
                         _n(jnd.mean), *map(_n, jnd.interval), "n/a",
                         _trials(judgements, task)])
        tables.append(write_csv(out / "temporal_order.csv", TEMPORAL_ORDER_COLUMNS, rows))
        tables.append(judgement_sidecar("temporal_order", out))
    return tables


_ACROSS = (f"; for subject {ALL_SUBJECTS}, the mean over the subjects whose value is a number, "
           "with the across-subject interval the summary names")
_THRESHOLD_WORDS = {
    ThresholdStatus.ESTIMATED.value: "a value and its 95 % credible interval",
    ThresholdStatus.BELOW.value: "the answers cannot bound it from below (e.g. every answer "
    "right): only its upper bound, one-sided 95 %",
    ThresholdStatus.ABOVE.value: "the answers cannot bound it from above (e.g. every answer "
    "at chance): only its lower bound, one-sided 95 %",
    ThresholdStatus.NOT_ESTIMABLE.value: "the answers bound it neither from below nor from "
    "above", NOT_FITTED: "no fit (summary.md says why)", "n/a": "an across-subject mean"}


def _bounds(name: str, unit: str) -> dict[str, dict[str, object]]:
    return {f"{name}ci_low": {"Description": "the 2.5 % point of the 95 % credible interval "
                              "(one-sided 95 % lower bound where the status says 'above'); "
                              "n/a where there is none" + _ACROSS, "Units": unit},
            f"{name}ci_high": {"Description": "the 97.5 % point of the 95 % credible interval "
                               "(one-sided 95 % upper bound where the status says 'below'); "
                               "n/a where there is none" + _ACROSS, "Units": unit}}


def judgement_sidecar(paradigm: str, out: Path) -> Path:
    """``two_interval.json`` or ``temporal_order.json``: each column of its table described
    (BIDS style: Description, Units, Levels), with the fit's method."""
    method = method_text(paradigm)
    columns: dict[str, dict[str, object]] = {
        "subject": {"Description": f"the subject; {ALL_SUBJECTS}: the across-subject mean"},
        "task": {"Description": "the task"}}
    if paradigm == "two_interval":
        unit = "the compared parameter's unit (column unit)"
        columns |= {
            "parameter": {"Description": "the parameter the intervals differ in"},
            "unit": {"Description": "its unit"},
            "standard": {"Description": "the standard's value", "Units": unit},
            "threshold": {"Description": "the difference threshold: " + method + "; n/a where "
                          "the status gives words instead", "Units": unit},
            **_bounds("", unit),
            "status": {"Description": "whether the answers place the threshold (and so the "
                       "Weber fraction)", "Levels": _THRESHOLD_WORDS},
            "weber_fraction": {"Description": "the threshold over the standard" + _ACROSS},
            **_bounds("weber_", "fraction of the standard"),
            "difference_75pct": {"Description": "the difference answered right 75 % of the "
                                 "time by the function at the posterior medians; n/a where "
                                 "the threshold is in words", "Units": unit}}
    else:
        jnd_words = {JndStatus.ESTIMATED.value: _THRESHOLD_WORDS["estimated"],
                     JndStatus.BELOW.value: "the answers do not bound the slope from above "
                     "(e.g. every answer right at every SOA tested): only jnd_ci_high",
                     JndStatus.ABOVE.value: "the answers do not bound the slope from below "
                     "(e.g. answers at chance): only jnd_ci_low",
                     **{k: v for k, v in _THRESHOLD_WORDS.items()
                        if k in (ThresholdStatus.NOT_ESTIMABLE.value, NOT_FITTED, "n/a")}}
        columns |= {
            "pins": {"Description": "pin A then pin B, as the protocol lists them"},
            "pss_ms": {"Description": "the point of subjective simultaneity, the SOA (B's "
                       "onset minus A's) at which pin A is named first half the time: "
                       + method + "; n/a where pss_status gives words instead" + _ACROSS,
                       "Units": "ms"},
            **_bounds("pss_", "ms"),
            "pss_status": {"Description": "whether the answers place the PSS",
                           "Levels": _THRESHOLD_WORDS},
            "jnd_ms": {"Description": "the just noticeable difference: half the distance "
                       "between the SOAs at which pin A is named first 25 % and 75 % of the "
                       "time; n/a where jnd_status gives words instead" + _ACROSS,
                       "Units": "ms"},
            **_bounds("jnd_", "ms"),
            "jnd_status": {"Description": "whether the answers place the JND",
                           "Levels": jnd_words}}
    columns["n_trials"] = {"Description": "the counted trials behind the numbers"}
    path = out / f"{paradigm}.json"
    path.write_text(json.dumps(columns, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def _trials(judgements: Judgements, task: str) -> int:
    fits: list[IntervalFit | OrderFit] = [*judgements.intervals, *judgements.orders]
    return sum(f.trials for f in fits if f.task == task)


def _row(cells: Sequence[object]) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def _interval(low: float, high: float) -> str:
    return "n/a (one subject)" if math.isnan(low) else f"[{_n(low)}, {_n(high)}]"


def _estimate(e: Estimate, digits: int = 3) -> str:
    """A subject's value with its credible interval, or its words with the bound they state."""
    if e.status is None:
        return NOT_FITTED
    if not math.isnan(e.value):
        return f"{_n(e.value, digits)} [{_n(e.ci_low, digits)}, {_n(e.ci_high, digits)}]"
    bound = (f" (< {_n(e.ci_high, digits)})" if not math.isnan(e.ci_high)
             else f" (> {_n(e.ci_low, digits)})" if not math.isnan(e.ci_low) else "")
    return f"*{e.words}*{bound}"


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
                  f"Per subject and standard: a {method_text('two_interval')}. Where a "
                  "subject's answers cannot place the threshold, the table gives words (*below "
                  "the lowest value tested*, *above the highest value tested*, *not "
                  "estimable*) with the one bound they state. Across subjects: the mean of the "
                  f"subjects with a number, with the {interval_name(settings)}.", "",
                  _row(["subject", "task", "standard", "threshold", "Weber fraction",
                        "75 % difference", "trials"]), "|---" * 7 + "|"]
        for f in judgements.intervals:
            name, unit = parameter_and_unit(f.compared)
            lines.append(_row([f.subject, f.task, f"{name} {f.standard:g} {unit}",
                               _estimate(f.threshold), _estimate(f.weber),
                               _n(f.difference_75), f.trials]))
        for m in judgements.across:
            if m.measure == "weber_fraction":
                lines.append(_row([ALL_SUBJECTS, m.task, "", "",
                                   f"{_n(m.mean)} {_interval(*m.interval)}", "",
                                   _trials(judgements, m.task)]))
        lines += [*_not_fitted(judgements.intervals), "",
                  "[two_interval.csv](two_interval.csv); its columns and the method: "
                  "[two_interval.json](two_interval.json).", ""]
    if judgements.orders:
        lines += ["## Temporal order", "",
                  f"Per subject: a {method_text('temporal_order')}. Pin A is the first the "
                  "protocol lists. Where a subject's answers cannot place the PSS or the JND, "
                  "the table gives words with the one bound they state. Across subjects: the "
                  f"mean of the subjects with a number, with the {interval_name(settings)}.", "",
                  _row(["subject", "task", "pins (A B)", "PSS (ms)", "JND (ms)", "trials"]),
                  "|---" * 6 + "|"]
        for order in judgements.orders:
            lines.append(_row([order.subject, order.task, " ".join(map(str, order.pins)),
                               _estimate(order.pss, 1), _estimate(order.jnd, 1),
                               order.trials]))
        across = {(m.task, m.measure): m for m in judgements.across}
        for task in sorted({f.task for f in judgements.orders}):
            pss_m, jnd_m = across[(task, "pss_ms")], across[(task, "jnd_ms")]
            lines.append(_row([ALL_SUBJECTS, task, "",
                               f"{_n(pss_m.mean, 1)} {_interval(*pss_m.interval)}",
                               f"{_n(jnd_m.mean, 1)} {_interval(*jnd_m.interval)}",
                               _trials(judgements, task)]))
        lines += [*_not_fitted(judgements.orders), "",
                  "[temporal_order.csv](temporal_order.csv); its columns and the method: "
                  "[temporal_order.json](temporal_order.json).", ""]
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


def _not_fitted(fits: Sequence[IntervalFit | OrderFit]) -> list[str]:
    """A note for each subject without a fit, and each whose value is in words (left out of
    the across-subject mean)."""
    notes = []
    for f in fits:
        if isinstance(f.fit, NotFitted):
            notes.append(f"- subject {f.subject}, task {f.task}: no fit: {f.fit.reason}")
            continue
        said = ([("threshold", f.threshold)] if isinstance(f, IntervalFit)
                else [("PSS", f.pss), ("JND", f.jnd)])
        for name, e in said:
            if e.status is not None and math.isnan(e.value):
                notes.append(f"- subject {f.subject}, task {f.task}: {name} {_estimate(e)}, "
                             f"tested {f.fit.lowest_tested:g} to {f.fit.highest_tested:g}; left "
                             "out of the across-subject mean")
    return [""] + notes if notes else []


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
            f"standard (dot area: trials) and its Bayesian Weibull fit at the posterior "
            f"medians, drawn where the answers place the threshold (guess rate 1/2, dashed). "
            f"Mean Weber fraction {weber.mean:.3f} over {len(weber.per_subject)} subject(s) "
            f"({interval_name(settings)} in summary.md); "
            f"{sum(f.trials for f in fits)} trials. Counted: main trials with status ok.")


def temporal_order_caption(task: str, judgements: Judgements, settings: IntervalSettings) -> str:
    fits = [f for f in judgements.orders if f.task == task]
    measures = {m.measure: m for m in judgements.across if m.task == task}
    return (f"Temporal-order judgement, task {task}: per subject, the proportion of trials "
            f"naming pin A ({fits[0].pins[0]}) first at each SOA (dot area: trials) and its "
            f"Bayesian logistic fit (guess and lapse rates 0) at the posterior medians, drawn "
            f"where the answers place the PSS. Mean PSS {measures['pss_ms'].mean:.1f} ms over "
            f"{len(measures['pss_ms'].per_subject)} subject(s), mean JND "
            f"{measures['jnd_ms'].mean:.1f} ms over {len(measures['jnd_ms'].per_subject)} "
            f"subject(s) ({interval_name(settings)} in summary.md); {sum(f.trials for f in fits)} trials. "
            "Counted: main trials with status ok.")


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
