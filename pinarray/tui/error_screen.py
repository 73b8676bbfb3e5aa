"""An error nothing handled: what it was, what became of the pins and the run, what next."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import Screen
from textual.widgets import Static

from pinarray.tui.footer import KeyFooter
from pinarray.tui.notice import KeyNotices, Notice
from pinarray.tui.outcome import Crashed


class ErrorScreen(KeyNotices, Screen):
    """Shown instead of a traceback; leaving it (q, Enter, Escape) ends the app.

    Parameters
    ----------
    crash : Crashed
        The error in one line and where its details were written.
    """

    DEFAULT_CSS = """
    ErrorScreen {
        #error-body { padding: 1 2; }
        #error-what { color: $error; text-style: bold; }
        #error-pins, #error-next { margin-top: 1; }
    }
    """
    BINDINGS = [Binding("q,enter,escape", "leave", "exit")]
    AUTO_FOCUS = None

    def __init__(self, crash: Crashed):
        super().__init__()
        self.crash = crash
        self.done = False

    def compose(self) -> ComposeResult:
        crash = self.crash
        if crash.bug:
            head = "pinarray stopped on an unexpected error (a bug in pinarray, not your doing):"
        else:
            head = "pinarray stopped on an error it could not recover from:"
        where = (f"The details are in {crash.log}; please send that file with a bug report."
                 if crash.log is not None else "Its details could not be written to a file.")
        yield Static("pinarray · stopped", id="title")
        with Vertical(id="error-body"):
            yield Static(head)
            yield Static(crash.what, id="error-what")
            yield Static("Pins: going to rest, torque off…", id="error-pins")
            yield Static("The run in progress is marked crashed and can be resumed: open "
                         "pinarray again and choose Resume on the start screen (the command "
                         "is printed when you leave).", id="error-next")
            yield Static(where, id="error-log")
            yield Notice()
        yield KeyFooter()

    def closed(self, pins: str) -> None:
        """The run is marked and the pins are safe: say so, and let the app be left."""
        self.done = True
        self.query_one("#error-pins", Static).update(f"Pins: {pins}.")
        self.notice.clear()
        self.refresh_keys()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action in ("leave", "quit"):
            return self.done
        return True

    def refusal(self, actions: tuple[str, ...]) -> str:
        return "wait: the pins are going to rest…"

    def action_leave(self) -> None:
        self.app.exit(return_code=1)
