"""Trial counts of one group of rows (a subject, or everyone pooled); pure functions, no files.

These are the *trial-pooled* numbers: every trial of the group weighs the same, so intervals
here (Wilson) treat trials as independent. Subject-level statistics, with subjects as the
unit, are built from the per-subject counts in `pinarray.analysis.subjects`.

Only rows that count are used: main trials (not practice) with status ``ok``. Localisation
answers are classified again from ``pin`` and ``response`` with the grid (so a results file
edited by hand cannot disagree with itself); motion answers are judged from ``direction``
and ``response``: motion was felt unless the answer is "none", and the direction is right
when the answer names the wave's direction ("unsure" counts as felt, not right).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.errors import ResultsError
from pinarray.grid import DEFAULT_GRID, ErrorClass, Grid
from pinarray.journal.records import LocalisationRecord, MotionRecord, TrialRecord
from pinarray.protocol import NOTHING_FELT

Z_95 = 1.959963984540054  # two-sided 95 % normal quantile
ERROR_CLASSES = tuple(c.value for c in ErrorClass if c is not ErrorClass.CORRECT)  # A-D
# Every localisation answer falls in exactly one of these; "nothing felt" is a category of
# its own in every table and figure, never dropped from a denominator.
CATEGORIES = ("correct", *ERROR_CLASSES, NOTHING_FELT)
CATEGORY_LABELS = {"correct": "correct", "A": "error A", "B": "error B", "C": "error C",
                   "D": "error D", NOTHING_FELT: "nothing felt"}
POOLED = "all"


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion, as fractions; (0, 1) when ``trials == 0``.

    Chosen over the normal approximation because it stays inside [0, 1] and behaves at the
    small counts one subject gives (8 trials per frequency in the seed).
    """
    if not 0 <= successes <= trials:
        raise ValueError(f"successes must lie in 0..trials, found {successes} of {trials}")
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class Proportion:
    """``successes`` of ``trials``, with its percentage and 95 % Wilson interval in percent."""

    successes: int
    trials: int

    @property
    def pct(self) -> float:
        return 100 * self.successes / self.trials if self.trials else math.nan

    @property
    def interval_pct(self) -> tuple[float, float]:
        if not self.trials:
            return math.nan, math.nan
        low, high = wilson_interval(self.successes, self.trials)
        return 100 * low, 100 * high


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
class MotionSummary:
    """Apparent motion: felt on wave trials, right direction among those, felt on no-wave."""

    felt: Proportion  # wave trials on which motion was felt
    direction_right: Proportion  # of those, the wave's direction named
    no_wave_felt: Proportion  # no-wave trials on which motion was (wrongly) felt


@dataclass(frozen=True)
class Summary:
    """Everything analysed for one group of trials (one subject, or everyone pooled)."""

    group: str
    subjects: tuple[str, ...]
    localisation: tuple[FrequencyRow, ...]
    confusion: np.ndarray  # counts; [stimulated - 1, reported - 1], last column nothing felt
    pin_correct: np.ndarray  # correct counts per pin, rows x columns, row 0 at the bottom
    pin_trials: np.ndarray  # trials per pin, same layout
    motion: MotionSummary

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


def motion_summary(records: Iterable[TrialRecord]) -> MotionSummary:
    """Felt-motion and direction proportions over the motion trials that count."""
    wave = felt = right = no_wave = no_wave_felt = 0
    for record in records:
        if not (record.counts and isinstance(record, MotionRecord)):
            continue
        answered_motion = record.response not in (None, "none")
        if record.direction == "none":
            no_wave += 1
            no_wave_felt += answered_motion
        else:
            wave += 1
            felt += answered_motion
            right += record.response == record.direction
    return MotionSummary(Proportion(felt, wave), Proportion(right, felt),
                         Proportion(no_wave_felt, no_wave))


def summarise(
    records: Sequence[TrialRecord], group: str = POOLED, subjects: Sequence[str] = (),
    grid: Grid = DEFAULT_GRID,
) -> Summary:
    """All the statistics of one group of trial rows."""
    correct, trials = pin_counts(records, grid)
    return Summary(
        group=group, subjects=tuple(subjects),
        localisation=localisation_by_frequency(records, grid),
        confusion=confusion_matrix(records, grid),
        pin_correct=correct, pin_trials=trials, motion=motion_summary(records),
    )


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
