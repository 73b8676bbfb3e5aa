"""Localisation's counts: every answer category by frequency, the confusion matrix, each pin's
accuracy, and their chance levels; one group of rows at a time, then subjects as the unit.

Only rows that count are used: main trials (not practice) with status ``ok``. Answers are
classified again from ``pin`` and ``response`` with the grid (so a results file edited by hand
cannot disagree with itself). Each answer falls in exactly one category: correct, an error
class A-D (`pinarray.grid.ErrorClass`), or nothing felt, which is a category of its own in
every table and figure, never dropped from a denominator.

Chance: a subject who names one of the ``answer_pins`` uniformly at random on every trial.
Correct by chance is then 1 / K for K nameable pins (1/16 when any pin of the 4x4 grid may be
named); the chance of each error class A-D is the share of nameable pins in that class,
averaged over the stimulated pins (pins stimulated equally often). "Nothing felt" has no
chance level: it is not a guess.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.analysis.stats import POOLED, Proportion
from pinarray.analysis.subjects import (
    DEFAULT_SETTINGS,
    AcrossSubjects,
    IntervalSettings,
    across_subjects,
)
from pinarray.errors import ResultsError
from pinarray.grid import DEFAULT_GRID, ErrorClass, Grid
from pinarray.journal.records import TrialRecord
from pinarray.paradigms.localisation.design import NOTHING_FELT
from pinarray.paradigms.localisation.rows import LocalisationRecord

ERROR_CLASSES = tuple(c.value for c in ErrorClass if c is not ErrorClass.CORRECT)  # A-D
# Every answer falls in exactly one of these.
CATEGORIES = ("correct", *ERROR_CLASSES, NOTHING_FELT)
CATEGORY_LABELS = {"correct": "correct", "A": "error A", "B": "error B", "C": "error C",
                   "D": "error D", NOTHING_FELT: "nothing felt"}


@dataclass(frozen=True)
class FrequencyRow:
    """Localisation at one frequency: correct answers, and each error class as % of trials."""

    frequency_hz: float
    correct: Proportion
    error_counts: tuple[int, int, int, int]  # A, B, C, D
    none_felt: int

    @property
    def trials(self) -> int:
        return self.correct.trials

    def count(self, category: str) -> int:
        """Trials answered in ``category`` (one of `CATEGORIES`)."""
        if category == "correct":
            return self.correct.successes
        if category == NOTHING_FELT:
            return self.none_felt
        return self.error_counts[ERROR_CLASSES.index(category)]

    def share(self, category: str) -> Proportion:
        """Trials answered in ``category`` out of all trials at this frequency."""
        return Proportion(self.count(category), self.trials)

    def error_pct(self, error_class: str) -> float:
        return self.share(error_class).pct


@dataclass(frozen=True)
class Summary:
    """Localisation of one group of trials (one subject, or everyone pooled)."""

    group: str
    subjects: tuple[str, ...]
    localisation: tuple[FrequencyRow, ...]
    confusion: np.ndarray  # counts; [stimulated - 1, reported - 1], last column nothing felt
    pin_correct: np.ndarray  # correct counts per pin, rows x columns, row 0 at the bottom
    pin_trials: np.ndarray  # trials per pin, same layout

    @property
    def pin_accuracy_pct(self) -> np.ndarray:
        """Percent correct per pin on the grid layout; NaN for pins never stimulated."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.pin_trials > 0, 100 * self.pin_correct / self.pin_trials,
                            np.nan)


def _reported_pin(record: LocalisationRecord, grid: Grid) -> int | None:
    if record.response in (None, "none"):
        return None
    try:
        return grid.check_pin(int(record.response))
    except (ValueError, TypeError):
        raise ResultsError(
            f"trial {record.trial}: localisation response {record.response!r} is neither a "
            f"pin number nor 'none'"
        ) from None


def _localisation_answers(
    records: Iterable[TrialRecord], grid: Grid
) -> Iterator[tuple[int, float | None, int | None]]:
    """(stimulated pin, frequency_hz, pin named or None) of every counted localisation row."""
    for record in records:
        if record.counts and isinstance(record, LocalisationRecord):
            yield grid.check_pin(record.pin), record.frequency_hz, _reported_pin(record, grid)


def localisation_by_frequency(
    records: Iterable[TrialRecord], grid: Grid = DEFAULT_GRID
) -> tuple[FrequencyRow, ...]:
    """Counts of every answer category per stimulation frequency, lowest frequency first."""
    tallies: dict[float, list[int]] = {}  # frequency -> [trials, correct, A, B, C, D, none]
    for pin, frequency_hz, reported in _localisation_answers(records, grid):
        if frequency_hz is None:
            continue
        tally = tallies.setdefault(frequency_hz, [0] * 7)
        tally[0] += 1
        verdict = NOTHING_FELT if reported is None else grid.classify(pin, reported).value
        tally[1 + CATEGORIES.index(verdict)] += 1
    return tuple(
        FrequencyRow(frequency, Proportion(t[1], t[0]), (t[2], t[3], t[4], t[5]), t[6])
        for frequency, t in sorted(tallies.items())
    )


def confusion_matrix(records: Iterable[TrialRecord], grid: Grid = DEFAULT_GRID) -> np.ndarray:
    """Counts of (stimulated pin, answer): columns 0..P-1 are pins 1..P, column P nothing felt.

    Each row sums to the trials of its stimulated pin, so a row's shares are shares of every
    trial, the same denominator as the pin map's.
    """
    matrix = np.zeros((grid.pin_count, grid.pin_count + 1), dtype=int)
    for pin, _, reported in _localisation_answers(records, grid):
        matrix[pin - 1, grid.pin_count if reported is None else reported - 1] += 1
    return matrix


