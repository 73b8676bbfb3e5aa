"""A yes/no question over the current screen."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Static

from pinarray.tui.notice import KeyNotices, Notice


class Confirm(KeyNotices, ModalScreen[bool]):
    """Ask ``question``; dismisses with True for yes (y) and False for no (n, Escape).

    Any other key is answered with a notice: a Space or Enter meant for the run behind the
    question must not pass for an answer (Enter presses the focused No).
    """

    DEFAULT_CSS = """
    Confirm {
        align: center middle;
        #dialog {
            width: 64;
            max-width: 100%;
            height: auto;
            border: thick $error;
            background: $surface;
            padding: 1 2;
        }
        #dialog-buttons { height: auto; margin-top: 1; }
        #dialog-buttons Button { margin-right: 2; }
    }
    """
    BINDINGS = [Binding("y", "answer(True)", "yes"), Binding("n,escape", "answer(False)", "no")]

    def __init__(self, question: str):
        super().__init__()
        self.question = question
        self._answered = False

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Static(self.question, id="question")
            with Horizontal(id="dialog-buttons"):
                yield Button("Yes (y)", id="yes", variant="error")
                yield Button("No (n)", id="no", variant="primary")
            yield Notice()

    def on_mount(self) -> None:
        self.query_one("#no", Button).focus()

    def unbound(self, key: str) -> str:
        return "y: yes · n or Escape: no"

    def action_answer(self, yes: bool) -> None:
        if not self._answered:  # y twice in a burst: the second one is not for this question
            self._answered = True
            self.dismiss(yes)

    @on(Button.Pressed)
    def _pressed(self, event: Button.Pressed) -> None:
        self.action_answer(event.button.id == "yes")
