"""The pin array as the subject feels it: pin 1 bottom-left, the top row drawn first."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.containers import Grid as GridLayout
from textual.events import Click
from textual.message import Message
from textual.widgets import Static

from pinarray.grid import Grid

MARKS = frozenset({"-lifted", "-active", "-chosen"})  # what `PinGrid.show` marks a pin with


class PinCell(Static):
    """One pin; its classes say whether it is used, moving, or the chosen answer."""

    DEFAULT_CSS = """
    PinCell {
        width: 100%;
        height: 100%;
        content-align: center middle;
        border: round $primary;
        text-style: bold;
        &.-unused { color: $text-disabled; border: round $panel; }
        &.-active { border: heavy $warning; }
        &.-lifted { background: $warning; color: $background; }
        &.-chosen { background: $accent; color: $background; }
    }
    """

    def __init__(self, pin: int):
        super().__init__(str(pin), id=f"pin-{pin}", classes="pin")
        self.pin = pin

    @on(Click)
    def _clicked(self) -> None:
        grid = self.parent
        assert isinstance(grid, PinGrid)
        self.post_message(PinGrid.Selected(grid, self.pin))


class PinGrid(GridLayout):
    """A clickable map of the array that shows which pins are up right now.

    Parameters
    ----------
    grid : pinarray.grid.Grid
        Rows and columns of the array.
    used : iterable of int
        Pins the protocol can move; the others are drawn dimmed.
    """

    DEFAULT_CSS = """
    PinGrid {
        grid-gutter: 0 1;
        width: 39;
        height: 16;
    }
    """

    class Selected(Message):
        """The experimenter clicked ``pin`` on ``grid`` (``@on(..., "#id")`` matches on it)."""

        def __init__(self, grid: PinGrid, pin: int):
            super().__init__()
            self.grid = grid
            self.pin = pin

        @property
        def control(self) -> PinGrid:
            return self.grid

    def __init__(self, grid: Grid, used=(), **kwargs):
        super().__init__(**kwargs)
        self.grid = grid
        self.used = frozenset(used)

    def compose(self) -> ComposeResult:
        for row in reversed(range(self.grid.rows)):  # the subject's far (top) row first
            for pin in self.grid.row_pins(row):
                cell = PinCell(pin)
                cell.set_class(pin not in self.used, "-unused")
                yield cell

    def on_mount(self) -> None:
        self.styles.grid_size_columns = self.grid.columns
        self.styles.grid_size_rows = self.grid.rows

    def show(self, lifted: frozenset[int] = frozenset(), active: frozenset[int] = frozenset(),
             chosen: int | None = None) -> None:
        """Mark pins that are up now, pins the trial drives, and the answer being entered."""
        for cell in self.query(PinCell):
            marks = {name for name, marked in (("-lifted", cell.pin in lifted),
                                               ("-active", cell.pin in active),
                                               ("-chosen", cell.pin == chosen)) if marked}
            classes = (cell.classes - MARKS) | marks
            if classes != cell.classes:  # styled again once, however many marks changed
                cell.set_classes(classes)
