"""What the run screen shows that is computed, not drawn: moving pins and running counts.

Pure functions of a compiled trial or of the rows written so far, so they are tested
without a terminal.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.journal.records import TrialRecord, TrialStatus
from pinarray.journal.seam import ParadigmRows
from pinarray.protocol.procedures import CATCH, PRACTICE
from pinarray.schedule import TargetList


@dataclass(frozen=True, eq=False)
class LiftTimeline:
    """When each pin of one trial is away from rest, from the trial's target changes.

    Attributes
    ----------
    pins : tuple of int
        Pins the trial moves.
    times_ns : tuple of numpy.ndarray
        Per pin, the times (ns from stimulus onset) its goal position changes.
    lifted : tuple of numpy.ndarray
        Per pin and change, whether the new goal is away from the pin's rest position.
    """

    pins: tuple[int, ...]
    times_ns: tuple[np.ndarray, ...]
    lifted: tuple[np.ndarray, ...]

    @classmethod
    def from_targets(cls, targets: TargetList, rest_steps: dict[int, int]) -> LiftTimeline:
        pins = tuple(int(p) for p in np.unique(targets.pin))
        times, lifted = [], []
        for pin in pins:
            mine = targets.pin == pin
            times.append(targets.time_ns[mine])
            lifted.append(targets.position_steps[mine] != rest_steps[pin])
        return cls(pins, tuple(times), tuple(lifted))

    def shortest_change_ns(self) -> int | None:
        """The least time between two changes of one pin (None: no pin changes twice)."""
        gaps = [int(np.diff(times).min()) for times in self.times_ns if len(times) > 1]
        return min(gaps, default=None)

    def lifted_at(self, elapsed_ns: int) -> frozenset[int]:
        """Pins away from rest ``elapsed_ns`` after onset (none before onset)."""
        up = set()
        for pin, times, lifted in zip(self.pins, self.times_ns, self.lifted, strict=True):
            last = int(np.searchsorted(times, elapsed_ns, side="right")) - 1
            if last >= 0 and lifted[last]:
                up.add(pin)
        return frozenset(up)


def live_lines(rows: ParadigmRows, records: Sequence[TrialRecord]) -> list[str]:
    """The counts panel: the paradigm's running counts of the counted trials (main trials
    with status ok; practice and redone rows aside), and the practice trials done."""
    lines = rows.live_lines([r for r in records if r.counts])
    practice = sum(1 for r in records if r.practice and r.status is TrialStatus.OK)
    return lines + ([f"practice done {practice} (not counted)"] if practice else [])


TRACK_LENGTH = 8  # the last values of each procedure the run screen shows


def track_lines(records: Sequence[TrialRecord]) -> list[str]:
    """Each adaptive procedure's track as it runs: its last values (✓ right, ✗ wrong, ↺ a
    reversal) and its estimate, one line each, e.g. ``from_above 300✓ 260✓↺ 280✗ · est 240``."""
    tracks: dict[str, list[str]] = {}
    estimates: dict[str, float | None] = {}
    for record in records:
        cells = record.adaptive
        if not record.counts or cells is None or cells.intensity is None \
                or cells.procedure in (CATCH, PRACTICE):
            continue
        mark = ("✓" if cells.correct else "✗") + ("↺" if cells.reversal else "")
        tracks.setdefault(cells.procedure, []).append(f"{cells.intensity:g}{mark}")
        estimates[cells.procedure] = cells.estimate
    lines = []
    for name, track in tracks.items():
        estimate = estimates[name]
        shown = " ".join(track[-TRACK_LENGTH:])
        lines.append(f"{name} {shown}" + ("" if estimate is None else f" · est {estimate:.4g}"))
    return lines
