"""The pin array as the subject feels it: pin 1 bottom-left, the top row drawn first."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.containers import Grid as GridLayout
from textual.events import Click
from textual.message import Message
from textual.widgets import Static

from pinarray.grid import Grid


class PinCell(Static):
    """One pin; its classes say whether it is used, moving, or the chosen answer."""

    def __init__(self, pin: int):
        super().__init__(str(pin), id=f"pin-{pin}", classes="pin")
        self.pin = pin

    @on(Click)
    def _clicked(self) -> None:
        self.post_message(PinGrid.Selected(self.pin))


class PinGrid(GridLayout):
    """A clickable map of the array that shows which pins are up right now.

    Parameters
    ----------
    grid : pinarray.grid.Grid
        Rows and columns of the array.
    used : iterable of int
        Pins the protocol can move; the others are drawn dimmed.
    """

    class Selected(Message):
        """The experimenter clicked a pin."""

        def __init__(self, pin: int):
            super().__init__()
            self.pin = pin

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
            cell.set_class(cell.pin in lifted, "-lifted")
            cell.set_class(cell.pin in active, "-active")
            cell.set_class(cell.pin == chosen, "-chosen")
