"""The experimenter's UI in the scanner: Begin run waits for the first counted volume.

Driven through Textual's Pilot. The emulated scanner runs in virtual time; the key trigger
and the serial trigger (a silent converter on a pseudo-terminal) on this machine's clock,
since a trigger is stamped on it.
"""

import csv
from pathlib import Path

import pytest
from textual.widgets import Static

from pinarray.clock import VirtualClock
from pinarray.journal.manifest import read_manifest
from pinarray.player.rig import Rig, choose_clock
from pinarray.protocol.imaging import SyncOverrides, parse_trigger
from pinarray.tui.app import PinArrayApp, TuiOptions
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.run_screen import RunScreen
from pinarray.tui.scanner_screen import ScannerScreen
from tests.imaging.fake_scanner import fake_scanner
from tests.tui.conftest import LOCALISATION, PROTOCOLS, SIZE, fill_start, settle

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = pytest.mark.realtime

NS = 1_000_000_000


def scanner_app(results: Path, trigger: str, dummy_volumes: int, *, real_time: bool,
                lsl: str | None = None, protocol: Path = LOCALISATION):
    options = TuiOptions(protocol_path=protocol, protocols_dir=PROTOCOLS,
                         results_root=results, time_scale=1 if real_time else 0, seed=3,
                         timing_check_ns=0,
                         sync=SyncOverrides(parse_trigger(trigger), dummy_volumes), lsl=lsl)
    clock = (lambda port: choose_clock(None, 1.0)) if real_time else (lambda port: VirtualClock())
    return PinArrayApp(options, clock_factory=clock, rig_factory=Rig, list_ports=lambda: [])


async def begin_run(pilot):
    await fill_start(pilot)
    await pilot.click("#start")
    await settle(pilot)
    assert isinstance(pilot.app.screen, PreflightScreen)
    await pilot.press("b")
    await pilot.pause()


def text(screen, selector: str) -> str:
    return str(screen.query_one(selector, Static).render())


def volume_log(results: Path) -> list[dict]:
    (log,) = results.rglob("*_volumes.tsv")
    with open(log, newline="") as file:
        return list(csv.DictReader(file, delimiter="\t"))


async def test_an_emulated_scanner_starts_the_run_at_its_first_counted_volume(tmp_path):
    results = tmp_path / "results"
    app = scanner_app(results, "emulate:2", 2, real_time=False)
    async with app.run_test(size=SIZE) as pilot:
        await begin_run(pilot)
        await settle(pilot)
        assert isinstance(app.screen, RunScreen)  # the wait is over: volumes 1-3 came
    (manifest,) = results.rglob("*_manifest.json")
    zero = read_manifest(manifest).time_zero
    assert zero is not None and zero.event.startswith("the first counted scanner volume: trigger 3")
    rows = volume_log(results)
    assert [(r["volume"], r["onset"], r["dummy"]) for r in rows[:3]] == [
        ("1", "-4", "true"), ("2", "-2", "true"), ("3", "0", "false")]


async def test_each_press_of_the_trigger_key_is_a_volume_and_the_third_starts_the_run(tmp_path):
    results = tmp_path / "results"
    app = scanner_app(results, "key:5", 2, real_time=True)
    async with app.run_test(size=SIZE) as pilot:
        await begin_run(pilot)
        screen = app.screen
        assert isinstance(screen, ScannerScreen)
        assert text(screen, "#scanner-state") == "WAITING FOR SCANNER…"
        assert text(screen, "#scanner-volumes").startswith("volumes seen: 0 of 3 to time zero")
        await pilot.press("5", "x")  # another key is not a volume
        await pilot.pause()
        assert text(screen, "#scanner-volumes").startswith("volumes seen: 1 of 3")
        assert list(results.rglob("*_beh.tsv")) == []  # nothing is written before time zero
        await pilot.press("5", "5")
        await settle(pilot)
        assert isinstance(app.screen, RunScreen)
        await pilot.press("q", "y")  # mid-run, q asks first
        await settle(pilot)
    assert "16 servo(s) at rest, 16 released" in app.outcome()[1]
    rows = volume_log(results)
    assert [(r["volume"], r["dummy"]) for r in rows[:3]] == [
        ("1", "true"), ("2", "true"), ("3", "false")]
    assert rows[2]["onset"] == "0" and float(rows[0]["onset"]) < float(rows[1]["onset"]) < 0


