"""A terminal that goes away without a SIGHUP (a shell that ignores it, a closed tmux pane)
still ends the UI like a hang-up: exit 128 + SIGHUP, never a process left spinning; one that
stopped reading leaves the UI's event loop held, and a stop signal still ends it."""

import os
import pty
import select
import signal
import subprocess
import sys
import time
from contextlib import contextmanager

import pytest

from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.tui.app import LOOP_HELD_NS
from tests.runs import REPO
from tests.test_library_paths import at_rest_and_released

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = pytest.mark.realtime

SCREEN_WAIT_S = 60  # bounds on a hang, not timing goals: a loaded machine may be slow
EXIT_WAIT_S = 60


def read_until(fd: int, text: bytes, wait_s: float) -> bytes:
    seen = b""
    deadline = time.monotonic() + wait_s
    while text not in seen and time.monotonic() < deadline:
        if select.select([fd], [], [], 0.5)[0]:
            try:
                seen += os.read(fd, 65536)
            except OSError:
                break
    return seen


class Terminal:
    """The other end of the UI's pseudo-terminal: the window, the SSH client."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def stop_reading(self) -> None:
        """Keys keep coming, each a redraw, and nothing is read any more: the UI's output
        fills the terminal's buffer, then Textual's output queue."""
        for _ in range(400):
            try:
                os.write(self.fd, b"\t")
            except BlockingIOError:
                pass  # the keys' side is full too
            time.sleep(0.01)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


def start_ui(tmp_path, launcher: str | None = None, port: str | None = None):
    """`pinarray tui` on a pseudo-terminal (``launcher``: Python code that runs it instead of
    ``python -m pinarray``; ``port``: a served port instead of the in-process simulator): its
    process and the terminal.

    A session of its own: the pseudo-terminal is not its controlling terminal, so closing the
    other end sends no SIGHUP, as when a shell ignoring SIGHUP is the session leader."""
    main, its_device = pty.openpty()
    os.set_blocking(main, False)
    python = ["-m", "pinarray"] if launcher is None else ["-c", launcher]
    servos = ["--sim"] if port is None else ["--port", port]
    process = subprocess.Popen(
        [sys.executable, *python, "tui", "protocols/localisation.yaml", *servos,
         "--subject", "01", "--results", str(tmp_path / "results")],
        cwd=REPO, stdin=its_device, stdout=its_device, stderr=its_device,
        start_new_session=True,
        env={**os.environ, "TERM": "xterm-256color", "COLUMNS": "100", "LINES": "30"})
    os.close(its_device)
    return process, Terminal(main)


@contextmanager
def ui_on_a_terminal(tmp_path, launcher: str | None = None, port: str | None = None,
                     shown: bytes | None = b"start a session"):
    """`start_ui`, once the terminal shows ``shown`` (its start screen; None: at once); killed
    at the end if it is still there."""
    process, terminal = start_ui(tmp_path, launcher, port)
    try:
        if shown is not None:
            assert shown in read_until(terminal.fd, shown, SCREEN_WAIT_S)
        yield process, terminal
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        terminal.close()


def test_the_ui_leaves_when_its_terminal_is_gone_even_without_a_hangup_signal(tmp_path):
    with ui_on_a_terminal(tmp_path) as (process, terminal):
        terminal.close()  # the terminal window is closed
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGHUP


# The UI as `pinarray tui` starts it, its results folder failing as the run is closed (a full
# disk): `Sitting.finish` rests the pins, then raises the error marking the run.
MARKING_FAILS = """
import sys
from pinarray.cli import main
from pinarray.errors import ResultsError
from pinarray.session.sitting import Sitting

finishing = Sitting.finish

def finish(sitting, *args, **kwargs):
    finishing(sitting, *args, **kwargs)
    raise ResultsError("results/sub-01: No space left on device")

