"""What the run screen shows that is computed, not drawn: moving pins and running counts.

Pure functions of a compiled trial or of the rows written so far, so they are tested
without a terminal.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.journal.records import (
    Direction,
    LabRecord,
    LocalisationRecord,
    MotionRecord,
    TrialRecord,
    TrialStatus,
)
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


@dataclass(frozen=True)
class LiveCounts:
    """Counted trials so far (main trials with status ok; practice and redone rows aside)."""

    counted: int
    correct: int  # localisation: the stimulated pin named
    error_classes: tuple[tuple[str, int], ...]  # localisation: A-D and "none" felt
    felt: int  # motion: wave trials felt as motion
    wave_trials: int  # motion: trials with a wave (left or right)
    direction_right: int  # motion: felt wave trials named in the right direction
    direction_named: int  # motion: felt wave trials with a direction answer
    practice_done: int
    judged: int = 0  # the lab's paradigms: counted trials with a right answer to give
    judged_right: int = 0  # ... given

    @classmethod
    def of(cls, records: list[TrialRecord]) -> LiveCounts:
        counted = [r for r in records if r.counts]
        judged = [r.correct for r in counted if isinstance(r, LabRecord) and r.correct is not None]
        classes = Counter(r.category for r in counted if isinstance(r, LocalisationRecord))
        waves = [r for r in counted if isinstance(r, MotionRecord) and r.direction != Direction.NONE]
        named = [r for r in waves if r.direction_correct is not None]
        return cls(
            counted=len(counted),
            correct=classes.pop("correct", 0),
            error_classes=tuple((c, classes.get(c, 0)) for c in ("A", "B", "C", "D", "none")),
            felt=sum(1 for r in waves if r.perceived_motion),
            wave_trials=len(waves),
            direction_right=sum(1 for r in named if r.direction_correct),
            direction_named=len(named),
            practice_done=sum(1 for r in records if r.practice and r.status is TrialStatus.OK),
            judged=len(judged),
            judged_right=sum(judged),
        )

    def lines(self, localisation: bool) -> list[str]:
        """Short lines for the counts panel."""
        if localisation:
            errors = "  ".join(f"{c} {n}" for c, n in self.error_classes if c != "none")
            lines = [f"correct {self.correct}/{self.counted}", errors,
                     f"nothing felt {dict(self.error_classes)['none']}"]
        else:
            lines = [f"motion felt {self.felt}/{self.wave_trials} wave trials",
                     f"direction right {self.direction_right}/{self.direction_named}"]
        return lines + self._practice()

    def judged_lines(self) -> list[str]:
        """The counts panel of the lab's paradigms: right answers of those that have one."""
        return [f"correct {self.judged_right}/{self.judged}", *self._practice()]

    def _practice(self) -> list[str]:
        return [f"practice done {self.practice_done} (not counted)"] if self.practice_done else []


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
