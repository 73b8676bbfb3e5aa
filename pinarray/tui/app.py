"""The experimenter's app: start -> pre-flight -> run -> end, over one `Sitting`.

However the app is left (q, Ctrl-C, a signal, an error nothing handled) the run in progress
is closed, the pins go to rest with torque off, and `outcome` gives the one line and the exit
status the command prints and returns (`pinarray.tui.outcome`).
"""

from __future__ import annotations

import asyncio
import os
import signal
import termios
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from textual.app import App
from textual.binding import Binding
from textual.message_pump import active_message_pump
from textual.screen import Screen
from textual.worker import WorkerFailed

from pinarray.clock import Clock, MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.journal.manifest import RunStatus
from pinarray.journal.paths import DEFAULT_RESULTS_ROOT
from pinarray.player.rig import Rig, choose_clock
from pinarray.protocol.imaging import SyncOverrides
from pinarray.session.sitting import QUIT_REASON, RigFactory, Sitting
from pinarray.session.trials import Session
from pinarray.stop import SignalTap, on_loop_signals, signal_name
from pinarray.tui.outcome import (
    Crashed,
    Ending,
    Quit,
    RunOutcome,
    Signalled,
    exit_status,
    farewell,
    resume_command,
)
from pinarray.version import __version__

TERMINAL_FD = 0  # the terminal Textual reads keys from (standard input)
TERMINAL_CHECK_S = 1.0  # how often the UI looks whether its terminal is still there
# The event loop says it is at work this often (`_beat`). A stop signal come while it has not
# said so for LOOP_HELD_NS is acted on from the terminal's watch: the loop is held (by a
# terminal that stopped reading: Textual's output queue full) and would never act on it, or
# never leave. A loop at work is left to close as it does, however long the pins take to rest.
LOOP_BEAT_S = 0.5
LOOP_HELD_NS = 3_000_000_000


@dataclass(frozen=True)
class TuiOptions:
    """What the command line fixes before the start screen opens."""

    protocol_path: Path | None = None
    protocols_dir: Path = Path("protocols")
    results_root: Path = DEFAULT_RESULTS_ROOT
    port: str | None = None  # real servos; None: the simulator
    sim_url: str | None = None
    time_scale: float = 1.0  # simulator only: times real time; 0 = virtual time
    seed: int | None = None
    # The pre-flight's wake-up measurement: None as long as the protocol needs; 0 = skip.
    timing_check_ns: int | None = None
    subject: str = ""  # the start screen's fields filled in (e.g. to resume a run)
    session: str = "1"
    sync: SyncOverrides = SyncOverrides()  # scanner options over the protocol's sync: section
    lsl: str | None = None  # LSL marker stream name; None: no outlet


def serial_ports() -> list[tuple[str, str]]:
    """(device, description) of each serial port pyserial finds."""
    from serial.tools.list_ports import comports

    return [(port.device, port.description) for port in comports()]


