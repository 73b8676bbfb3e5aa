"""The pre-flight's timing verdict as the experimenter acts on it: asked before beginning
after a NOT OK, measured again when the read-backs got faster."""

import time

import pytest
from textual.widgets import DataTable

from pinarray.tui.confirm import Confirm
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.run_screen import RunScreen
from tests.tui.conftest import SMALL, both_sizes, fill_start, make_app, settle
from tests.tui.test_small_terminal import ArrayRig, on_screen, says, unseen


@pytest.fixture(autouse=True)
def fresh_rig():
    ArrayRig.hold, ArrayRig.failures = None, 0


class CountingRig(ArrayRig):
    """The busy laptop's NOT OK verdict, counting how often the pre-flight asked for it."""

    checks = 0

    def check_timing(self, duration_ns=0, period_ns=0, progress=None):
        CountingRig.checks += 1
        return super().check_timing(duration_ns, period_ns, progress)


async def in_view(pilot, text: str) -> None:
    """Until ``text`` is on the terminal: at 80x24 the verdict is scrolled into view after the
    refresh that lays it out (`PreflightScreen._timing_line`), which on a busy machine may come
    frames after the worker that measured has ended. At most 15 s: a hang guard, not a timing
    check (two seconds once ran out with six test processes on two cores)."""
    give_up = time.monotonic() + 15
    while text not in on_screen(pilot.app) and time.monotonic() < give_up:
        await pilot.pause(0.02)


async def test_a_not_ok_timing_check_shows_every_button_is_measured_again_after_lowering_the_delay_and_begin_asks_first(
        results):
    """The busy laptop's NOT OK verdict: the pre-flight still shows every button and its table
    at 80x24 as at 120x40 (issue 24); Lower return delay (faster read-backs) measures the timing
    again; Begin asks first, and No leaves nothing opened."""
    CountingRig.checks = 0
    app = make_app(results, rig_factory=CountingRig, timing_check_ns=1)
    async with app.run_test(size=SMALL) as pilot:
        await fill_start(pilot)
        await pilot.click("#start")
        await settle(pilot)
        assert CountingRig.checks == 1
        screen = app.screen
        async for size in both_sizes(pilot):
            assert "NOT OK" in says(screen, "#timing")
            await in_view(pilot, "NOT OK: stimuli may be reported not delivered")
            assert "NOT OK: stimuli may be reported not delivered" in on_screen(app), size
            assert unseen(screen) == [], size
            table = screen.query_one(DataTable)
            assert table.scrollable_content_region.height >= table.header_height + 5, size
        await pilot.click("#lower-delay")
        await settle(pilot)
        assert CountingRig.checks == 2, "the timing not measured again after lowering the delay"
        await pilot.press("b")
        await settle(pilot)
        assert isinstance(app.screen, Confirm)
        assert "Begin although the timing check said NOT OK?" in on_screen(app)
        await pilot.press("n")
        await settle(pilot)
        assert isinstance(app.screen, PreflightScreen)  # still here, nothing opened
        assert list(results.rglob("*_manifest.json")) == []
        await pilot.press("b")
        await settle(pilot)
        await pilot.press("y")
        await settle(pilot)
        assert isinstance(app.screen, RunScreen)
