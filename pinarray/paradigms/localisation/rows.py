"""Localisation's rows: the pin that moved at which frequency, the pin named, its error class.

Its files keep the columns of the releases before the paradigm seam (`LEGACY_LAYOUT`): ``pin``,
``frequency_hz`` and ``error_class`` are its own. The error class (correct, A-D, or none:
nothing felt) follows from the pin named, the pin moved and the run's grid; read back it is
checked against them.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, ClassVar

from pinarray.errors import ResultsError
from pinarray.grid import ErrorClass, Grid
from pinarray.journal.columns import Cell, Column, number_text
from pinarray.journal.manifest import PlanEntry, RunManifest
from pinarray.journal.records import (
    LEGACY_EVENT_LAYOUT,
    LEGACY_LAYOUT,
    TrialFields,
    TrialRecord,
    coerce,
    required,
)
from pinarray.journal.seam import RowsDefaults, pin_levels
from pinarray.paradigms.localisation.design import NOTHING_FELT, LocalisationCondition
from pinarray.protocol.model import Condition

CATEGORY_MEANING = {
    "correct": "the stimulated pin", "A": "adjacent, same row or column",
    "B": "diagonal neighbour", "C": "same row or column, not adjacent",
    "D": "neither on the same row or column nor close", NOTHING_FELT: "nothing felt",
}
COLUMNS = (
    Column("pin", Cell.INTEGER, "Stimulated pin, numbered as the subject sees it (1 = bottom-left, "
           "rising along the bottom row, then row by row upwards); n/a for motion trials.",
           levels_for=pin_levels),
    Column("frequency_hz", Cell.NUMBER, "Stimulation frequency of the moving pin.", units="Hz"),
    Column("error_class", Cell.TEXT, "Localisation answer relative to the stimulated pin.",
           levels=CATEGORY_MEANING),
)


@dataclass(frozen=True, kw_only=True)
class LocalisationRecord(TrialRecord):
    """A localisation trial: ``pin`` moved at ``frequency_hz``; the subject named a pin or none.

    ``response`` is the pin named, as text, or "none" (nothing felt); None when the trial got
    no answer (redone, aborted, invalid). ``error_class`` classifies the pin named.
    """

    paradigm: ClassVar[str] = "localisation"
    pin: int
    frequency_hz: float
    response: str | None = None
    error_class: ErrorClass | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        coerce(self, "error_class", ErrorClass, where)
        text = self.response
        if text is not None and text != NOTHING_FELT and not (
                text.isascii() and text.isdigit() and int(text) >= 1):
            raise ResultsError(f"{where}: a localisation response must be a pin number or "
                               f"'{NOTHING_FELT}', found {text!r}")
        if self.error_class is not None and self.reported_pin is None:
            raise ResultsError(f"{where}: error class {self.error_class} needs a pin named, "
                               f"found the response {text!r}")

    @property
    def reported_pin(self) -> int | None:
        """The pin the subject named; None for nothing felt or no answer."""
        response = self.response
        return int(response) if response and response.isascii() and response.isdigit() else None

    @property
    def nothing_felt(self) -> bool:
        """Whether the subject said nothing was felt."""
        return self.response == NOTHING_FELT

    @property
    def category(self) -> str | None:
        """The ``error_class`` cell: correct, A-D, or "none" (nothing felt); None if no answer."""
        if self.nothing_felt:
            return NOTHING_FELT
        return None if self.error_class is None else self.error_class.value


def frequency_label(task: str, frequency_hz: float) -> str:
    """``<task>_<frequency>hz``: one trial_type level."""
    return f"{task}_{number_text(float(frequency_hz))}hz"


class LocalisationRows(RowsDefaults):
    """Localisation's rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "localisation"
    record_type = LocalisationRecord
    columns = COLUMNS
    layout = LEGACY_LAYOUT
    event_layout = LEGACY_EVENT_LAYOUT
    marker = "pin"
    instructions = ("Rest your fingertip on the pins. After each stimulus, name the pin that "
                    "moved by its number (1 = bottom-left as you feel it), or say 'none' if "
                    "you felt nothing.")

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, LocalisationRecord)
        return {"pin": record.pin, "frequency_hz": record.frequency_hz,
                "response": record.response, "error_class": record.category}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        error_class = values.get("error_class")
        return LocalisationRecord(
            **fields, pin=required(dict(values), "pin", where),
            frequency_hz=required(dict(values), "frequency_hz", where),
            response=values.get("response"),
            error_class=None if error_class in (None, NOTHING_FELT) else error_class)

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, LocalisationCondition)
        named = None if response in (None, NOTHING_FELT) else int(str(response))
        return LocalisationRecord(
            **fields, pin=condition.pin, frequency_hz=float(condition.frequency_hz),
            response=response,
            error_class=None if named is None else grid.classify(condition.pin, named))

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, LocalisationRecord)
        return frequency_label(record.task, record.frequency_hz)

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        levels: dict[str, str] = {}
        for entry in plan:
            frequency = float(Fraction(str(entry["frequency_hz"])))
            levels.setdefault(frequency_label(task, frequency),
                              f"one pin moves at {frequency:g} Hz")
        return dict(sorted(levels.items()))

    def levels(self, manifest: RunManifest) -> dict[str, dict[str, str]]:
        pins = [str(p) for p in manifest.task_info.pins]
        return {"response": {p: f"named pin {p}" for p in pins} | {NOTHING_FELT: "nothing felt"}}

    def offered(self, manifest: RunManifest) -> tuple[str, ...] | None:
        return (*(str(p) for p in manifest.task_info.pins), NOTHING_FELT)

    def check_entry(self, entry: PlanEntry) -> None:
        if isinstance(entry["pin"], bool):
            raise TypeError("a pin is a number")
        int(entry["pin"])
        Fraction(str(entry["frequency_hz"]))

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, LocalisationRecord)
        if record.pin != int(entry["pin"]):
            return f"the plan moves pin {entry['pin']}, the row says pin {record.pin}"
        adapted = record.adaptive is not None and record.adaptive.parameter == "frequency_hz"
        planned = float(Fraction(str(entry["frequency_hz"])))
        if not adapted and record.frequency_hz != planned:
            return (f"the plan plays {planned:g} Hz, the row says "
                    f"{record.frequency_hz:g} Hz")
        info = manifest.task_info
        grid = Grid(info.grid_rows, info.grid_columns, info.pitch_mm)
        named = record.reported_pin
        if named is not None:
            if named > grid.pin_count:
                return f"the answer names pin {named}, which the grid does not have"
            should = grid.classify(record.pin, named)
            if record.error_class is not None and record.error_class is not should:
                return (f"error_class is {record.error_class}, but pin {named} named for pin "
                        f"{record.pin} is {should} (edited by hand?)")
        return None

    def live_lines(self, counted: Sequence[TrialRecord]) -> list[str]:
        classes = Counter(r.category for r in counted if isinstance(r, LocalisationRecord))
        errors = "  ".join(f"{c} {classes.get(c, 0)}" for c in ("A", "B", "C", "D"))
        return [f"correct {classes.get('correct', 0)}/{len(counted)}", errors,
                f"nothing felt {classes.get(NOTHING_FELT, 0)}"]

    def last_line(self, record: TrialRecord) -> str:
        assert isinstance(record, LocalisationRecord)
        answer = "nothing felt" if record.nothing_felt else f"pin {record.response}"
        return f", pin {record.pin} → {answer} ({record.category})"


ROWS = LocalisationRows()
