"""The start screen: protocol, subject, session, experimenter, bus, seed; resume if unfinished."""

from __future__ import annotations

import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, cast

from textual import on
from textual.app import ComposeResult
from textual.containers import Grid, Horizontal, VerticalScroll
from textual.screen import Screen
from textual.widgets import Button, Input, Label, Select, Static

from pinarray.errors import PinArrayError
from pinarray.hardware.feetech.faults import SIM_DEFAULT
from pinarray.journal.paths import check_label
from pinarray.protocol import Protocol
from pinarray.session.sitting import SessionRequest
from pinarray.tui.footer import KeyFooter
from pinarray.tui.notice import KeyNotices, Notice

if TYPE_CHECKING:
    from textual.timer import Timer

    from pinarray.journal.runs import Unfinished
    from pinarray.tui.app import PinArrayApp

SIM = "sim"
HELD_RECHECK_S = 2.0  # how often to look again at a run another process has open


def protocol_files(options) -> list[Path]:
    """The command line's file first, then the protocols folder's YAML files by name."""
    found = sorted(Path(options.protocols_dir).glob("*.yaml")) if options.protocols_dir else []
    first = [Path(options.protocol_path)] if options.protocol_path else []
    return first + [p for p in found if not first or p.resolve() != first[0].resolve()]


