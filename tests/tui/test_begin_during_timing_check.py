"""Begin pressed at once, while the pre-flight still measures this machine's timing: nothing
plays in silence. The run begins when the check ends, or at once when the experimenter skips
the check, which the run's records then say."""

import threading

import pytest

from pinarray.errors import BusError
from pinarray.journal.manifest import read_manifest
from pinarray.player.timing import CheckSkipped, PortFigures, WakeUps, judge
from pinarray.tui.confirm import Confirm
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.run_screen import RunScreen
from tests.tui.conftest import SIZE, SMALL, both_sizes, fill_start, make_app
from tests.tui.test_small_terminal import ArrayRig, on_screen

SLICE_NS = 1_000_000_000
SLICES = 10


class MeasuringRig(ArrayRig):
    """A ten-second timing check that measures a slice each time the test lets it."""

    go = threading.Semaphore(0)

    def check_timing(self, duration_ns=0, period_ns=0, progress=None):
        total_ns = SLICES * SLICE_NS
        for k in range(1, SLICES + 1):
            assert MeasuringRig.go.acquire(timeout=30), "the test never let the check go on"
            if progress is not None and not progress(k * SLICE_NS, total_ns) and k < SLICES:
                return CheckSkipped(k * SLICE_NS, total_ns)
        # A quiet machine: 20 000 deadlines, none late.
        return judge(WakeUps(20_000, 100_000, 300_000, 900_000), "",
                     PortFigures("sim://", 1, 1_400_000, None, 200), 10_000_000)


@pytest.fixture(autouse=True)
def fresh_check():
    MeasuringRig.go = threading.Semaphore(0)
    yield
    MeasuringRig.go.release(SLICES)  # a test that failed midway must not leave a worker waiting


async def until(pilot, condition, what: str):
    for _ in range(400):
        if condition():
            return
        await pilot.pause(0.01)
    raise AssertionError(f"never: {what}\n{on_screen(pilot.app)}")


def manifests(results):
    return [read_manifest(path) for path in results.rglob("*_manifest.json")]


async def measuring_preflight(pilot, slices: int):
    """The pre-flight, connected, its check ``slices`` seconds into its ten."""
    await fill_start(pilot)
    await pilot.click("#start")
    app = pilot.app
    await until(pilot, lambda: isinstance(app.screen, PreflightScreen) and app.screen.connected
                and app.screen._measuring, "connected and measuring")
    if slices:
        MeasuringRig.go.release(slices)
        await until(pilot, lambda: f"{SLICES - slices} s left" in on_screen(app),
                    "the seconds left")


async def test_begin_while_the_check_measures_waits_for_it_visibly_then_the_run_begins(
        results):
    app = make_app(results, rig_factory=MeasuringRig, timing_check_ns=None)
    async with app.run_test(size=SMALL) as pilot:
        await measuring_preflight(pilot, 3)
        await pilot.press("b")
        await pilot.pause(0.1)
        async for size in both_sizes(pilot):  # the check holds still: the same moment at both
            assert isinstance(app.screen, PreflightScreen)  # not playing anything in silence
            assert "the run begins when the check ends" in on_screen(app), size
            assert "After check…" in on_screen(app), size
            assert manifests(results) == []  # no run opened yet
        MeasuringRig.go.release(SLICES - 3)
        await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")
        (manifest,) = manifests(results)
        assert manifest.sittings[-1].timing_check.startswith("OK: stimuli can be delivered")


async def test_s_skips_the_check_and_the_runs_records_say_so(results):
    app = make_app(results, rig_factory=MeasuringRig, timing_check_ns=None)
    async with app.run_test(size=SIZE) as pilot:
        await measuring_preflight(pilot, 2)
        await pilot.press("b")
        await pilot.press("s")
        MeasuringRig.go.release(1)  # the slice being measured ends; the check stops there
        await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")
        (manifest,) = manifests(results)
        assert manifest.sittings[-1].timing_check == (
            "timing check skipped by the experimenter after 3 of 10 s: no verdict")


async def test_a_skipped_check_lets_begin_start_the_run_later_without_asking(results):
    app = make_app(results, rig_factory=MeasuringRig, timing_check_ns=None)
    async with app.run_test(size=SIZE) as pilot:
        await measuring_preflight(pilot, 0)
        await pilot.press("s")
        MeasuringRig.go.release(1)
        await until(pilot, lambda: "skipped by the experimenter after 1 of 10 s" in on_screen(app),
                    "the check skipped")
        assert isinstance(app.screen, PreflightScreen)
        await pilot.press("b")
        await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")


class DoubtfulRig(MeasuringRig):
    """A first check that says NOT OK at once; a re-check that measures as `MeasuringRig`."""

    checks = 0

    def check_timing(self, duration_ns=0, period_ns=0, progress=None):
        DoubtfulRig.checks += 1
        if DoubtfulRig.checks == 1:
            return judge(WakeUps(2000, 1_200_000, 9_800_000, 32_100_000), "",
                         PortFigures("sim://", 8, 3_400_000, None, 200), 10_000_000)
        return super().check_timing(duration_ns, period_ns, progress)


async def test_a_re_check_skipped_leaves_the_verdict_before_it_to_ask_about_and_record(results):
    DoubtfulRig.checks = 0
    app = make_app(results, rig_factory=DoubtfulRig, timing_check_ns=None)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        await pilot.click("#start")
        await until(pilot, lambda: "NOT OK" in on_screen(app), "the first verdict")
        await pilot.click("#lower-delay")  # faster read-backs: the timing is measured again
        await until(pilot, lambda: app.screen._measuring, "the re-check measuring")
        await pilot.press("s")
        MeasuringRig.go.release(1)
        await until(pilot, lambda: "skipped by the experimenter" in on_screen(app), "skipped")
        await pilot.press("b")
        await until(pilot, lambda: isinstance(app.screen, Confirm), "Begin asking first")
        assert "Begin although the timing check said NOT OK?" in on_screen(app)
        await pilot.press("y")
        await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")
        (manifest,) = manifests(results)
        said = manifest.sittings[-1].timing_check
        assert said.startswith("timing check skipped by the experimenter after 1 of 10 s")
        assert "; the verdict before it: NOT OK: stimuli may be reported not delivered" in said


class FailingCheckRig(MeasuringRig):
    """A timing check that ends without a verdict: the array went away while it measured."""

    def check_timing(self, duration_ns=0, period_ns=0, progress=None):
        assert MeasuringRig.go.acquire(timeout=30)
        raise BusError("servo 3 (pin 3): no status packet after 3 retries")


async def test_a_begin_waiting_for_a_check_that_fails_is_cancelled_in_words(results):
    app = make_app(results, rig_factory=FailingCheckRig, timing_check_ns=None)
    async with app.run_test(size=SIZE) as pilot:
        await measuring_preflight(pilot, 0)
        await pilot.press("b")
        MeasuringRig.go.release(1)
        await until(pilot, lambda: "Begin cancelled" in on_screen(app), "the cancel said")
        assert isinstance(app.screen, PreflightScreen)
        assert "Timing: not checked" in on_screen(app)
        assert manifests(results) == []
