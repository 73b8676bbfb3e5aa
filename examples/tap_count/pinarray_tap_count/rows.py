"""Tap counting's rows: the pin, how many taps, the count said.

The rows side of the paradigm seam (`pinarray.journal.seam.ParadigmRows`): the record type,
the columns a row adds to every row's (`pins`, `response` and `correct` are common ones it
fills; ``taps`` is its own), and how a row is made, read back and checked against its run's
plan. pinarray keeps the rest for every paradigm: each cell is written and parsed by its
column's type, the record rebuilt from the cells read must write the same cells again (a
``correct`` edited by hand is refused), the task and trial must be the run's, the answer one
the design offered.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from pinarray.errors import ResultsError
from pinarray.grid import Grid
from pinarray.journal.columns import Cell, Column, pins_cell
from pinarray.journal.manifest import PlanEntry, RunManifest
from pinarray.journal.records import TrialFields, TrialRecord, required
from pinarray.journal.seam import RowsDefaults
from pinarray.protocol.model import Condition
from pinarray_tap_count.design import TapCountCondition

COLUMNS = (Column("taps", Cell.INTEGER, "Tap counting: how many times the pin tapped."),)


# --8<-- [start:record]
@dataclass(frozen=True, kw_only=True)
class TapCountRecord(TrialRecord):
    """A tap-counting trial: ``pin`` tapped ``taps`` times; the subject said ``response``."""

    paradigm: ClassVar[str] = "tap_count"
    pin: int
    taps: int
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (isinstance(self.taps, int) and self.taps >= 1):
            raise ResultsError(f"trial {self.trial}: taps must be a count, found {self.taps!r}")
        if self.response is not None and not self.response.isdigit():
            raise ResultsError(f"trial {self.trial}: a tap count is said in digits, found "
                               f"{self.response!r}")

    @property
    def correct(self) -> bool | None:
        """Whether the count said is the taps made; None without an answer."""
        return None if self.response is None else self.response == str(self.taps)
# --8<-- [end:record]


# --8<-- [start:rows]
class TapCountRows(RowsDefaults):
    """Tap counting's rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "tap_count"
    record_type = TapCountRecord
    columns = COLUMNS
    marker = "taps"  # a column only its rows fill: a file read without its manifest is known
    instructions = "Rest your fingertip on the pins. One pin taps a few times; say how many."

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, TapCountRecord)
        return {"pins": str(record.pin), "taps": record.taps, "response": record.response,
                "correct": record.correct}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        cells = dict(values)
        pins = pins_cell(required(cells, "pins", where), where)
        if len(pins) != 1:
            raise ResultsError(f"{where}: a tap-counting trial taps one pin, found {pins}")
        return TapCountRecord(**fields, pin=pins[0], taps=required(cells, "taps", where),
                              response=cells.get("response"))

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, TapCountCondition)
        return TapCountRecord(**fields, pin=condition.pin, taps=condition.taps,
                              response=response)

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, TapCountRecord)
        return f"{record.task}_taps{record.taps}"

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        return {f"{task}_taps{taps}": f"{taps} taps"
                for taps in sorted({int(e["taps"]) for e in plan})}

    def check_entry(self, entry: PlanEntry) -> None:
        int(entry["pin"]), int(entry["taps"])

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, TapCountRecord)
        if (record.pin, record.taps) != (int(entry["pin"]), int(entry["taps"])):
            return (f"the plan taps pin {entry['pin']} {entry['taps']} times, the row says "
                    f"pin {record.pin} {record.taps} times")
        return None


ROWS = TapCountRows()
# --8<-- [end:rows]