class StartScreen(KeyNotices, Screen):
    """Collects a `SessionRequest` and opens the pre-flight screen with it.

    Fits an 80x24 terminal (one-line fields); below that the form scrolls, the buttons and
    the unfinished-run notice just under the fields.

    Parameters
    ----------
    options : TuiOptions
        Command-line choices (protocol file, bus, results folder, seed).
    list_ports : callable
        (device, description) of each serial port found.
    """

    # No first focus of Textual's (the form's scroll, all of its fields styled again as it
    # takes focus and again as it gives it up): on_mount gives it.
    AUTO_FOCUS = ""

    def __init__(self, options, list_ports: Callable[[], list[tuple[str, str]]]):
        super().__init__()
        self.options = options
        self.files = protocol_files(options)
        self.ports = list_ports()
        self._unfinished: Unfinished | None = None
        self._back = False  # shown again after a pre-flight or a run
        self._recheck: Timer | None = None
        # The task label of each protocol file looked at, by (path, modification time, size).
        self._tasks: dict[tuple[str, int, int], str] = {}

    def _new_seed(self) -> str:
        # Shown and recorded before the run starts, so a session can be replayed exactly.
        seed = self.options.seed
        return str(seed if seed is not None else secrets.randbelow(2**31))

    def compose(self) -> ComposeResult:
        sim_url = self.options.sim_url
        faults = f" ({sim_url})" if sim_url and sim_url != SIM_DEFAULT else ""
        buses = [("simulated array" + faults, SIM)]
        buses += [(f"{device} · {about}", device) for device, about in self.ports]
        if self.options.port and self.options.port not in {d for d, _ in self.ports}:
            buses.append((self.options.port, self.options.port))
        yield Static("pinarray · start a session", id="title")
        with VerticalScroll(id="start-form"):
            with Grid(id="fields"):
                yield Label("Protocol")
                yield Select([(p.name, str(p)) for p in self.files], id="protocol",
                             allow_blank=True, compact=True,
                             value=str(self.files[0]) if self.files else Select.BLANK)
                yield Label("Subject")
                yield Input(self.options.subject, placeholder="letters and digits, e.g. 01",
                            id="subject", compact=True)
                yield Label("Session")
                yield Input(self.options.session, id="session", compact=True)
                yield Label("Experimenter")
                yield Input(placeholder="your initials (optional)", id="experimenter",
                            compact=True)
                yield Label("Array")
                yield Select(buses, id="bus", allow_blank=False, value=self.options.port or SIM,
                             compact=True)
                yield Label("Seed")
                yield Input(self._new_seed(), id="seed", type="integer", compact=True)
            yield Static(id="resume-info")
            yield Static(id="start-error")
            with Horizontal(id="start-buttons"):
                yield Button("Start new run", id="start", variant="primary")
                yield Button("Resume", id="resume", disabled=True)
                yield Button("Quit", id="quit")
            yield Notice()
        yield KeyFooter()

    def on_mount(self) -> None:
        self._look_for_unfinished()
        if self._unfinished is not None:
            self.query_one("#resume", Button).focus()  # opened to resume it (--subject ...)
        else:
            self.query_one("#subject", Input).focus()

    def on_screen_resume(self) -> None:
        self.query_one("#seed", Input).value = self._new_seed()  # the next subject's own order
        self._look_for_unfinished()  # back from a run: it may have become resumable
        if self._back:
            # Not a field: keys still arriving from the screen left must not type into one.
            button = "#resume" if self._unfinished is not None else "#start"
            self.query_one(button, Button).focus()
        self._back = True  # the first resume is the screen's first showing

    # -- reading the form --------------------------------------------------------------------

    def _value(self, field: str) -> str:
        return self.query_one(f"#{field}", Input).value.strip()

    def _chosen(self) -> str:
        chosen = self.query_one("#protocol", Select).value
        if chosen is Select.BLANK:
            raise PinArrayError("choose a protocol (none found in protocols/; "
                                "give one on the command line: pinarray tui FILE)")
        return str(chosen)

    def _protocol(self) -> Protocol:
        from pinarray.protocol.load import load_protocol

        return load_protocol(self._chosen())

    def _chosen_task(self) -> str:
        """The chosen protocol's task label: the form looks for an unfinished run at every
        key typed in the subject and session fields, and loads the file again only when it
        changed (Start always loads it afresh)."""
        from pinarray.session.trials import task_label

        chosen = self._chosen()
        try:
            status = os.stat(chosen)
        except OSError:
            return task_label(self._protocol())  # which says what is wrong with the file
        key = (chosen, status.st_mtime_ns, status.st_size)
        if key not in self._tasks:
            self._tasks[key] = task_label(self._protocol())
        return self._tasks[key]

    def _request(self, resume: bool) -> SessionRequest:
        protocol = self._protocol()
        subject = check_label("subject", self._value("subject"))
        session = check_label("session", self._value("session"))
        seed_text = self._value("seed")
        try:
            seed = int(seed_text) if seed_text else None
        except ValueError:
            raise PinArrayError(f"the seed must be a whole number, found {seed_text!r}") from None
        bus = self.query_one("#bus", Select).value
        port = None if bus == SIM else str(bus)
        return SessionRequest(protocol, subject, session, self._value("experimenter"),
                              port, self.options.sim_url if port is None else None, seed, resume)

    @on(Input.Changed)
    @on(Select.Changed)
    def _edited(self) -> None:
        self.query_one("#start-error", Static).update("")  # what it said may be fixed now

    @on(Input.Changed, "#subject, #session")
    @on(Select.Changed, "#protocol")
    def _look_for_unfinished(self) -> None:
        from pinarray.journal.runs import unfinished_run

        info = self.query_one("#resume-info", Static)
        self._unfinished = None
        found, problem = None, ""
        try:
            task = self._chosen_task()
            subject = check_label("subject", self._value("subject"))
            session = check_label("session", self._value("session"))
        except PinArrayError:
            pass  # the form is not complete yet; Start will say what is wrong
        else:
            try:
                found = unfinished_run(self.options.results_root, subject, session, task)
            except PinArrayError as error:  # e.g. a run's lock file that cannot be used
                problem = f"Cannot look for an unfinished run: {error}"
        # A run open in another process (its lock is held) cannot be resumed from here; look
        # again shortly, so the offer appears once that process ends.
        # Nor one a simulated observer or a sheet answered: a person's answers would follow.
        resumable = found is not None and found.holder is None and found.answered_otherwise is None
        if self._recheck is not None:
            self._recheck.stop()
        self._recheck = None
        if found is not None and found.holder is not None:
            self._recheck = self.set_timer(HELD_RECHECK_S, self._look_for_unfinished)
        self.query_one("#resume", Button).disabled = not resumable
        self.query_one("#resume", Button).variant = "primary" if resumable else "default"
        self.query_one("#start", Button).variant = "default" if resumable else "primary"
        info.update(problem or ("" if found is None else found.describe()))
        if resumable and found is not None and found.manifest.seed is not None:
            # The seed beside the offer is the run's: Resume keeps it (a new run would too).
            self.query_one("#seed", Input).value = str(found.manifest.seed)
        self._unfinished = found if resumable else None

    # -- buttons -----------------------------------------------------------------------------

    @on(Button.Pressed, "#start")
    def _start(self) -> None:
        self._go(resume=False)

    @on(Input.Submitted)
    def _enter(self) -> None:
        # Enter continues an unfinished run rather than leaving it behind for a new one.
        self._go(resume=self._unfinished is not None)

    @on(Button.Pressed, "#resume")
    def _resume(self) -> None:
        self._go(resume=True)

    @on(Button.Pressed, "#quit")
    async def _quit(self) -> None:
        await self.app.action_quit()

    def _go(self, resume: bool) -> None:
        from pinarray.tui.preflight_screen import PreflightScreen

        error = self.query_one("#start-error", Static)
        try:
            request = self._request(resume)
        except PinArrayError as problem:
            error.update(str(problem))
            return
        error.update("")
        sitting = cast("PinArrayApp", self.app).sitting
        self.app.push_screen(PreflightScreen(sitting, request))
