"""The end of a run: the summary `pinarray analyse` would give, and where the files went."""

from __future__ import annotations

from pathlib import Path

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import Button, Static

from pinarray.analysis import summary_lines
from pinarray.session.sitting import Sitting
from pinarray.session.trials import Phase, Session
from pinarray.tui.footer import KeyFooter
from pinarray.tui.notice import KeyNotices, Notice


def shown_path(path: Path) -> str:
    """A path relative to the working folder when it is inside it (shorter, and copyable)."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


class EndScreen(KeyNotices, Screen):
    """How the run ended, its numbers, its files, and how the pins were left.

    Parameters
    ----------
    session : Session
        The finished or aborted run.
    sitting : Sitting
        For the results folder.
    safe_stop : SafeStopReport or None
        What the final rest-and-release achieved.
    """

    BINDINGS = [Binding("n", "new", "new session")]
    # Nothing focused: Enter or Space still arriving from the last trial must not leave.
    AUTO_FOCUS = None

    def __init__(self, session: Session, sitting: Sitting, safe_stop):
        super().__init__()
        self.session = session
        self.sitting = sitting
        self.safe_stop = safe_stop

    def compose(self) -> ComposeResult:
        session, paths = self.session, self.session.writer.paths
        manifest = session.writer.manifest
        counted = sum(1 for t in session.plan.trials if not t.practice)
        practice = session.total - counted
        if session.phase is Phase.DONE:
            extra = f" and {practice} practice" if practice else ""
            headline = f"Run {paths.run} complete: {counted} trials{extra}."
        else:
            extra = (f" (practice {session.done_of(practice=True)} of {practice})"
                     if practice else "")
            headline = (f"Run {paths.run} aborted ({manifest.abort_reason}) after "
                        f"{session.done_of(practice=False)} of {counted} trials{extra}. "
                        "Resume it from the start screen: same subject, session and protocol.")
        pins = self.safe_stop.describe() if self.safe_stop is not None else "not connected"
        outcome = "-done" if session.phase is Phase.DONE else "-aborted"
        files = (paths.beh_tsv, paths.events_tsv, paths.manifest)
        yield Static(f"{session.protocol.name} · sub-{paths.subject} ses-{paths.session}",
                     id="title")
        with Vertical(id="end-body"):
            yield Static(headline, id="headline", classes=outcome)
            # What may not fit a small terminal (a long summary, results paths that wrap)
            # scrolls; the buttons and the notice below keep their rows.
            with VerticalScroll(id="end-info", can_focus=False):
                yield Static("Summary (main trials with status ok, as `pinarray analyse` "
                             "counts them)", classes="caption")
                yield Static("\n".join(summary_lines(session.records)), id="summary")
                yield Static("Files", classes="caption")
                yield Static("\n".join(shown_path(p) for p in files), id="files")
                yield Static(f"Pins: {pins}", id="pins-left")
            with Horizontal(id="end-buttons"):
                yield Button("New session (n)", id="new", variant="primary")
                yield Button("Quit (q)", id="quit")
            yield Notice()
        yield KeyFooter()

    @on(Button.Pressed, "#new")
    def action_new(self) -> None:
        if self.is_current:  # n twice: the second is not for the start screen's form
            self.app.pop_screen()  # the start screen is underneath

    @on(Button.Pressed, "#quit")
    async def _quit(self) -> None:
        await self.app.action_quit()
