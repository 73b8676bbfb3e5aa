"""The pin grid as the subject feels it, and the seed's localisation error classes A-D.

Numbering follows the seed (Fig. 9.12): pin 1 is bottom-left, numbers rise left to right
along a row, then row by row upwards; on the default 4x4 grid pin 16 is top-right::

    13 14 15 16
     9 10 11 12
     5  6  7  8
     1  2  3  4

Rows and columns are 0-based internally (row 0 is the bottom row, column 0 the left column);
pins are 1-based, as the lab numbers them.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from pinarray.errors import PinArrayError


class ErrorClass(StrEnum):
    """How a localisation response relates to the stimulated pin (seed section 9.7.1)."""

    CORRECT = "correct"
    A = "A"  # adjacent on the same row or column
    B = "B"  # diagonal neighbour
    C = "C"  # same row or column, not adjacent
    D = "D"  # none of these


ERROR_CLASS_MEANING: dict[ErrorClass, str] = {
    ErrorClass.CORRECT: "the stimulated pin itself",
    ErrorClass.A: "adjacent on the same row or column",
    ErrorClass.B: "diagonal neighbour (close, not on the same row or column)",
    ErrorClass.C: "same row or column, not adjacent",
    ErrorClass.D: "neither on the same row or column nor close",
}


@dataclass(frozen=True)
class Grid:
    """An N x M pin grid with a fixed pitch between neighbouring pins.

    Parameters
    ----------
    rows, columns : int
        Grid size; at least 1 each.
    pitch_mm : float
        Centre-to-centre distance between neighbouring pins, in millimetres.
    """

    rows: int = 4
    columns: int = 4
    pitch_mm: float = 2.0

    def __post_init__(self) -> None:
        if self.rows < 1 or self.columns < 1:
            raise PinArrayError(
                f"a grid needs at least 1 row and 1 column, found {self.rows}x{self.columns}"
            )
        if not self.pitch_mm > 0:
            raise PinArrayError(f"grid pitch must be positive (mm), found {self.pitch_mm}")

    @property
    def pin_count(self) -> int:
        return self.rows * self.columns

    @property
    def pins(self) -> range:
        """All pin numbers, 1..rows*columns."""
        return range(1, self.pin_count + 1)

    def check_pin(self, pin: int) -> int:
        """Return ``pin`` if it is on this grid, else raise a `PinArrayError` naming the range."""
        if isinstance(pin, bool) or not isinstance(pin, int) or not 1 <= pin <= self.pin_count:
            raise PinArrayError(
                f"pin {pin!r} is not on the {self.rows}x{self.columns} grid: "
                f"expected a pin from 1 to {self.pin_count}"
            )
        return pin

    def cell(self, pin: int) -> tuple[int, int]:
        """(row, column) of ``pin``, 0-based, row 0 at the bottom."""
        self.check_pin(pin)
        return divmod(pin - 1, self.columns)

    def pin_at(self, row: int, column: int) -> int:
        """The pin at 0-based (row, column), row 0 at the bottom."""
        if not (0 <= row < self.rows and 0 <= column < self.columns):
            raise PinArrayError(
                f"cell (row {row}, column {column}) is not on the {self.rows}x{self.columns} "
                f"grid: rows 0..{self.rows - 1}, columns 0..{self.columns - 1}"
            )
        return row * self.columns + column + 1

    def position_mm(self, pin: int) -> tuple[float, float]:
        """(x, y) of the pin's centre in mm from pin 1; x rightwards, y upwards."""
        row, column = self.cell(pin)
        return (column * self.pitch_mm, row * self.pitch_mm)

    def row_pins(self, row: int) -> tuple[int, ...]:
        """Pins of a 0-based row (0 = bottom), left to right."""
        return tuple(self.pin_at(row, c) for c in range(self.columns))

    def column_pins(self, column: int) -> tuple[int, ...]:
        """Pins of a 0-based column (0 = left), bottom to top."""
        return tuple(self.pin_at(r, column) for r in range(self.rows))

    def neighbours(self, pin: int) -> frozenset[int]:
        """The up to 8 pins touching ``pin``: same row/column adjacent plus diagonals."""
        row, column = self.cell(pin)
        return frozenset(
            self.pin_at(r, c)
            for r in range(max(0, row - 1), min(self.rows, row + 2))
            for c in range(max(0, column - 1), min(self.columns, column + 2))
            if (r, c) != (row, column)
        )

    def classify(self, stimulated: int, reported: int) -> ErrorClass:
        """Classify a localisation response as the seed does (section 9.7.1).

        ``correct`` when the reported pin is the stimulated one; ``A`` adjacent on the same row
        or column; ``B`` diagonal neighbour; ``C`` same row or column but not adjacent; ``D``
        anything else.
        """
        s_row, s_col = self.cell(stimulated)
        r_row, r_col = self.cell(reported)
        d_row, d_col = abs(s_row - r_row), abs(s_col - r_col)
        if d_row == 0 and d_col == 0:
            return ErrorClass.CORRECT
        if d_row + d_col == 1:
            return ErrorClass.A
        if d_row == 1 and d_col == 1:
            return ErrorClass.B
        if d_row == 0 or d_col == 0:
            return ErrorClass.C
        return ErrorClass.D


DEFAULT_GRID = Grid()


def classify(stimulated: int, reported: int) -> str:
    """Error class of a response on the default 4x4 grid: "correct", "A", "B", "C" or "D"."""
    return DEFAULT_GRID.classify(stimulated, reported).value


def render_layout(grid: Grid) -> str:
    """The grid's numbering as the subject sees it, top row first."""
    width = len(str(grid.pin_count))
    return "\n".join(
        " ".join(f"{p:>{width}}" for p in grid.row_pins(row)) for row in reversed(range(grid.rows))
    )


def render_class_map(grid: Grid, stimulated: int) -> str:
    """Each pin's error class if reported when ``stimulated`` moved, laid out like the grid."""
    marks = {ErrorClass.CORRECT: "*"}
    return "\n".join(
        " ".join(
            marks.get(c, c.value)
            for c in (grid.classify(stimulated, p) for p in grid.row_pins(row))
        )
        for row in reversed(range(grid.rows))
    )
