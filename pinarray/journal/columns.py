"""A results table's columns: each one's cell type, words and levels, and how a cell is written
and read back. Pure: no files.

Times are whole nanoseconds in a record and exact decimal seconds in a file; numbers are
written as integers where they are whole ("10", not "10.0"); "n/a" (BIDS's spelling) is a
cell with no value. A column's ``levels`` are fixed (a status's meanings); ``levels_for``
computes them from the run (the pins of its grid), for the run's sidecar.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Mapping, Sequence
from enum import Enum
from typing import TYPE_CHECKING, Any, NamedTuple

from pinarray.errors import ResultsError
from pinarray.journal.timebase import ns_from_seconds, seconds_text

if TYPE_CHECKING:
    from pinarray.journal.manifest import TaskInfo

NA = "n/a"  # BIDS spelling of "not applicable"


class Cell(Enum):
    """How a column's cells are written and read."""

    INTEGER = "integer"
    SECONDS = "seconds"  # whole nanoseconds inside, exact decimal seconds in the file
    NUMBER = "number"
    BOOLEAN = "boolean"
    TEXT = "text"


class Column(NamedTuple):
    """One column of a results table: its name, cell type, description and units; its levels,
    fixed (``levels``: str or StrEnum keys) or of the run (``levels_for``: from its task's
    device, e.g. the pins of its grid)."""

    name: str
    cell: Cell
    description: str
    units: str | None = None
    levels: Mapping[Any, str] | None = None
    levels_for: Callable[[TaskInfo], Mapping[str, str]] | None = None


_BOOLEAN = {"true": True, "false": False}


def number_text(value: float) -> str:
    """A number as a cell: whole numbers as integers ("10", not "10.0"), others exactly."""
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def pins_text(pins: Sequence[int]) -> str:
    """A pins cell: the pins separated by spaces."""
    return " ".join(map(str, pins))


def pins_cell(text: str, where: str) -> tuple[int, ...]:
    """The pins of a pins cell, or a `ResultsError` naming where it cannot hold them."""
    try:
        return tuple(_ascii(int)(p) for p in text.split())
    except ValueError:
        raise ResultsError(f"{where}: column 'pins' cannot hold {text!r}") from None


def _ascii(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """``parse`` of ASCII text only: int() and float() also read other scripts' digits (１)."""
    def parsed(text: str) -> Any:
        if not text.isascii():
            raise ValueError(text)
        return parse(text)
    return parsed


_FORMAT: dict[Cell, Callable[[Any], str]] = {
    Cell.INTEGER: str,
    Cell.SECONDS: seconds_text,
    Cell.NUMBER: lambda value: number_text(float(value)),
    Cell.BOOLEAN: lambda value: "true" if value else "false",
    Cell.TEXT: str,
}
_PARSE: dict[Cell, Callable[[str], Any]] = {
    Cell.INTEGER: _ascii(int),
    Cell.SECONDS: ns_from_seconds,
    Cell.NUMBER: _ascii(float),
    Cell.BOOLEAN: _BOOLEAN.__getitem__,
    Cell.TEXT: str,
}


def cell_text(column: Column, value: Any) -> str:
    """``value`` written in ``column`` (None: n/a)."""
    return NA if value is None else _FORMAT[column.cell](value)


def cell_value(column: Column, text: str, where: str) -> Any:
    """The value of a cell read back (None for n/a); a `ResultsError` naming where when the
    column cannot hold it."""
    if text == NA:
        return None
    try:
        return _PARSE[column.cell](text)
    except (ValueError, KeyError):
        raise ResultsError(f"{where}: column {column.name!r} cannot hold {text!r}") from None


def tsv_line(cells: Sequence[str]) -> str:
    """One row of a tab-separated table, quoted where a cell needs it, ending in a newline."""
    out = io.StringIO()
    csv.writer(out, delimiter="\t", lineterminator="\n").writerow(cells)
    return out.getvalue()


def entry(column: Column) -> dict[str, Any]:
    """A column as a BIDS sidecar describes it: Description, Levels, Units."""
    described: dict[str, Any] = {"Description": column.description}
    if column.levels is not None:
        described["Levels"] = {str(level): meaning for level, meaning in column.levels.items()}
    if column.units is not None:
        described["Units"] = column.units
    return described