Sitting.finish = finish
sys.exit(main(sys.argv[1:]))
"""


def test_the_ui_leaves_when_its_terminal_is_gone_even_if_the_run_cannot_be_marked(tmp_path):
    with ui_on_a_terminal(tmp_path, MARKING_FAILS) as (process, terminal):
        terminal.close()
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGHUP


def test_the_ui_leaves_when_its_terminal_stopped_reading_then_went_away(tmp_path):
    # Found by `make run` in a pseudo-terminal that stopped being read (an SSH link frozen,
    # then dropped): Textual's output queue filled, its writer thread died on the dead terminal
    # and the event loop waited on that queue for good; the look at the terminal, made from the
    # loop, never came, nor did SIGTERM's handler: the UI stayed, its input thread spinning
    # (half a processor for as long as one let it), the port held.
    with ui_on_a_terminal(tmp_path) as (process, terminal):
        terminal.stop_reading()
        terminal.close()  # the link drops
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGHUP


@pytest.mark.long
def test_the_ui_whose_terminal_stopped_reading_still_leaves_on_sigterm(tmp_path):
    # The link frozen but not dropped (an SSH session hung, its window still open): the event
    # loop waits on Textual's full output queue, so a signal's handler on the loop never runs.
    # SIGTERM (an experimenter's `kill` from another terminal) is still heard: the pins go to
    # rest and the UI leaves with 128 + SIGTERM.
    with ui_on_a_terminal(tmp_path) as (process, terminal):
        terminal.stop_reading()
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGTERM


def test_sigterm_to_the_ui_on_a_live_terminal_leaves_the_terminal_as_it_found_it(tmp_path):
    # The signal passes through the terminal's watch to the event loop, which closes the UI
    # the usual way: the terminal's own screen is back, the last line says why it ended.
    with ui_on_a_terminal(tmp_path) as (process, terminal):
        process.send_signal(signal.SIGTERM)
        shown = read_until(terminal.fd, b"SIGTERM", EXIT_WAIT_S)
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGTERM
        assert b"\x1b[?1049l" in shown  # the alternate screen left
        assert b"SIGTERM" in shown.rpartition(b"\x1b[?1049l")[2]


@pytest.mark.long
def test_the_ui_whose_terminal_stopped_reading_during_the_timing_check_leaves_on_sigterm(
        tmp_path):
    # The pre-flight measures this machine, telling the screen how far it got after every
    # slice; with the terminal frozen the screen never hears it. SIGTERM still ends the UI:
    # the check ends, the servos rest with torque off and the UI leaves with 128 + SIGTERM.
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    try:
        with ui_on_a_terminal(tmp_path, port=server.path) as (process, terminal):
            os.write(terminal.fd, b"\r")  # Start new run: the pre-flight connects, then measures
            assert b"measuring this machine" in read_until(
                terminal.fd, b"measuring this machine", SCREEN_WAIT_S)
            terminal.stop_reading()
            process.send_signal(signal.SIGTERM)
            assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGTERM
        assert at_rest_and_released(server.sim.servos) == []
    finally:
        server.stop()


# The UI as `pinarray tui` starts it, its rig slow to rest the pins as it closes (a lossy bus
# healing its goals): longer than the terminal's watch gives a held event loop.
SLOW_TO_REST = f"""
import sys, time
from pinarray.cli import main
from pinarray.player.rig import Rig

closing = Rig.close

def close(rig):
    time.sleep({LOOP_HELD_NS / 1e9 + 2})  # longer than a held loop is given
    return closing(rig)

Rig.close = close
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.long
def test_a_ui_slow_to_rest_the_pins_on_sigterm_still_leaves_the_usual_way(tmp_path):
    # Its event loop at work all along: the terminal's watch leaves it to close as it does,
    # the terminal's own screen back and the last line saying how the pins were left.
    with ui_on_a_terminal(tmp_path, SLOW_TO_REST) as (process, terminal):
        os.write(terminal.fd, b"\r")  # Start new run: the pre-flight connects
        assert b"measuring this machine" in read_until(
            terminal.fd, b"measuring this machine", SCREEN_WAIT_S)
        process.send_signal(signal.SIGTERM)
        shown = read_until(terminal.fd, b"at rest", EXIT_WAIT_S)
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGTERM
        assert b"\x1b[?1049l" in shown  # the alternate screen left
        assert b"stopped by SIGTERM" in shown.rpartition(b"\x1b[?1049l")[2]


# The UI as `pinarray tui` starts it, but a SIGTERM comes to it as its screen is being put up:
# the terminal already in the UI's hands (alternate screen, keys raw), its own handlers not
# yet in place.
SIGNALLED_AS_IT_STARTS = """
import os, signal, sys
from pinarray.cli import main
from pinarray.tui.app import PinArrayApp

putting_up = PinArrayApp.on_mount

def on_mount(app):
    os.kill(os.getpid(), signal.SIGTERM)
    putting_up(app)

PinArrayApp.on_mount = on_mount
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_as_the_ui_starts_ends_it_with_the_terminal_as_it_found_it(tmp_path):
    # A SIGTERM there used to kill the UI at once: no status of its own, the terminal left on
    # the alternate screen with keys raw.
    with ui_on_a_terminal(tmp_path, SIGNALLED_AS_IT_STARTS, shown=None) as (process, terminal):
        shown = read_until(terminal.fd, b"SIGTERM", EXIT_WAIT_S)
        assert process.wait(timeout=EXIT_WAIT_S) == 128 + signal.SIGTERM
        shown += read_until(terminal.fd, b"\n", 1)
        assert b"\x1b[?1049l" in shown  # the alternate screen left
        assert b"stopped by SIGTERM" in shown.rpartition(b"\x1b[?1049l")[2]
