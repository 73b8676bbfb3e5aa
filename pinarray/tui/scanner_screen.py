"""Waiting for the scanner: volumes seen so far, a key trigger's key, and a way back.

Pushed by the pre-flight's Begin run when the run has a scanner (``--trigger`` or the
protocol's ``sync:`` section). It dismisses with the open session once the first counted
volume has come (the run is opened only then), or with None when the experimenter stopped
waiting; a device that does not open or a scanner that sends nothing in time is said here and
no run is started.
"""

from __future__ import annotations

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.events import Key
from textual.screen import Screen
from textual.widgets import Static

from pinarray.errors import PinArrayError
from pinarray.protocol.imaging import KeyTrigger, ScannerSync, SyncError, SyncOverrides
from pinarray.session.sitting import SessionRequest, Sitting
from pinarray.session.trials import Session
from pinarray.tui.footer import KeyFooter

# Redraws of the volume count per second while waiting.
COUNT_FPS = 10


def scanner_settings(request: SessionRequest, overrides: SyncOverrides) -> ScannerSync | None:
    """The run's scanner: the protocol's ``sync:`` with the command line's options on top."""
    sync = overrides.over(request.protocol.sync)
    if sync is not None and request.resume:
        raise SyncError("a run timed from scanner volumes cannot go on in a new scan (its time "
                        "zero was the old scan's first volume): start a new run")
    return sync


class ScannerScreen(Screen[Session | None]):
    """"Waiting for scanner": the trigger, dummy volumes, volumes seen; Esc stops waiting.

    Parameters
    ----------
    sitting : Sitting
        Connected; waits for the scanner in a worker and then opens the run.
    sync : ScannerSync
        The run's trigger, dummy volumes, TR and locking.
    """

    BINDINGS = [Binding("escape", "stop_waiting", "stop waiting")]

    def __init__(self, sitting: Sitting, sync: ScannerSync):
        super().__init__()
        self.sitting = sitting
        self.sync = sync
        self._leaving = False
        self._failed = False
        self._shown = ""  # the volume count as last shown

    def compose(self) -> ComposeResult:
        request = self.sitting.request
        assert request is not None
        yield Static(f"Scanner · {request.protocol.name} · sub-{request.subject} "
                     f"ses-{request.session}", id="title")
        with Vertical(id="scanner-wait"):
            yield Static("WAITING FOR SCANNER…", id="scanner-state")
            yield Static(id="scanner-volumes")
            yield Static(f"trigger {self.sync.describe()}", classes="hint")
            trigger = self.sync.trigger
            press = (f"Each press of {trigger.character!r} here is a volume. "
                     if isinstance(trigger, KeyTrigger) else "")
            yield Static(f"{press}The run starts at the first counted volume and every onset "
                         "is timed from it. Esc: stop waiting (no run is started).",
                         classes="hint")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.set_interval(1 / COUNT_FPS, self._count)
        self._count()
        self._wait()

    def _count(self) -> None:
        scanner = self.sitting.scanner
        seen = scanner.seen if scanner is not None else 0
        needed = self.sync.dummy_volumes + 1
        shown = f"volumes seen: {seen} of {needed} to time zero ({self.sync.dummy_volumes} dummy)"
        if shown != self._shown:  # an update lays the screen out again: only when it changed
            self._shown = shown
            self.query_one("#scanner-volumes", Static).update(shown)

    @work(thread=True, exclusive=True, group="scanner")
    def _wait(self) -> None:
        try:
            scanner = self.sitting.wait_for_scanner(self.sync)
        except PinArrayError as problem:
            self.app.call_from_thread(self._problem, str(problem))
            return
        if scanner is not None:
            self.app.call_from_thread(self._begin)
        # None: stopped (Esc, or the app is quitting): whoever stopped it moves on.

    def _problem(self, text: str) -> None:
        self._failed = True
        state = self.query_one("#scanner-state", Static)
        state.update(f"{text}\nEsc goes back to the pre-flight.")
        state.add_class("-problem")

    def _begin(self) -> None:
        try:
            session = self.sitting.open_session()
        except PinArrayError as problem:
            self.sitting.close_scanner()
            self._problem(f"Cannot open the run: {problem}")
            return
        session.begin()  # the instructions were given before the scan started
        self.dismiss(session)

    def on_key(self, event: Key) -> None:
        scanner = self.sitting.scanner
        if scanner is not None and event.character == scanner.listens_for_key:
            scanner.press()
            event.stop()
            self._count()

    def action_stop_waiting(self) -> None:
        if self._leaving:
            return
        self._leaving = True
        self.query_one("#scanner-state", Static).update("Stopping the wait…")
        self._stop_waiting()

    @work(thread=True, exclusive=True, group="scanner-stop")
    def _stop_waiting(self) -> None:
        if not self._failed:
            self.sitting.abort_wait()
        self.app.call_from_thread(self.dismiss, None)
