"""Identification: confusion matrices by pattern, percent correct and information transferred.

Per subject and task, over the counted rows (status ok, not practice): the confusion matrix
(a row per pattern presented, a column per answer given; counts), the percent correct, and the
information transferred from stimulus to answer, estimated from the matrix by maximum
likelihood::

    IT = sum_ij n_ij / n * log2(n_ij * n / (n_i. * n_.j))     bits

which lies between 0 and log2 of the smaller of the numbers of patterns and answers. With few
trials per cell it is **biased upward** (Miller 1955; Rabinowitz & Houtsma): chance pairings
look like information. The first-order bias, ``(R - 1)(C - 1) / (2 n ln 2)`` bits for ``R``
patterns and ``C`` answers seen in ``n`` trials, is reported beside it (and subtracted in
``it_corrected_bits``, floored at 0), as a warning of its size rather than an exact repair.
Across subjects (subject ``all``): the mean of the subjects' values, with the interval the
analysis's settings name (subject bootstrap or t); the pooled matrix (every subject's trials
together, unit trial) is what the figure draws.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.subjects import IntervalSettings, interval_of
from pinarray.journal.records import IdentificationRecord


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
    """The first-order upward bias of `information_transferred` (the module says whose)."""
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
    by_count = all(answer.isdigit() for _, answer in pairs) and bool(pairs)
    presented = _ordered((p for p, _ in pairs), by_count)
    answered = _ordered((*presented, *(a for _, a in pairs)), by_count)
    counts = np.zeros((len(presented), len(answered)), dtype=np.int64)
    for p, a in pairs:
        counts[presented.index(p), answered.index(a)] += 1
    return Confusion(presented, answered, counts)


def _presented(record: IdentificationRecord) -> str:
    """What a right answer names: the pattern, or its count of pins for a count answer."""
    assert record.response is not None
    return str(len(record.pins)) if record.response.isdigit() else record.pattern


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


@dataclass(frozen=True)
class Identifications:
    """Every subject's identification results and their across-subject means."""

    per_subject: tuple[SubjectIdentification, ...]
    across: tuple[AcrossIdentification, ...]

    @property
    def found(self) -> bool:
        return bool(self.per_subject)


MEASURES = ("percent_correct", "it_bits", "it_corrected_bits")


def identifications(trials: Sequence[LoadedTrial], settings: IntervalSettings) -> Identifications:
    """The identification rows of ``trials`` (those that count), per subject and across."""
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
    return Identifications(per_subject, tuple(across))