def pin_counts(
    records: Iterable[TrialRecord], grid: Grid = DEFAULT_GRID
) -> tuple[np.ndarray, np.ndarray]:
    """(correct, trials) per stimulated pin, laid out rows x columns with row 0 at the bottom."""
    correct = np.zeros(grid.pin_count, dtype=int)
    trials = np.zeros(grid.pin_count, dtype=int)
    for pin, _, reported in _localisation_answers(records, grid):
        trials[pin - 1] += 1
        correct[pin - 1] += reported == pin
    shape = (grid.rows, grid.columns)
    return correct.reshape(shape), trials.reshape(shape)


def summarise(
    records: Sequence[TrialRecord], group: str = POOLED, subjects: Sequence[str] = (),
    grid: Grid = DEFAULT_GRID,
) -> Summary:
    """All the counts of one group of trial rows."""
    correct, trials = pin_counts(records, grid)
    return Summary(group=group, subjects=tuple(subjects),
                   localisation=localisation_by_frequency(records, grid),
                   confusion=confusion_matrix(records, grid), pin_correct=correct,
                   pin_trials=trials)


def summarise_subjects(
    rows: Iterable[tuple[str, TrialRecord]], grid: Grid = DEFAULT_GRID
) -> tuple[Summary, ...]:
    """The pooled summary (group "all") first, then one per subject (group "sub-<id>")."""
    by_subject: dict[str, list[TrialRecord]] = {}
    for subject, record in rows:
        by_subject.setdefault(subject, []).append(record)
    subjects = sorted(by_subject)
    pooled = [r for s in subjects for r in by_subject[s]]
    return (
        summarise(pooled, POOLED, subjects, grid),
        *(summarise(by_subject[s], f"sub-{s}", (s,), grid) for s in subjects),
    )


@dataclass(frozen=True)
class FrequencyMeasures:
    """Localisation at one frequency: every answer category, subjects as the unit."""

    frequency_hz: float
    categories: tuple[AcrossSubjects, ...]  # in `CATEGORIES` order

    def share(self, category: str) -> AcrossSubjects:
        return self.categories[CATEGORIES.index(category)]


@dataclass(frozen=True)
class SubjectLevel:
    """Every localisation measure with subjects as the unit, and the settings that made it."""

    settings: IntervalSettings
    localisation: tuple[FrequencyMeasures, ...]
    pins: tuple[AcrossSubjects, ...]  # correct per stimulated pin, pins 1..P

    @property
    def localisation_subjects(self) -> tuple[str, ...]:
        names = {s for row in self.localisation for s, _ in row.share("correct").per_subject}
        return tuple(sorted(names))


def subject_level(per_subject: Sequence[Summary],
                  settings: IntervalSettings = DEFAULT_SETTINGS) -> SubjectLevel:
    """Subject-level measures from one `Summary` per subject (each with one subject name)."""
    named = [(summary.subjects[0], summary) for summary in per_subject]
    frequencies = sorted({row.frequency_hz for _, s in named for row in s.localisation})

    def at(summary: Summary, frequency_hz: float, category: str) -> Proportion:
        for row in summary.localisation:
            if row.frequency_hz == frequency_hz:
                return row.share(category)
        return Proportion(0, 0)

    localisation = tuple(
        FrequencyMeasures(f, tuple(across_subjects(((name, at(s, f, c)) for name, s in named),
                                                   settings) for c in CATEGORIES))
        for f in frequencies
    )
    pin_count = named[0][1].pin_trials.size if named else 0
    pins = tuple(
        across_subjects(((name, Proportion(int(s.pin_correct.flat[i]), int(s.pin_trials.flat[i])))
                         for name, s in named), settings)
        for i in range(pin_count)
    )
    return SubjectLevel(settings, localisation, pins)


@dataclass(frozen=True)
class LocalisationChance:
    """Chance levels of the localisation answer categories, as fractions."""

    answer_pins: tuple[int, ...]
    stimulated_pins: tuple[int, ...]
    fractions: Mapping[str, float]  # "correct", "A".."D"

    @property
    def correct(self) -> float:
        return self.fractions["correct"]

    def definition(self) -> str:
        k = len(self.answer_pins)
        return (f"chance = a subject naming any of {k} pins at random "
                f"(correct 1/{k} = {100 * self.correct:.2f} %)")


def localisation_chance(stimulated_pins: Iterable[int], answer_pins: Iterable[int] | None = None,
                        grid: Grid = DEFAULT_GRID) -> LocalisationChance:
    """Chance levels for the given stimulated pins when any of ``answer_pins`` may be named.

    ``answer_pins`` defaults to every pin of ``grid``.
    """
    stimulated = tuple(sorted({grid.check_pin(p) for p in stimulated_pins}))
    answers = tuple(sorted({grid.check_pin(p) for p in (answer_pins or grid.pins)}))
    fractions = dict.fromkeys(("correct", *ERROR_CLASSES), 0.0)
    for s in stimulated:
        for r in answers:
            fractions[grid.classify(s, r).value] += 1 / (len(answers) * len(stimulated))
    return LocalisationChance(answers, stimulated, fractions)
