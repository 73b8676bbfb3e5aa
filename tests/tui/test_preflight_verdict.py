"""The pre-flight's timing verdict as the experimenter acts on it: asked before beginning
after a NOT OK, measured again when the read-backs got faster."""

import pytest

from pinarray.tui.confirm import Confirm
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.run_screen import RunScreen
from tests.tui.conftest import SIZE, fill_start, make_app, settle
from tests.tui.test_small_terminal import ArrayRig, on_screen


@pytest.fixture(autouse=True)
def fresh_rig():
    ArrayRig.hold, ArrayRig.failures = None, 0


class CountingRig(ArrayRig):
    """The busy laptop's NOT OK verdict, counting how often the pre-flight asked for it."""

    checks = 0

    def check_timing(self, duration_ns=0, period_ns=0, progress=None):
        CountingRig.checks += 1
        return super().check_timing(duration_ns, period_ns, progress)


async def test_beginning_after_a_not_ok_timing_check_asks_first(results):
    app = make_app(results, rig_factory=ArrayRig, timing_check_ns=1)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        await pilot.click("#start")
        await settle(pilot)
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


async def test_lowering_the_return_delay_measures_the_timing_again(results):
    CountingRig.checks = 0
    app = make_app(results, rig_factory=CountingRig, timing_check_ns=1)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        await pilot.click("#start")
        await settle(pilot)
        assert CountingRig.checks == 1
        await pilot.click("#lower-delay")
        await settle(pilot)
        assert CountingRig.checks == 2