async def test_escape_stops_waiting_for_a_silent_scanner_and_no_run_is_started(tmp_path):
    results = tmp_path / "results"
    with fake_scanner(tr_s=1, volumes=0) as scanner:
        scanner.start()
        app = scanner_app(results, f"serial:{scanner.path}", 0, real_time=True)
        async with app.run_test(size=SIZE) as pilot:
            await begin_run(pilot)
            assert isinstance(app.screen, ScannerScreen)
            assert "trigger serial:" in str(app.screen.query(Static)[3].render())
            await pilot.press("escape")
            await settle(pilot)
            screen = app.screen
            assert isinstance(screen, PreflightScreen)
            assert "Stopped waiting for the scanner; no run was started." in text(screen, "#preflight-status")
            assert app.sitting.rig is not None  # still connected: Begin run can wait again
            await pilot.press("b")
            await pilot.pause()
            assert isinstance(app.screen, ScannerScreen)
            await pilot.press("q")  # quitting while waiting: pins safe, as everywhere
            await settle(pilot)
        assert "16 servo(s) at rest, 16 released" in app.outcome()[1]
    assert list(results.rglob("*_beh.tsv")) == [] and list(results.rglob("*_manifest.json")) == []


async def test_a_trigger_device_that_does_not_open_is_said_on_the_wait_screen(tmp_path):
    results = tmp_path / "results"
    app = scanner_app(results, "serial:/dev/no-such-trigger", 0, real_time=True)
    async with app.run_test(size=SIZE) as pilot:
        await begin_run(pilot)
        await settle(pilot)
        screen = app.screen
        assert isinstance(screen, ScannerScreen)
        state = text(screen, "#scanner-state")
        assert state.startswith("/dev/no-such-trigger: cannot open the trigger device")
        assert screen.query_one("#scanner-state").has_class("-problem")
        await pilot.press("escape")
        await settle(pilot)
        assert isinstance(app.screen, PreflightScreen)
    assert list(results.rglob("*_manifest.json")) == []


async def test_the_ui_sends_an_lsl_marker_at_each_end_of_a_presented_stimulus(tmp_path):
    from tests.imaging.lsl_inlet import MarkerInlet, unique_stream_name

    results, name = tmp_path / "results", unique_stream_name()
    # The seed's localisation with 1 s stimuli: the first presents in real time.
    text = LOCALISATION.read_text()
    assert "    duration_s: 10\n" in text
    short = tmp_path / "localisation.yaml"
    short.write_text(text.replace("    duration_s: 10\n", "    duration_s: 1\n"))
    app = scanner_app(results, "key", 0, real_time=True, lsl=name, protocol=short)
    inlet = MarkerInlet(name, count=2)
    async with app.run_test(size=SIZE) as pilot:
        await begin_run(pilot)
        assert inlet.found.wait(60), "the UI opened no outlet named like --lsl"
        await pilot.press("5")
        await settle(pilot)
        assert isinstance(app.screen, RunScreen)
        session = app.screen.session
        await pilot.press("space")  # leave the instructions
        await settle(pilot)
        await pilot.press("space")  # present the first trial
        await settle(pilot)
        planned = session.current
        markers = inlet.join()
        await pilot.press("q", "y")  # mid-run, q asks first
        await settle(pilot)
    assert [(m["event"], m["trial"], m["pin"], m["practice"]) for m, _ in markers] == [
        ("onset", 1, planned.condition.pin, True), ("offset", 1, planned.condition.pin, True)]
    (events,) = results.rglob("*_events.tsv")
    with open(events, newline="") as file:
        (row,) = list(csv.DictReader(file, delimiter="\t"))
    assert round(markers[1][1] - markers[0][1], 6) == float(row["duration"])