class PinArrayApp(App[None]):
    """Runs subjects through protocols on the pin array.

    Parameters
    ----------
    options : TuiOptions
        Command-line choices.
    clock_factory : callable, optional
        ``clock_factory(port)`` gives each connection's clock; tests pass a virtual one.
    rig_factory : callable, optional
        Makes the `Rig`; tests wrap it to inject faults.
    list_ports : callable, optional
        Lists serial ports for the start screen.
    """

    CSS_PATH = "pinarray.tcss"
    TITLE = "pinarray"
    # The command palette would be a second way to do things the footer does not show.
    ENABLE_COMMAND_PALETTE = False
    # Screens get -short below 32 rows and -narrow below 100 columns (the 80x24 terminal):
    # buttons one row tall, rows of buttons in two, the pin grid smaller (pinarray.tcss).
    VERTICAL_BREAKPOINTS = [(0, "-short"), (32, "-tall")]
    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (100, "-wide")]
    BINDINGS = [
        Binding("q", "quit", "quit"),
        # In the UI Ctrl-C is a key, not a signal: it leaves the run resumable and the pins at
        # rest like q, and the exit status says SIGINT as the other commands' would.
        Binding("ctrl+c", "interrupt", "quit", priority=True, show=False),
    ]

    def __init__(self, options: TuiOptions = TuiOptions(),
                 clock_factory: Callable[[str | None], Clock] | None = None,
                 rig_factory: RigFactory = Rig,
                 list_ports: Callable[[], list[tuple[str, str]]] = serial_ports):
        super().__init__()
        self.options = options
        scale = options.time_scale
        self.sitting = Sitting(
            options.results_root,
            clock_factory or (lambda port: choose_clock(port, None if port else scale,
                                                             sim_url=options.sim_url)),
            rig_factory, lsl_name=options.lsl)
        self.list_ports = list_ports
        self.ending: Ending = Quit()
        self._leaving_app = False
        self._crash_closed = False  # after an error: the run is marked and the pins rest
        # The terminal's watch (`_watch_terminal`) stops looking at the terminal once the app
        # has unmounted, and ends once `run` has returned.
        self._unmounted = threading.Event()
        self._returned = threading.Event()
        self._tap: SignalTap | None = None
        self._beat_clock = MonotonicClock()
        self._beat_ns = self._beat_clock.now_ns()  # when the event loop last said it is at work

    # -- screens ------------------------------------------------------------------------------

    def push_screen(self, screen, *args, **kwargs):  # type: ignore[no-untyped-def, override]
        _sized(self, screen)
        return super().push_screen(screen, *args, **kwargs)

    def switch_screen(self, screen, *args, **kwargs):  # type: ignore[no-untyped-def, override]
        _sized(self, screen)
        return super().switch_screen(screen, *args, **kwargs)

    def on_mount(self) -> None:
        from pinarray.tui.start_screen import StartScreen

        self.push_screen(StartScreen(self.options, self.list_ports))
        try:
            # Any stop signal: same as q. Closing the terminal: see `_leave_at_once`.
            taken = on_loop_signals(asyncio.get_running_loop(), self.sitting.stop,
                                    self._signalled)
        except (NotImplementedError, RuntimeError, ValueError, AttributeError):
            taken = ()  # not the main thread (tests) or no such signals (Windows)
        early = self.sitting.stop.signal_number
        if early is not None:  # came as the UI started (`pinarray.cli.tui`): acted on now
            self._signalled(early)
        if os.isatty(TERMINAL_FD):
            # A terminal can vanish without a SIGHUP reaching us (a shell that ignores it, a
            # closed tmux pane whose shell was the session leader): Textual's input thread then
            # spins on end-of-file forever. Looking at the terminal now and then catches it,
            # from a thread of its own: a terminal that stopped reading (an SSH link frozen)
            # fills Textual's output queue, and the event loop waits on that queue, signals and
            # all, until the terminal reads again; once it is gone, for good (the UI stayed,
            # spinning, with the port held, deaf to SIGTERM). The thread hears the signals too.
            self._tap = SignalTap(taken) if taken else None
            self.set_interval(LOOP_BEAT_S, self._beat)
            threading.Thread(target=self._watch_terminal, args=(self._tap,),
                             name="terminal-watch", daemon=True).start()

    def on_unmount(self) -> None:
        self._unmounted.set()

    def run(self, *args, **kwargs):  # type: ignore[no-untyped-def, override]
        try:
            return super().run(*args, **kwargs)
        finally:
            if self._tap is not None:
                self._tap.detach()  # the loop has closed: the watch no longer hears signals
            self._returned.set()

    def _beat(self) -> None:
        self._beat_ns = self._beat_clock.now_ns()

    def _watch_terminal(self, tap: SignalTap | None) -> None:
        # A thread of the composition root: it waits on the pipe and the events it watches,
        # and reads the loop's beat on the clock the loop writes it with.
        clock = self._beat_clock
        first: tuple[int, int] | None = None  # the first stop signal: (number, ns it came at)
        try:
            while not self._returned.is_set():
                if tap is None:
                    if self._unmounted.wait(TERMINAL_CHECK_S):
                        return
                else:
                    for number in tap.wait(TERMINAL_CHECK_S,
                                           forward=not self._unmounted.is_set()):
                        first = first or (number, clock.now_ns())
                now_ns = clock.now_ns()
                if (first is not None and now_ns - first[1] > LOOP_HELD_NS
                        and now_ns - self._beat_ns > LOOP_HELD_NS and not self._returned.is_set()):
                    self._leave_at_once(first[0])  # the loop is held: it never will
                if not self._unmounted.is_set():
                    try:
                        termios.tcgetattr(TERMINAL_FD)
                    except (termios.error, OSError):  # EIO: the terminal hung up
                        self._leave_at_once(signal.SIGHUP)
        finally:
            if tap is not None and self._returned.is_set():
                tap.close()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action in ("quit", "interrupt") and isinstance(self.ending, Crashed):
            return self._crash_closed  # after an error: once the pins are safe
        return True

    # -- leaving ------------------------------------------------------------------------------

    def _signalled(self, signal_number: int) -> None:
        if signal_number == signal.SIGHUP:
            self._leave_at_once(signal.SIGHUP)
        else:
            self.call_later(self._close, f"stopped by {signal_name(signal_number)}",
                            Signalled(signal_number))

    def _leave_at_once(self, signal_number: int) -> None:
        """The terminal is gone (SIGHUP), or the event loop is held and cannot act on a stop
        signal: close the run and rest the pins, then leave at once, with 128 + the signal.

        A normal exit would restore a terminal that no longer exists, and Textual's driver
        then waits forever (seen closing a tmux window mid-run); a held loop never gets to
        it. Rows and the manifest are already fsync'd by the time `Sitting.finish` returns,
        so nothing is lost by not unwinding.
        """
        reason = f"stopped by {signal_name(signal_number)}"
        # Asked as a signal asks it (the loop's handler may never have run): a connection a
        # worker is making meanwhile keeps the stop, and gives up.
        self.sitting.stop.request(reason, signal_number)
        try:
            self.sitting.finish(reason)
        finally:  # the pins rest before any error marking the run is raised: leave all the same
            os._exit(128 + signal_number)

    def finish_run(self, session: Session, reason: str) -> None:
        """End the run (aborted with ``reason`` unless complete) and show the end screen."""
        from pinarray.tui.end_screen import EndScreen

        def close() -> None:
            safe = self.sitting.finish(reason or QUIT_REASON)
            self.call_from_thread(self.switch_screen, EndScreen(session, self.sitting, safe))

        self.run_worker(close, thread=True, group="close", name="finish run")

    async def action_quit(self) -> None:
        """Cut a stimulus short, mark the run aborted (resumable), pins to rest, exit."""
        await self._close(QUIT_REASON, Quit())

    async def action_interrupt(self) -> None:
        await self._close("interrupted (Ctrl-C)", Signalled(signal.SIGINT))

    async def _close(self, reason: str, ending: Ending) -> None:
        if isinstance(self.ending, Crashed):
            if self._crash_closed:  # from the error screen, once the pins are safe
                self.exit(return_code=1)
            return
        if self._leaving_app:
            return  # a second q (or a signal) while closing: already on the way out
        self._leaving_app = True
        self.ending = ending
        worker = self.run_worker(lambda: self.sitting.finish(reason), thread=True, group="close",
                                 name="quit")
        await worker.wait()
        self.exit()

    def outcome(self) -> tuple[int, str]:
        """The exit status and the one line that says what happened and how to continue.

        Call once the app has stopped (it closes whatever is still open first).
        """
        self.sitting.finish(QUIT_REASON)
        runs = []
        for request, session in self.sitting.runs:
            manifest = session.writer.manifest
            command = resume_command(request.protocol.source, request.subject, request.session,
                                     self.options.results_root, request.port, request.sim_url)
            counted = (session.done_of(practice=False),
                       sum(1 for t in session.plan.trials if not t.practice))
            practice = (session.done_of(practice=True), session.total - counted[1])
            label = f"run {session.writer.paths.run} of sub-{request.subject} ses-{request.session} task-{request.task}"
            runs.append(RunOutcome(label, RunStatus(manifest.status), manifest.abort_reason or "",
                                   counted, practice, command))
        safe = self.sitting.last_safe
        pins = safe.describe() if safe is not None else ""
        return exit_status(self.ending, runs), farewell(self.ending, runs, pins)

    # -- errors nothing handled ---------------------------------------------------------------

    def _handle_exception(self, error: Exception) -> None:
        # Textual has no public hook for this (Textualize/textual#2818, #5325): every error
        # no handler, timer or worker caught ends here, and Textual would print a traceback
        # on exit. Here it becomes a crashed (resumable) run, pins at rest, the error screen.
        if isinstance(self.ending, Crashed):
            self.exit()  # a second error while closing after the first: leave as we are
            return
        cause = error.error if isinstance(error, WorkerFailed) else error
        self.ending = crash = Crashed(
            str(cause) if isinstance(cause, PinArrayError) else f"{type(cause).__name__}: {cause}",
            _write_crash_log(self.options.results_root, cause),
            not isinstance(cause, PinArrayError))
        if active_message_pump.get(None) is self or not self.is_running:
            # The app's own loop is ending with this error: close here, then leave.
            self._close_after_crash(crash)
            self.exit(return_code=1)
            return
        from pinarray.tui.error_screen import ErrorScreen

        self._leaving_app = True
        screen = ErrorScreen(crash)
        self.push_screen(screen)

        def close() -> None:
            pins = self._close_after_crash(crash)
            self._crash_closed = True
            self.call_from_thread(screen.closed, pins)

        self.run_worker(close, thread=True, group="close", name="crash", exit_on_error=False)

    def _close_after_crash(self, crash: Crashed) -> str:
        """Mark the run crashed and rest the pins; what became of them, in words."""
        try:
            self.sitting.finish(f"crashed: {crash.what}", RunStatus.CRASHED)
            note = ""
        except Exception as problem:  # noqa: BLE001 - the pins went to rest all the same
            note = f" (the run could not be marked crashed: {problem})"
        safe = self.sitting.last_safe
        return (safe.describe() if safe is not None else "not connected") + note


def _sized(app: App[None], screen: object) -> None:
    """Give a screen about to be shown the size classes of the terminal's present size.

    Textual gives them as the screen first lays out, after its widgets were styled without
    them: every widget of the screen was styled again. Given now, they are already right then.
    """
    if not isinstance(screen, Screen):
        return
    width, height = app.size
    for dimension, breakpoints in ((width, app.HORIZONTAL_BREAKPOINTS),
                                   (height, app.VERTICAL_BREAKPOINTS)):
        reached = [(at, name) for at, name in breakpoints or () if dimension >= at]
        for _, name in breakpoints or ():
            screen.set_class(bool(reached) and name == max(reached)[1], name)


def _write_crash_log(results_root: Path, error: BaseException) -> Path | None:
    """The error's traceback and this pinarray's version, for a bug report; None if unwritable."""
    now = datetime.now(UTC)
    folder = Path(results_root) / "sourcedata"
    path = folder / f"crash-{now:%Y%m%dT%H%M%S}Z-{os.getpid()}.log"
    text = (f"pinarray {__version__} crashed at {now.isoformat()}\n\n"
            + "".join(traceback.format_exception(error)))
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError:
        return None
    return path
