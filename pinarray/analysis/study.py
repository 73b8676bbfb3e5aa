"""One analysis of a set of runs: the value that tables, figures and the summary are drawn from.

Each paradigm's rows are analysed by its room (`pinarray.analysis.seam.ParadigmAnalysis`:
its `Findings`), in the registry's order; the adaptive designs' thresholds are every
paradigm's alike (`pinarray.analysis.thresholds`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from pinarray import registry
from pinarray.analysis.load import LoadedTrial, RunSelection
from pinarray.analysis.seam import Context, Findings, analysis_of
from pinarray.analysis.subjects import DEFAULT_SETTINGS, IntervalSettings
from pinarray.analysis.thresholds import Thresholds, thresholds
from pinarray.grid import DEFAULT_GRID, Grid


@dataclass(frozen=True)
class Study:
    """Everything `pinarray analyse` reports about the runs that count: each paradigm's
    findings (of the paradigms with rows in them, in the registry's order) and the adaptive
    designs' thresholds (empty without any)."""

    runs: RunSelection
    settings: IntervalSettings
    grid: Grid
    findings: tuple[Findings, ...]
    thresholds: Thresholds

    @property
    def subjects(self) -> tuple[str, ...]:
        """Every subject with a counted trial."""
        return tuple(sorted({t.subject for t in self.runs.trials if t.record.counts}))

    def of(self, paradigm: str) -> Findings | None:
        """The findings of ``paradigm``, or None when its rows are not in the runs."""
        return next((f for f in self.findings if f.paradigm == paradigm), None)


def study(runs: RunSelection, settings: IntervalSettings = DEFAULT_SETTINGS,
          answer_pins: Iterable[int] | None = None, grid: Grid = DEFAULT_GRID) -> Study:
    """Analyse the included runs of ``runs``.

    ``answer_pins`` are the pins a subject could name (all pins of ``grid`` by default); they
    set a localisation's chance levels.
    """
    context = Context(runs, settings, grid, None if answer_pins is None else tuple(answer_pins))
    by_paradigm: dict[str, list[LoadedTrial]] = {}
    for trial in runs.trials:
        by_paradigm.setdefault(trial.record.paradigm, []).append(trial)
    order = list(registry.LISTED) + sorted(set(by_paradigm) - set(registry.LISTED))
    findings = tuple(analysis_of(name).findings(by_paradigm[name], context)
                     for name in order if name in by_paradigm)
    return Study(runs, settings, grid, findings, thresholds(runs, settings))
