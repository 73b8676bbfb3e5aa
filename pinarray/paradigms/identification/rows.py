"""Identification's rows: the pattern presented and its pins, the pattern named (or the count).

Its files keep the columns of the releases before the paradigm seam (`LEGACY_LAYOUT`):
``pattern`` is its own; it fills ``pins`` (every pin of the pattern) and ``correct`` (the
answer names the pattern, or counts its pins), which follows from them and is checked when
read back, as the pattern and its pins are against the run's plan.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from pinarray.grid import Grid
from pinarray.journal.columns import Cell, Column, pins_cell, pins_text
from pinarray.journal.manifest import PlanEntry, RunManifest
from pinarray.journal.records import (
    LEGACY_EVENT_LAYOUT,
    LEGACY_LAYOUT,
    TrialFields,
    TrialRecord,
    check_pins,
    required,
)
from pinarray.journal.seam import RowsDefaults
from pinarray.paradigms.identification.design import IdentificationCondition
from pinarray.protocol.model import Condition

COLUMNS = (
    Column("pattern", Cell.TEXT, "Identification: the pattern presented, by its name in the "
           "protocol; n/a for the other paradigms."),
)


@dataclass(frozen=True, kw_only=True)
class IdentificationRecord(TrialRecord):
    """An identification trial: the pattern stimulus ``pattern`` raised ``pins``; the subject
    named a pattern, or a count of pins (``response``; None when the trial got no answer)."""

    paradigm: ClassVar[str] = "identification"
    pattern: str
    pins: tuple[int, ...]
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        check_pins(self.pins, f"trial {self.trial}")

    @property
    def correct(self) -> bool | None:
        """Whether the answer names the pattern (or, a count, how many pins it raised)."""
        if self.response is None:
            return None
        if self.response.isascii() and self.response.isdigit():
            return int(self.response) == len(self.pins)
        return self.response == self.pattern


class IdentificationRows(RowsDefaults):
    """Identification's rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "identification"
    sidecar_needs = ("pattern",)  # each pattern's pins
    record_type = IdentificationRecord
    columns = COLUMNS
    layout = LEGACY_LAYOUT
    event_layout = LEGACY_EVENT_LAYOUT
    marker = "pattern"
    instructions = ("Rest your fingertip on the pins. After each stimulus, name the shape the "
                    "raised pins made (or how many pins were raised).")

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, IdentificationRecord)
        return {"pattern": record.pattern, "pins": pins_text(record.pins),
                "response": record.response, "correct": record.correct}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        return IdentificationRecord(
            **fields, pattern=values["pattern"],
            pins=pins_cell(required(dict(values), "pins", where), where),
            response=values.get("response"))

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, IdentificationCondition)
        return IdentificationRecord(**fields, pattern=condition.pattern, pins=condition.pins,
                                    response=response)

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, IdentificationRecord)
        return f"{record.task}_{record.pattern}"

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        levels: dict[str, str] = {}
        for entry in plan:
            levels.setdefault(f"{task}_{entry.stimulus}", f"pattern {entry.stimulus} on pins "
                                                          f"{' '.join(map(str, entry['pins']))}")
        return dict(sorted(levels.items()))

    def levels(self, manifest: RunManifest) -> dict[str, dict[str, str]]:
        patterns = {e.stimulus: _pins_words(int(p) for p in e["pins"]) for e in manifest.plan}
        return {"response": dict(manifest.task_info.answers), "pattern": patterns}

    def check_levels(self, record: TrialRecord,
                     levels: Mapping[str, Mapping[str, str]]) -> str | None:
        assert isinstance(record, IdentificationRecord)
        said = levels.get("pattern", {}).get(record.pattern)
        if said is not None and said != _pins_words(record.pins):
            return (f"pattern {record.pattern!r} raises {said}, the row says "
                    f"{_pins_words(record.pins)}")
        return None

    def check_entry(self, entry: PlanEntry) -> None:
        if entry["pattern"] is None:
            raise KeyError("pattern")
        tuple(int(p) for p in entry["pins"])

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, IdentificationRecord)
        if record.pattern != entry["pattern"]:
            return f"the plan presents pattern {entry['pattern']!r}, the row says {record.pattern!r}"
        planned = tuple(int(p) for p in entry["pins"])
        if record.pins != planned:
            return (f"the plan's pattern raises pins {pins_text(planned)}, the row says "
                    f"{pins_text(record.pins)}")
        return None


def _pins_words(pins: Iterable[int]) -> str:
    """A pattern's pins as its ``pattern`` level says them (``pins 1 6 11 16``)."""
    return f"pins {' '.join(map(str, pins))}"


ROWS = IdentificationRows()
