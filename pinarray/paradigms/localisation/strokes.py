"""The stimulus actually delivered: each pin's achieved stroke by frequency, from localisation's
rows.

The source is ``beh.tsv``'s stroke columns (``stroke_commanded``, ``stroke_achieved``,
``cycles_short``): the run measured them from each trial's sampled positions against the
exact times of its goal changes (`pinarray.hardware.motion`), which the motion recording
keeps only as the goal in force at each sample. A row describes one pin: in a localisation
trial the one pin that moved (its ``pin``), at the row's ``frequency_hz``, so localisation
rows give each pin's frequency response.

Every row of the counted runs with a measured stroke counts, practice and invalid rows too: a
stroke below the protocol's tolerance makes a trial invalid, and leaving those out would
hide what the table is for. Millimetres come through each run's manifest (``mm_per_step``);
older manifests have none: n/a. Results written before strokes were measured (or on PWM
servos, which report no position) give no table.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from statistics import median

from pinarray.journal.records import TrialRecord
from pinarray.paradigms.localisation.rows import LocalisationRecord


@dataclass(frozen=True)
class StrokeRow:
    """One pin at one frequency and commanded stroke: its achieved strokes over the trials.

    ``achieved_*_steps`` are over the trials' achieved strokes (each the smallest peak-to-peak
    of its cycles), in servo steps; ``mm_per_step`` is None where the manifest does not say;
    ``n_short`` counts the trials with a cycle below the stroke tolerance.
    """

    pin: int
    frequency_hz: float
    commanded_steps: int
    mm_per_step: float | None
    achieved_min_steps: int
    achieved_median_steps: float
    achieved_max_steps: int
    n_trials: int
    n_short: int

    def share_pct(self, steps: float) -> float:
        """``steps`` as a percentage of the commanded stroke (NaN when none was commanded)."""
        return 100 * steps / self.commanded_steps if self.commanded_steps else math.nan

    def mm(self, steps: float) -> float:
        """``steps`` of this pin in mm (NaN where the manifest does not say)."""
        return math.nan if self.mm_per_step is None else steps * self.mm_per_step


@dataclass(frozen=True)
class StrokeTable:
    """`StrokeRow` s by pin, frequency and commanded stroke, and the measured rows not in them
    (``not_measured``: rows whose pin was sampled too sparsely to judge a cycle)."""

    rows: tuple[StrokeRow, ...]
    not_measured: int = 0

    @property
    def measured(self) -> bool:
        return bool(self.rows or self.not_measured)


def stroke_table(rows: Iterable[tuple[TrialRecord, Sequence[float]]]) -> StrokeTable:
    """Each pin's achieved strokes by frequency from ``rows``: a row with its run's
    ``mm_per_step`` (pin 1 first; empty where the manifest does not say)."""
    groups: dict[tuple[int, float, int, float | None], list[LocalisationRecord]] = {}
    not_measured = 0
    for record, mm_per_step in rows:
        stroke = record.stroke
        if stroke is None or not isinstance(record, LocalisationRecord):
            continue
        if stroke.achieved_steps is None:
            not_measured += 1
            continue
        per_step = mm_per_step[record.pin - 1] if record.pin <= len(mm_per_step) else None
        key = (record.pin, record.frequency_hz, stroke.commanded_steps, per_step)
        groups.setdefault(key, []).append(record)
    table = []
    for (pin, frequency_hz, commanded, per_step), records in sorted(
            groups.items(), key=lambda item: (item[0][:3], item[0][3] or 0.0)):
        achieved = [r.stroke.achieved_steps for r in records if r.stroke is not None
                    and r.stroke.achieved_steps is not None]
        short = sum(1 for r in records if r.stroke is not None and r.stroke.short_cycles)
        table.append(StrokeRow(pin, frequency_hz, commanded, per_step, min(achieved),
                               float(median(achieved)), max(achieved), len(achieved), short))
    return StrokeTable(tuple(table), not_measured)
