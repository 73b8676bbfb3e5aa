"""Two-point discrimination's rows: the pins pressed, how far apart, the train, one or two.

A paradigm added since the seam: its files hold the common columns, then its own
(``distance``, ``stimulus``); it fills ``pins`` and ``correct`` (``two`` said of two pins,
``one`` of one), which follows from them and is checked when read back, as the pins, the
distance and the train are against the run's plan.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from pinarray.errors import ResultsError
from pinarray.grid import Grid
from pinarray.journal.columns import Cell, Column, number_text, pins_cell, pins_text
from pinarray.journal.manifest import PlanEntry, RunManifest
from pinarray.journal.records import TrialFields, TrialRecord, check_pins, required
from pinarray.journal.seam import RowsDefaults
from pinarray.paradigms.two_point.design import LABEL_DIGITS, ONE, TWO, TwoPointCondition
from pinarray.protocol.model import Condition

COLUMNS = (
    Column("distance", Cell.NUMBER, "Two points: how far apart the two pins pressed are, "
           "centre to centre, from the grid's pitch; 0 when one pin pressed.", units="mm"),
    Column("stimulus", Cell.TEXT, "The train the pins played, by its name in the protocol (the "
           "one-pin trials may rove over several: the design's single_stimuli)."),
)


@dataclass(frozen=True, kw_only=True)
class TwoPointRecord(TrialRecord):
    """A two-point trial: the train ``stimulus`` on ``pins`` at once, one pin or two
    ``distance_mm`` apart (0: one pin); the subject said ``one`` or ``two`` (``response``;
    None when the trial got no answer)."""

    paradigm: ClassVar[str] = "two_point"
    stimulus: str
    pins: tuple[int, ...]
    distance_mm: float
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        check_pins(self.pins, where)
        if len(self.pins) not in (1, 2) or len(set(self.pins)) != len(self.pins):
            raise ResultsError(f"{where}: a two-point trial presses one pin or two different "
                               f"pins, found {pins_text(self.pins)}")
        d = self.distance_mm
        if (isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d)
                or (d == 0) != (len(self.pins) == 1) or d < 0):
            raise ResultsError(f"{where}: a distance of {d!r} mm cannot part "
                               f"{len(self.pins)} pin(s)")
        if not isinstance(self.stimulus, str) or not self.stimulus.strip():
            raise ResultsError(f"{where}: the stimulus must be named, found {self.stimulus!r}")
        if self.response is not None and self.response not in (ONE, TWO):
            raise ResultsError(f"{where}: a two-point response is {ONE} or {TWO}, found "
                               f"{self.response!r}")

    @property
    def said_two(self) -> bool | None:
        """Whether the subject said two; None without an answer."""
        return None if self.response is None else self.response == TWO

    @property
    def correct(self) -> bool | None:
        """Whether the answer counts the pins that pressed; None without an answer."""
        return None if self.said_two is None else self.said_two == (len(self.pins) == 2)


def _distance_text(distance_mm: float) -> str:
    return number_text(round(distance_mm, LABEL_DIGITS))


class TwoPointRows(RowsDefaults):
    """Two-point discrimination's rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "two_point"
    record_type = TwoPointRecord
    columns = COLUMNS
    marker = "distance"
    instructions = ("Rest your fingertip on the pins. One pin or two press at once; say whether "
                    "you felt one point or two.")

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, TwoPointRecord)
        return {"pins": pins_text(record.pins), "distance": record.distance_mm,
                "stimulus": record.stimulus, "response": record.response,
                "correct": record.correct}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        cells = dict(values)
        return TwoPointRecord(**fields, stimulus=required(cells, "stimulus", where),
                              pins=pins_cell(required(cells, "pins", where), where),
                              distance_mm=required(cells, "distance", where),
                              response=cells.get("response"))

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, TwoPointCondition)
        return TwoPointRecord(**fields, stimulus=condition.stimulus, pins=condition.pins,
                              distance_mm=condition.distance_mm, response=response)

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, TwoPointRecord)
        if len(record.pins) == 1:
            return f"{record.task}_one"
        return f"{record.task}_two{_distance_text(record.distance_mm)}mm"

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        levels: dict[str, str] = {}
        for entry in plan:
            if len(entry["pins"]) == 1:
                levels.setdefault(f"{task}_one", "one pin")
            else:
                d = _distance_text(float(entry["distance_mm"]))
                levels.setdefault(f"{task}_two{d}mm", f"two pins {d} mm apart")
        return dict(sorted(levels.items()))

    def check_entry(self, entry: PlanEntry) -> None:
        pins = tuple(int(p) for p in entry["pins"])
        distance = float(entry["distance_mm"])
        if len(pins) not in (1, 2) or not math.isfinite(distance):
            raise ValueError("pins")

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, TwoPointRecord)
        planned = tuple(int(p) for p in entry["pins"])
        if record.pins != planned:
            return (f"the plan's pins are {pins_text(planned)}, the row says "
                    f"{pins_text(record.pins)}")
        if record.distance_mm != float(entry["distance_mm"]):
            return (f"the plan's pins are {number_text(float(entry['distance_mm']))} mm apart, "
                    f"the row says {number_text(record.distance_mm)} mm")
        if record.stimulus != entry.stimulus:
            return f"the plan plays {entry.stimulus!r}, the row says {record.stimulus!r}"
        return None

    def live_lines(self, counted: Sequence[TrialRecord]) -> list[str]:
        rows = [r for r in counted if isinstance(r, TwoPointRecord) and r.said_two is not None]
        one = [r.said_two is True for r in rows if len(r.pins) == 1]
        two = [r.said_two is True for r in rows if len(r.pins) == 2]
        return [f"'two' on one pin {sum(one)}/{len(one)}, on two pins {sum(two)}/{len(two)}"]


ROWS = TwoPointRows()
