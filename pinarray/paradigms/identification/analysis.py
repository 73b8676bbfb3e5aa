"""Identification's findings: confusion matrices by pattern, percent correct and information transferred.

Per subject and task, over the counted rows (status ok, not practice): the confusion matrix
(a row per pattern presented, a column per answer given; counts), the percent correct, and the
information transferred from stimulus to answer, estimated from the matrix by maximum
likelihood::

    IT = sum_ij n_ij / n * log2(n_ij * n / (n_i. * n_.j))     bits

which lies between 0 and log2 of the smaller of the numbers of patterns and answers. With few
trials per cell it is **biased upward** (Miller 1955; Rabinowitz & Houtsma): chance pairings
look like information. The first-order bias, ``(R - 1)(C - 1) / (2 n ln 2)`` bits for ``R``
patterns presented and ``C`` answers given (the matrix's columns that hold a trial: an answer
offered but never given does not count) in ``n`` trials, is reported beside it (and subtracted in
``it_corrected_bits``, floored at 0), as a warning of its size rather than an exact repair.
Across subjects (subject ``all``): the mean of the subjects' values, with the interval the
analysis's settings name (subject bootstrap or t); the pooled matrix (every subject's trials
together, unit trial) is what the figure draws.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.seam import AnalysisDefaults, Context, Estimate, Findings, Reported
from pinarray.analysis.subjects import IntervalSettings, interval_of
from pinarray.analysis.tables import ALL_SUBJECTS, number, write_csv
from pinarray.paradigms.identification.rows import IdentificationRecord

IDENTIFICATION_COLUMNS = ("subject", "task", "n_trials", "percent_correct", "it_bits",
                          "it_bias_bits", "it_corrected_bits", "it_max_bits", "ci_low", "ci_high")
CONFUSION_COLUMNS = ("task", "presented", "answered", "n_trials", "percent_of_presented")


def information_transferred(counts: np.ndarray) -> float:
    """The maximum-likelihood information transferred of a confusion matrix, in bits."""
    n = float(counts.sum())
    if n == 0:
        return 0.0
    rows = counts.sum(axis=1, keepdims=True)
    columns = counts.sum(axis=0, keepdims=True)
    filled = counts > 0
    ratio = np.where(filled, counts * n / np.where(filled, rows * columns, 1.0), 1.0)
    return max(0.0, float((counts[filled] / n * np.log2(ratio[filled])).sum()))


def it_bias_bits(counts: np.ndarray) -> float:
    """The first-order upward bias of `information_transferred` (the module says whose): R the
    rows and C the columns of ``counts`` that hold a trial (the answers used, not offered)."""
    n = float(counts.sum())
    if n == 0:
        return 0.0
    rows = int((counts.sum(axis=1) > 0).sum())
    columns = int((counts.sum(axis=0) > 0).sum())
    return (rows - 1) * (columns - 1) / (2 * n * math.log(2))


@dataclass(frozen=True)
class Confusion:
    """A confusion matrix: ``counts[i, j]`` trials presenting ``presented[i]`` answered
    ``answered[j]``."""

    presented: tuple[str, ...]
    answered: tuple[str, ...]
    counts: np.ndarray

    @property
    def trials(self) -> int:
        return int(self.counts.sum())

    @property
    def correct(self) -> int:
        """Trials answered with what was presented (a pattern's name, or its count)."""
        return sum(int(self.counts[i, self.answered.index(p)])
                   for i, p in enumerate(self.presented) if p in self.answered)

    @property
    def percent_correct(self) -> float:
        return 100 * self.correct / self.trials if self.trials else math.nan

    @property
    def it_bits(self) -> float:
        return information_transferred(self.counts)

    @property
    def it_bias_bits(self) -> float:
        return it_bias_bits(self.counts)

    @property
    def it_corrected_bits(self) -> float:
        return max(0.0, self.it_bits - self.it_bias_bits)

    @property
    def it_max_bits(self) -> float:
        """What a perfect subject would transfer: log2 of the patterns presented."""
        return math.log2(len(self.presented)) if self.presented else 0.0

    def row_percentages(self) -> np.ndarray:
        """Each row as percentages of its pattern's trials."""
        totals = self.counts.sum(axis=1, keepdims=True)
        return 100 * self.counts / np.where(totals == 0, 1, totals)


def confusion(records: Iterable[IdentificationRecord]) -> Confusion:
    """The confusion matrix of the answered ``records``: patterns in the order first met
    (counts ascending when subjects named counts), answers in the patterns' order, then any
    answer no trial presented."""
    pairs = [(_presented(r), r.response) for r in records if r.response is not None]
    by_count = all(_is_count(answer) for _, answer in pairs) and bool(pairs)
    presented = _ordered((p for p, _ in pairs), by_count)
    answered = _ordered((*presented, *(a for _, a in pairs)), by_count)
    counts = np.zeros((len(presented), len(answered)), dtype=np.int64)
    for p, a in pairs:
        counts[presented.index(p), answered.index(a)] += 1
    return Confusion(presented, answered, counts)


def _presented(record: IdentificationRecord) -> str:
    """What a right answer names: the pattern, or its count of pins for a count answer."""
    assert record.response is not None
    return str(len(record.pins)) if _is_count(record.response) else record.pattern


def _is_count(answer: str) -> bool:
    """Whether an answer is a count of pins: ASCII digits (`str.isdigit` takes ² and १ too)."""
    return answer.isascii() and answer.isdigit()


def _ordered(items: Iterable[str], by_count: bool) -> tuple[str, ...]:
    found = tuple(dict.fromkeys(items))
    return tuple(sorted(found, key=int)) if by_count else found


@dataclass(frozen=True)
class SubjectIdentification:
    """One subject's identification of one task."""

    subject: str
    task: str
    confusion: Confusion


@dataclass(frozen=True)
class AcrossIdentification:
    """One task's measures with the subject as the unit: the mean of the subjects' values
    and its interval (NaN with fewer than two subjects), by measure name."""

    task: str
    subjects: int
    trials: int
    means: tuple[tuple[str, float, tuple[float, float]], ...]  # (measure, mean, interval)
    pooled: Confusion


MEASURES = ("percent_correct", "it_bits", "it_corrected_bits")


def _n(value: float, digits: int = 3) -> str:
    return number(value, digits)


def _row(cells: Sequence[object]) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def _interval(low: float, high: float) -> str:
    return "n/a (one subject)" if math.isnan(low) else f"[{_n(low)}, {_n(high)}]"


@dataclass(frozen=True)
class Identifications:
    """Every subject's identification results and their across-subject means (`Findings`)."""

    per_subject: tuple[SubjectIdentification, ...]
    across: tuple[AcrossIdentification, ...]
    settings: IntervalSettings
    paradigm: str = "identification"

    @property
    def trials(self) -> int:
        return sum(s.confusion.trials for s in self.per_subject)

    @property
    def estimates(self) -> tuple[Reported, ...]:
        found = [Reported(s.task, s.subject, measure, "%" if measure == "percent_correct"
                          else "bits", s.confusion.trials,
                          Estimate.of(getattr(s.confusion, measure)))
                 for s in self.per_subject for measure in MEASURES]
        found += [Reported(a.task, ALL_SUBJECTS, measure,
                           "%" if measure == "percent_correct" else "bits", a.trials,
                           Estimate.of(mean, *interval))
                  for a in self.across for measure, mean, interval in a.means]
        return tuple(found)

    def counted(self) -> str:
        return f"{self.trials} identification trials"

    def methods(self) -> list[str]:
        return []

    def tables(self, out: Path) -> list[Path]:
        """``identification.csv`` (each subject's row, then the across-subject means: subject
        ``all``, the interval the settings name in ``ci_low``/``ci_high``) and
        ``identification_confusion.csv``."""
        rows: list[list[object]] = []
        for s in self.per_subject:
            c = s.confusion
            rows.append([s.subject, s.task, c.trials, _n(c.percent_correct, 1), _n(c.it_bits),
                         _n(c.it_bias_bits), _n(c.it_corrected_bits), _n(c.it_max_bits), "",
                         ""])
        for a in self.across:
            for measure, mean, (low, high) in a.means:
                row = {"percent_correct": "", "it_bits": "", "it_corrected_bits": ""}
                row[measure] = _n(mean, 1 if measure == "percent_correct" else 3)
                rows.append([ALL_SUBJECTS, a.task, a.trials, row["percent_correct"],
                             row["it_bits"], "", row["it_corrected_bits"],
                             _n(a.pooled.it_max_bits), _n(low), _n(high)])
        cells = []
        for a in self.across:
            percent = a.pooled.row_percentages()
            for i, presented in enumerate(a.pooled.presented):
                for j, answered in enumerate(a.pooled.answered):
                    cells.append([a.task, presented, answered, int(a.pooled.counts[i, j]),
                                  _n(float(percent[i, j]), 1)])
        return [write_csv(out / "identification.csv", IDENTIFICATION_COLUMNS, rows),
                write_csv(out / "identification_confusion.csv", CONFUSION_COLUMNS, cells)]

    def sections(self) -> list[str]:
        lines = ["## Identification", "",
                 "Per subject: percent correct and the information transferred (IT, bits) "
                 "from the confusion matrix of patterns presented and answers given. IT is "
                 "biased upward when there are few trials per cell (Miller 1955): its "
                 "first-order bias, (R - 1)(C - 1) / (2 n ln 2) bits for R patterns presented, "
                 "C answers given (an answer never given does not count) and n trials, is "
                 "given beside it, and subtracted in the corrected "
                 f"IT; read both as bounds. Across subjects: the mean with the "
                 f"{self.settings.describe()}.", "",
                 _row(["task", "subjects", "trials", "percent correct", "IT (bits)",
                       "IT corrected (bits)", "IT max (bits)"]), "|---" * 7 + "|"]
        for a in self.across:
            means = {m: (mean, interval) for m, mean, interval in a.means}
            cells = [f"{_n(means[m][0], 1 if m == 'percent_correct' else 3)} "
                     f"{_interval(*means[m][1])}" for m in ("percent_correct", "it_bits",
                                                            "it_corrected_bits")]
            lines.append(_row([a.task, a.subjects, a.trials, *cells, _n(a.pooled.it_max_bits)]))
        return lines + ["", "Per subject, and the pooled confusion matrices: "
                        "[identification.csv](identification.csv), "
                        "[identification_confusion.csv](identification_confusion.csv).", ""]

    def lines(self) -> list[str]:
        lines = []
        for a in self.across:
            means = {m: mean for m, mean, _ in a.means}
            bias = float(np.mean([s.confusion.it_bias_bits for s in self.per_subject
                                  if s.task == a.task]))
            lines.append(f"identification {a.task}: {_n(means['percent_correct'], 1)} % correct, "
                         f"information transferred {_n(means['it_bits'])} bits of "
                         f"{_n(a.pooled.it_max_bits)} (its small-sample bias {_n(bias)} bits; "
                         f"less the bias, floored at 0: {_n(means['it_corrected_bits'])} bits), "
                         f"mean of {a.subjects} subject(s)")
        return lines

    def captions(self) -> dict[str, str]:
        return {f"identification_{a.task}": caption(a, self.settings) for a in self.across}

    def figures(self, out: Path) -> list[Path]:
        from pinarray.paradigms.identification.figures import plot_identification

        drawn: list[Path] = []
        for a in self.across:
            drawn += plot_identification(a, caption(a, self.settings),
                                         out / f"identification_{a.task}")
        return drawn


def caption(a: AcrossIdentification, settings: IntervalSettings) -> str:
    pooled = a.pooled
    return (f"Identification, task {a.task}: confusion matrix, trial-pooled (unit: trial; "
            f"N = {a.subjects} subject(s), {a.trials} trials). Each row is one pattern "
            f"presented and adds up to 100 % of its trials. Pooled: {pooled.percent_correct:.1f} "
            f"% correct, information transferred {pooled.it_bits:.2f} bits of "
            f"{pooled.it_max_bits:.2f} (biased upward by about {pooled.it_bias_bits:.2f} bits "
            f"with this many trials per cell). Subject-level means with the "
            f"{settings.describe()} are in summary.md. Counted: main trials with status ok.")


def identifications(trials: Sequence[LoadedTrial], context: Context) -> Identifications:
    """The identification rows of ``trials`` (those that count), per subject and across."""
    settings = context.settings
    groups: dict[tuple[str, str], list[IdentificationRecord]] = {}
    for trial in trials:
        record = trial.record
        if isinstance(record, IdentificationRecord) and record.counts:
            groups.setdefault((record.task, trial.subject), []).append(record)
    per_subject = tuple(SubjectIdentification(subject, task, confusion(records))
                        for (task, subject), records in sorted(groups.items()))
    across = []
    for task in sorted({s.task for s in per_subject}):
        mine = [s for s in per_subject if s.task == task]
        means = []
        for measure in MEASURES:
            values = [getattr(s.confusion, measure) for s in mine]
            means.append((measure, float(np.mean(values)), interval_of(values, settings)))
        pooled = confusion(r for (t, _), records in groups.items() if t == task
                           for r in records)
        across.append(AcrossIdentification(task, len(mine), sum(s.confusion.trials
                                                                 for s in mine),
                                           tuple(means), pooled))
    return Identifications(per_subject, tuple(across), settings)


class IdentificationAnalysis(AnalysisDefaults):
    """The identification analysis (`pinarray.analysis.seam.ParadigmAnalysis`)."""

    name = "identification"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return identifications(trials, context)


ANALYSIS = IdentificationAnalysis()
