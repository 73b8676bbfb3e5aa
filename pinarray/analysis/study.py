"""One analysis of a set of runs: the value that tables, figures and the summary are drawn from."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from pinarray.analysis.chance import LocalisationChance, localisation_chance
from pinarray.analysis.identification import Identifications, identifications
from pinarray.analysis.judgements import Judgements, judgements
from pinarray.analysis.load import RunSelection
from pinarray.analysis.mixed import Cell, FitSkipped, FrequencyEffect, fit_frequency_effect
from pinarray.analysis.stats import Summary, summarise_subjects
from pinarray.analysis.strokes import StrokeTable, stroke_table
from pinarray.analysis.subjects import (
    DEFAULT_SETTINGS,
    IntervalSettings,
    SubjectLevel,
    subject_level,
)
from pinarray.analysis.thresholds import Thresholds, thresholds
from pinarray.grid import DEFAULT_GRID, Grid


@dataclass(frozen=True)
class Study:
    """Everything `pinarray analyse` reports about the runs that count.

    ``pooled`` and ``per_subject`` are trial counts (see `pinarray.analysis.stats`);
    ``subject_level`` has subjects as the unit; ``chance`` is None without localisation trials;
    ``thresholds`` are those of the adaptive rows (empty without any); ``strokes`` each pin's
    achieved stroke by frequency (empty where nothing was measured); ``identification`` and
    ``judgements`` the lab's paradigms' (confusion matrices and information transferred;
    two-interval and temporal-order fits), empty without their rows.
    """

    runs: RunSelection
    pooled: Summary
    per_subject: tuple[Summary, ...]
    subject_level: SubjectLevel
    chance: LocalisationChance | None
    frequency_effect: FrequencyEffect | FitSkipped
    grid: Grid
    thresholds: Thresholds
    strokes: StrokeTable
    identification: Identifications
    judgements: Judgements

    @property
    def subjects(self) -> tuple[str, ...]:
        return self.pooled.subjects

    @property
    def localisation_trials(self) -> int:
        return sum(row.trials for row in self.pooled.localisation)

    @property
    def motion_trials(self) -> int:
        motion = self.pooled.motion
        return motion.felt.trials + motion.no_wave_felt.trials


def study(runs: RunSelection, settings: IntervalSettings = DEFAULT_SETTINGS,
          answer_pins: Iterable[int] | None = None, grid: Grid = DEFAULT_GRID) -> Study:
    """Analyse the included runs of ``runs``.

    ``answer_pins`` are the pins a subject could name (all pins of ``grid`` by default); they
    set the chance levels.
    """
    pooled, *per_subject = summarise_subjects(
        ((t.subject, t.record) for t in runs.trials), grid)
    stimulated = [pin for pin in grid.pins if pooled.pin_trials.flat[pin - 1]]
    chance = localisation_chance(stimulated, answer_pins, grid) if stimulated else None
    cells = [Cell(s.subjects[0], row.frequency_hz, row.correct.successes, row.trials)
             for s in per_subject for row in s.localisation]
    return Study(runs, pooled, tuple(per_subject), subject_level(per_subject, settings), chance,
                 fit_frequency_effect(cells), grid, thresholds(runs, settings),
                 stroke_table((record, run.mm_per_step) for run in runs.included
                              for record in run.records),
                 identifications(runs.trials, settings), judgements(runs.trials, settings))
