"""Helpers for driving the experimenter's UI through Textual's Pilot in virtual time."""

from pathlib import Path

import pytest
from textual.geometry import Size

from pinarray.clock import VirtualClock
from pinarray.player.rig import Rig
from pinarray.tui.app import PinArrayApp, TuiOptions
from tests.runs import write_short_localisation

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
LOCALISATION = PROTOCOLS / "localisation.yaml"
MOTION = PROTOCOLS / "apparent_motion.yaml"
SIZE = (120, 40)
SMALL = (80, 24)  # the smallest terminal a lab laptop opens (tmux): everything needed must show


def make_app(results, protocol=LOCALISATION, seed=3, sim_url=None, rig_factory=Rig,
             timing_check_ns=0):
    """The app on the simulated array in virtual time: a whole session runs instantly.

    The pre-flight's timing check (a real player process measuring real wake-ups) is off
    unless a test asks for it.
    """
    options = TuiOptions(protocol_path=protocol, protocols_dir=PROTOCOLS,
                         results_root=Path(results), sim_url=sim_url, time_scale=0, seed=seed,
                         timing_check_ns=timing_check_ns)
    return PinArrayApp(options, clock_factory=lambda port: VirtualClock(),
                       rig_factory=rig_factory, list_ports=lambda: [])


async def settle(pilot):
    """Let every worker finish and every message it posted be handled."""
    await pilot.app.workers.wait_for_complete()
    await pilot.pause()
    # A finished worker's messages may start another (the end of a run closes the rig).
    while any(worker.is_running for worker in pilot.app.workers):
        await pilot.app.workers.wait_for_complete()
        await pilot.pause()


async def fill_start(pilot, subject="01", session=None):
    """Type the subject (and session) on the start screen."""
    # Focused, not clicked: under the snapshot harness at 80x24 a click on the subject field
    # once left the typing in the session field (not reproduced in a plain run_test); the
    # fields' behaviour, not the pilot's aim, is what these tests are about.
    pilot.app.screen.query_one("#subject").focus()
    await pilot.press(*subject)
    if session is not None:
        pilot.app.screen.query_one("#session").focus()
        await pilot.press("end", "ctrl+u", *session)
    await settle(pilot)


async def to_preflight(pilot, subject="01", resume=False):
    """Start screen -> pre-flight, connected."""
    await fill_start(pilot, subject)
    await pilot.click("#resume" if resume else "#start")
    await settle(pilot)


async def to_run_screen(pilot, subject="01", resume=False):
    """Start screen -> pre-flight (connected) -> run screen, with instructions showing."""
    await to_preflight(pilot, subject, resume)
    await pilot.press("b")
    await settle(pilot)


async def resize(pilot, size):
    """The terminal resized to ``size`` (columns, rows), as a lab's tmux pane is: the app lays
    its screens out again (and sets its size classes) before this returns."""
    await pilot.resize_terminal(*size)
    while pilot.app.screen.region.size != Size(*size):  # the app passes it on after a timer
        await pilot.pause(0.01)
    await pilot.pause()


async def both_sizes(pilot):
    """The screen at the terminal's size, then at the other of 80x24 and 120x40: the same state
    checked at both sizes without driving the app there twice (a screen is laid out for its
    size whenever the terminal's changes, as when it opens). The terminal stays at the other."""
    here = (pilot.app.size.width, pilot.app.size.height)
    yield here
    other = SIZE if here == SMALL else SMALL
    await resize(pilot, other)
    yield other


def delay_column(app) -> list[str]:
    """The pre-flight's return delay of each servo, as shown (µs)."""
    table = app.screen.query_one("#servos")
    column = [c.label.plain for c in table.columns.values()].index("return\ndelay (µs)")
    return [str(table.get_row_at(row)[column]) for row in range(table.row_count)]


@pytest.fixture
def results(tmp_path):
    return tmp_path / "results"


@pytest.fixture
def short_localisation(tmp_path):
    return write_short_localisation(tmp_path)
