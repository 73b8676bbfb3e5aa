"""The experimenter's app: start -> pre-flight -> run -> end, over one `Lab`."""

from __future__ import annotations

import asyncio
import os
import signal
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from textual.app import App
from textual.binding import Binding

from pinarray.clock import Clock
from pinarray.player import describe
from pinarray.protocol.sync import SyncOverrides
from pinarray.rig import Rig, choose_clock
from pinarray.session import Session
from pinarray.stop import on_loop_signals
from pinarray.tui.lab import QUIT_REASON, Lab, RigFactory


@dataclass(frozen=True)
class TuiOptions:
    """What the command line fixes before the start screen opens."""

    protocol_path: Path | None = None
    protocols_dir: Path = Path("protocols")
    results_root: Path = Path("results")
    port: str | None = None  # real servos; None: the simulator
    sim_url: str | None = None
    time_scale: float = 1.0  # simulator only; 0 = virtual time
    seed: int | None = None
    timing_check_ns: int = 2_000_000_000  # pre-flight's wake-up measurement; 0 = skip
    sync: SyncOverrides = SyncOverrides()  # scanner options over the protocol's sync: section
    lsl: str | None = None  # LSL marker stream name; None: no outlet


def serial_ports() -> list[tuple[str, str]]:
    """(device, description) of each serial port pyserial finds."""
    from serial.tools.list_ports import comports

    return [(port.device, port.description) for port in comports()]


class PinArrayApp(App[str]):
    """Runs subjects through protocols on the pin array; returns how the pins were left.

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
    BINDINGS = [
        Binding("q", "quit", "quit"),
        # Ctrl-C must leave the run resumable and the pins at rest, like q.
        Binding("ctrl+c", "quit", "quit", priority=True),
    ]

    def __init__(self, options: TuiOptions = TuiOptions(),
                 clock_factory: Callable[[str | None], Clock] | None = None,
                 rig_factory: RigFactory = Rig,
                 list_ports: Callable[[], list[tuple[str, str]]] = serial_ports):
        super().__init__()
        self.options = options
        scale = options.time_scale
        self.lab = Lab(options.results_root,
                       clock_factory or (lambda port: choose_clock(port, None if port else scale)),
                       rig_factory, lsl_name=options.lsl)
        self.list_ports = list_ports
        self.pins_left = ""

    def on_mount(self) -> None:
        from pinarray.tui.start_screen import StartScreen

        self.push_screen(StartScreen(self.options, self.list_ports))
        try:
            # Any stop signal: same as q. Closing the terminal: see `_hang_up`.
            on_loop_signals(asyncio.get_running_loop(), self.lab.stop, self._signalled)
        except (NotImplementedError, RuntimeError, ValueError, AttributeError):
            pass  # not the main thread (tests) or no such signals (Windows)

    def _signalled(self, signal_number: int) -> None:
        if signal_number == signal.SIGHUP:
            self._hang_up()
        else:
            self.call_later(self.action_quit)

    def _hang_up(self) -> None:
        """The terminal is gone: close the run and rest the pins, then leave at once.

        A normal exit would restore a terminal that no longer exists, and Textual's driver
        then waits forever (seen closing a tmux window mid-run). Rows and the manifest are
        already fsync'd by the time `Lab.finish` returns, so nothing is lost by not unwinding.
        """
        self.lab.finish()
        os._exit(128 + signal.SIGHUP)

    def finish_run(self, session: Session, reason: str) -> None:
        """End the run (aborted with ``reason`` unless complete) and show the end screen."""
        from pinarray.tui.end_screen import EndScreen

        def close() -> None:
            safe = self.lab.finish(reason or QUIT_REASON)
            self.call_from_thread(self.switch_screen, EndScreen(session, self.lab, safe))

        self.run_worker(close, thread=True, group="close", name="finish run")

    async def action_quit(self) -> None:
        """Cut a stimulus short, mark the run aborted (resumable), pins to rest, exit."""
        worker = self.run_worker(self.lab.finish, thread=True, group="close", name="quit")
        safe = await worker.wait()
        self.pins_left = describe(safe) if safe is not None else ""
        self.exit(self.pins_left)
