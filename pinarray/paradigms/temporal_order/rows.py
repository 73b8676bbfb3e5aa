"""Temporal order's rows: the two pins (A, B) and the SOA of B after A, the pin named first.

Its files keep the columns of the releases before the paradigm seam (`LEGACY_LAYOUT`):
``soa`` is its own; it fills ``pins`` (A then B) and ``correct`` (the pin that started first
named; n/a at an SOA of 0), which follows from them and is checked when read back, as they are
against the run's plan (an adaptive design's SOA is its intensity, either pin first).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from pinarray.errors import ResultsError
from pinarray.grid import Grid
from pinarray.journal.columns import Cell, Column, number_text, pins_cell, pins_text
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
from pinarray.paradigms.temporal_order.design import TemporalOrderCondition
from pinarray.protocol.model import Condition
from pinarray.units import NS_PER_MS

COLUMNS = (
    Column("soa", Cell.SECONDS, "Temporal order: the onset of pin B's train minus pin A's "
           "(the pins column's order): positive when A started first, negative when B did.",
           units="s"),
)


@dataclass(frozen=True, kw_only=True)
class TemporalOrderRecord(TrialRecord):
    """A temporal-order trial: a train on ``pins`` (A, B), B starting ``soa_ns`` after A
    (negative: B first); the subject named the pin that came first (``response``)."""

    paradigm: ClassVar[str] = "temporal_order"
    pins: tuple[int, int]
    soa_ns: int
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        check_pins(self.pins, where, 2)
        if isinstance(self.soa_ns, bool) or not isinstance(self.soa_ns, int):
            raise ResultsError(f"{where}: soa_ns must be whole nanoseconds, found {self.soa_ns!r}")
        if self.response is not None and self.response not in map(str, self.pins):
            raise ResultsError(f"{where}: a temporal-order response must name pin "
                               f"{self.pins[0]} or {self.pins[1]}, found {self.response!r}")

    @property
    def named_a_first(self) -> bool | None:
        """Whether the subject said pin A (the first listed) came first."""
        return None if self.response is None else self.response == str(self.pins[0])

    @property
    def correct(self) -> bool | None:
        """Whether the pin named started first; None without an answer or at an SOA of 0."""
        if self.response is None or self.soa_ns == 0:
            return None
        return self.named_a_first == (self.soa_ns > 0)


class TemporalOrderRows(RowsDefaults):
    """Temporal order's rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "temporal_order"
    sidecar_needs = ("soa",)  # the design's SOAs
    record_type = TemporalOrderRecord
    columns = COLUMNS
    layout = LEGACY_LAYOUT
    event_layout = LEGACY_EVENT_LAYOUT
    marker = "soa"
    instructions = ("Rest your fingertip on the pins. Two pins tap one after the other; say "
                    "which came first.")

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, TemporalOrderRecord)
        return {"pins": pins_text(record.pins), "soa": record.soa_ns,
                "response": record.response, "correct": record.correct}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        pins = pins_cell(required(dict(values), "pins", where), where)
        return TemporalOrderRecord(**fields, pins=pins,  # type: ignore[arg-type]
                                   soa_ns=required(dict(values), "soa", where),
                                   response=values.get("response"))

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, TemporalOrderCondition)
        return TemporalOrderRecord(**fields, pins=condition.pins, soa_ns=condition.soa_ns,
                                   response=response)

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, TemporalOrderRecord)
        return f"{record.task}_soa{number_text(record.soa_ns / 1e6)}ms"

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        levels: dict[str, str] = {}
        for entry in plan:
            soa = number_text(int(entry["soa_ns"]) / 1e6)
            a, b = entry["pins"]
            levels.setdefault(f"{task}_soa{soa}ms", f"pin {b} starts {soa} ms after pin {a}")
        return dict(sorted(levels.items()))

    def check_entry(self, entry: PlanEntry) -> None:
        if entry["soa_ns"] is None or isinstance(entry["soa_ns"], bool):
            raise KeyError("soa_ns")
        int(entry["soa_ns"])
        tuple(int(p) for p in entry["pins"])

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, TemporalOrderRecord)
        planned = tuple(int(p) for p in entry["pins"])
        if record.pins != planned:
            return (f"the plan's pins are {pins_text(planned)}, the row says "
                    f"{pins_text(record.pins)}")
        adaptive = record.adaptive
        if adaptive is None:
            if record.soa_ns != int(entry["soa_ns"]):
                return (f"the plan's SOA is {number_text(int(entry['soa_ns']) / 1e6)} ms, the "
                        f"row says {number_text(record.soa_ns / 1e6)} ms")
        elif adaptive.intensity is not None and abs(record.soa_ns) != round(
                adaptive.intensity * NS_PER_MS):
            return (f"the trial presents an SOA of {number_text(adaptive.intensity)} ms, the row "
                    f"says {number_text(record.soa_ns / 1e6)} ms")
        return None


ROWS = TemporalOrderRows()
