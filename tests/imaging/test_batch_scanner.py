"""`pinarray batch` in the scanner: a trigger converter on a pseudo-terminal, markers to LSL.

The scanner is `FakeScanner` (one ``5`` per volume at a set TR on a pty, as a USB trigger
converter sends them); the markers are read by an independent LSL inlet on 127.0.0.1, as
LabRecorder would. Nothing here is timed: orders and counts only (timing is `make bench`).
"""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pinarray.journal.paths import RunPaths
from pinarray.journal.volumes import volume_log_path
from tests.bids_validator import VALIDATOR, validate
from tests.hardware.test_compat import sim_serve  # noqa: F401  (a fixture)
from tests.imaging.fake_scanner import fake_scanner
from tests.imaging.lsl_inlet import MarkerInlet, unique_stream_name
from tests.runs import REPO

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos. Not the
# options refused before anything opens, nor the emulated scanner in virtual time.
realtime = pytest.mark.realtime

DEMO = REPO / "protocols" / "demo.yaml"
NS = 1_000_000_000

# These runs are about triggers, volumes and markers, not timing (`make bench` measures that):
# a delivery tolerance no host hiccup on a busy machine reaches, and no stroke checked (a
# simulator starved of the processor on the wall clock samples too seldom to judge a cycle,
# which no real servo makes it do), keep a trial from being presented again.
RELAXED = "device:\n  delivery_tolerance_ms: 5000\n  stroke_tolerance_percent: 0\n"

SHORT = RELAXED + """\
protocol: short
description: Three pins, half a second each.
stimuli:
  buzz: {frequency_hz: 5, duration_s: 0.5, pulse_width_ms: {up: 2.0, down: 1.5}}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 2, 3]
  frequencies_hz: [5]
  order: sequential
  inter_trial_interval_s: 0.3
"""


def batch_command(root, *args, protocol=DEMO, subject="S"):
    return [sys.executable, "-m", "pinarray", "batch", str(protocol), "--subject", subject,
            "--observer", "default", "--results", str(root), *args]


def batch(root, *args, protocol=DEMO, timeout_s=180):
    return subprocess.run(batch_command(root, *args, protocol=protocol), capture_output=True,
                          text=True, timeout=timeout_s, cwd=REPO)


def batch_with_scanner(root, scanner, *args, protocol=DEMO, signum=None):
    """Run batch; start ``scanner`` once batch says it waits (a trigger sent before the device
    is open is lost, as at a real scanner), or send it ``signum`` then. Returns (status, out, err)."""
    process = subprocess.Popen(batch_command(root, *args, protocol=protocol),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
                               env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        said = []
        deadline = time.monotonic() + 60  # a hang guard, not a timing check
        while not (said and "waiting for the scanner" in said[-1]) and time.monotonic() < deadline:
            said.append(process.stderr.readline())
            if not said[-1] and process.poll() is not None:
                break
        assert "waiting for the scanner" in said[-1], "".join(said)
        if signum is None:
            scanner.start()
        else:
            process.send_signal(signum)
        out, err = process.communicate(timeout=240)
    finally:
        if process.poll() is None:
            process.kill()
    return process.returncode, out, "".join(said) + err


def tsv(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file, delimiter="\t"))


@pytest.fixture
def short_protocol(tmp_path):
    path = tmp_path / "short.yaml"
    path.write_text(SHORT)
    return path


def no_run_was_created(root: Path) -> bool:
    return not list(root.rglob("*_beh.tsv")) and not list(root.rglob("*_manifest.json"))


def demo_in_short(tmp_path: Path) -> Path:
    """demo.yaml (16 pins in order, 5 Hz) with 0.2 s stimuli (one cycle) 0.1 s apart: a 5 s
    run, not 48 s, and a relaxed delivery tolerance."""
    text = DEMO.read_text()
    assert "duration_s: 2\n" in text and "inter_trial_interval_s: 1\n" in text
    path = tmp_path / "demo.yaml"
    path.write_text(RELAXED + text.replace("duration_s: 2\n", "duration_s: 0.2\n")
                    .replace("inter_trial_interval_s: 1\n", "inter_trial_interval_s: 0.1\n"))
    return path


@realtime
@pytest.mark.long
def test_the_done_when_waits_for_the_volumes_logs_them_and_every_onset_reaches_lsl(tmp_path):
    """The issue's done-when, as a lab runs it: demo.yaml in real time, two dummy volumes."""
    root, name = tmp_path / "results", unique_stream_name()
    with fake_scanner(tr_s=0.5, delay_s=0.5) as scanner:
        inlet = MarkerInlet(name, count=32)
        process = subprocess.Popen(
            batch_command(root, "--time-scale", "1", "--trigger", f"serial:{scanner.path}",
                          "--dummy-volumes", "2", "--lsl", name,
                          protocol=demo_in_short(tmp_path)),
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
        try:
            assert inlet.found.wait(60), "no LSL stream named like the --lsl option"
            scanner.start()  # the scanner starts once the recording is on, as in a lab
            out, err = process.communicate(timeout=240)
        finally:
            if process.poll() is None:
                process.kill()
        markers = inlet.join()
        written_ns = list(scanner.written_ns)
    assert process.returncode == 0, err
    assert "pinarray: waiting for the scanner (serial:" in err
    paths = RunPaths(root, "S", "1", "demo", 1)

    # Every trigger received is logged; the first two are dummies before time zero.
    volumes = tsv(volume_log_path(paths))
    assert [(v["volume"], v["dummy"]) for v in volumes[:3]] == [
        ("1", "true"), ("2", "true"), ("3", "false")]
    assert float(volumes[0]["onset"]) < float(volumes[1]["onset"]) < 0
    assert volumes[2]["onset"] == "0"
    numbered = [int(v["volume"]) for v in volumes if v["status"] != "extra"]
    assert numbered == list(range(1, len(numbered) + 1))
    arrived = [v for v in volumes if v["status"] in ("received", "irregular")]
    last_s = float(volumes[-1]["onset"])
    # Every trigger written before the last one logged came (a converter loses none on a pty).
    zero_written_ns = written_ns[2]
    assert len(arrived) >= sum(1 for w in written_ns if (w - zero_written_ns) / NS < last_s - 0.5)
    assert f"every volume in {volume_log_path(paths)}" in out

    # Onsets from the first counted volume, the same in beh.tsv and events.tsv.
    events, beh = tsv(paths.events_tsv), tsv(paths.beh_tsv)
    assert [e["trial"] for e in events] == [str(n) for n in range(1, 17)]
    onsets = [float(e["onset"]) for e in events]
    assert onsets == sorted(onsets) and onsets[0] >= 0
    assert [b["stimulus_onset"] for b in beh] == [e["onset"] for e in events]
    manifest = json.loads(paths.manifest.read_text())
    assert manifest["time_zero"]["event"].startswith("the first counted scanner volume: trigger 3")

    # One onset and one offset marker per stimulus, with its trial, pin and frequency, stamped
    # on LSL's clock at the times the events file gives (one time base, to float precision).
    assert inlet.info is not None and inlet.info.type() == "Markers"
    assert [(m["event"], m["trial"], m["pin"], m["frequency_hz"], m["task"]) for m, _ in markers] \
        == [(event, n, n, 5, "demo") for n in range(1, 17) for event in ("onset", "offset")]
    onset_stamps = [stamp for m, stamp in markers if m["event"] == "onset"]
    offset_stamps = [stamp for m, stamp in markers if m["event"] == "offset"]
    zero_s = onset_stamps[0] - onsets[0]
    # Stamps are doubles of ~1e5 s (a few 1e-11 s apart from exact after the subtraction);
    # onsets have whole nanoseconds: equal within 1 us whatever digits they have (rounding
    # both to 6 decimals split an onset ending in ...500 ns either way).
    assert all(abs((s - zero_s) - o) <= 1e-6 for s, o in zip(onset_stamps, onsets, strict=True))
    assert [round(off - on, 6) for on, off in zip(onset_stamps, offset_stamps, strict=True)] == [
        float(e["duration"]) for e in events]
    # LSL's clock is the one the triggers were stamped on: the zero falls after the third
    # trigger was written and before the fourth.
    assert written_ns[2] / NS <= zero_s < written_ns[3] / NS


@realtime
@pytest.mark.skipif(not VALIDATOR.exists(), reason="bids-validator-deno comes with the dev extra")
def test_a_scanner_run_with_missed_volumes_stays_valid_bids(tmp_path, short_protocol):
    """The trigger stops mid-run: the session goes on on its own clock, the gap is logged."""
    root = tmp_path / "results"
    with fake_scanner(tr_s=0.25, delay_s=0.3, stop_after=5) as scanner:
        status, out, err = batch_with_scanner(
            root, scanner, "--time-scale", "1", "--trigger", f"serial:{scanner.path}",
            "--dummy-volumes", "1", "--tr", "0.25", protocol=short_protocol)
    assert status == 0, err
    paths = RunPaths(root, "S", "1", "short", 1)
    volumes = tsv(volume_log_path(paths))
    statuses = [v["status"] for v in volumes]
    assert statuses[:5].count("missed") == 0 and statuses[5:] and set(statuses[5:]) == {"missed"}
    assert [int(v["volume"]) for v in volumes] == list(range(1, len(volumes) + 1))
    assert len(tsv(paths.events_tsv)) == 3
    assert f"{len(statuses) - 5} missed" in out
    report, done = validate(root)
    assert report is not None, done.stderr
    issues = report["issues"]["issues"]
    assert [i for i in issues if i["severity"] == "error"] == []
    sidecar = json.loads(volume_log_path(paths).with_suffix(".json").read_text())
    assert {"onset", "volume", "dummy", "status"} <= set(sidecar)


def test_a_trigger_device_that_does_not_exist_ends_with_one_line_and_no_run(tmp_path):
    root = tmp_path / "results"
    done = batch(root, "--time-scale", "1", "--trigger", "serial:/dev/no-such-trigger")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip().splitlines()[-1] == (
        "pinarray: /dev/no-such-trigger: cannot open the trigger device: No such file or directory")
    assert "Traceback" not in done.stderr
    assert no_run_was_created(root)


@realtime
def test_a_scanner_that_sends_nothing_gives_up_after_the_timeout_with_no_run(tmp_path):
    root = tmp_path / "results"
    with fake_scanner(tr_s=1, volumes=0) as scanner:
        scanner.start()
        done = batch(root, "--time-scale", "1", "--trigger", f"serial:{scanner.path}",
                     "--dummy-volumes", "1", "--trigger-timeout", "1")
    assert done.returncode == 2, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert "0 of the 2 volume(s) to time zero came" in last and "No run was started" in last
    assert no_run_was_created(root)


@realtime
def test_the_wrong_trigger_character_is_named_when_nothing_counts(tmp_path):
    root = tmp_path / "results"
    with fake_scanner(tr_s=0.2, delay_s=0.1, character=b"t", volumes=3) as scanner:
        status, _, err = batch_with_scanner(root, scanner, "--time-scale", "1", "--trigger",
                                            f"serial:{scanner.path}", "--trigger-timeout", "1")
    assert status == 2
    assert err.splitlines()[-1].endswith(
        "; 3 other byte(s) came instead ('ttt'): is the trigger character right? No run was started.")
    assert no_run_was_created(root)


def test_emulated_volumes_in_virtual_time_lock_each_trial_to_its_volume(tmp_path, short_protocol):
    """Rehearsal without a scanner: emulate:TR runs in the simulator's virtual time too."""
    root = tmp_path / "results"
    done = batch(root, "--trigger", "emulate:2", "--dummy-volumes", "3", "--lock-to-volumes", "2",
                 protocol=short_protocol)
    assert done.returncode == 0, done.stderr
    paths = RunPaths(root, "S", "1", "short", 1)
    volumes = tsv(volume_log_path(paths))
    assert [v["onset"] for v in volumes[:5]] == ["-6", "-4", "-2", "0", "2"]
    assert {v["status"] for v in volumes} == {"received"}
    # Trials start on counted volumes 0, 2, 4 ... (every 4 s): each onset is its volume's time
    # plus the player's start-up, the same for every trial in virtual time.
    onsets = [float(e["onset"]) for e in tsv(paths.events_tsv)]
    latency = onsets[0]
    assert 0 <= latency < 0.5
    assert [round(o - latency, 9) for o in onsets] == [0, 4, 8]


def test_scanner_options_without_a_trigger_or_with_a_key_are_refused_up_front(tmp_path):
    root = tmp_path / "results"
    lonely = batch(root, "--dummy-volumes", "2")
    assert lonely.returncode == 2
    assert lonely.stderr.strip().splitlines()[-1] == (
        "pinarray: --dummy-volumes: a scanner trigger is needed too: give --trigger serial:PATH, "
        "key or emulate:TR, or a sync: section in the protocol")
    key = batch(root, "--trigger", "key")
    assert key.returncode == 2 and "batch has no keyboard" in key.stderr
    lsl = batch(root, "--lsl")
    assert lsl.returncode == 2 and "--speed 1" in lsl.stderr
    assert no_run_was_created(root)


@realtime
@pytest.mark.parametrize("sim_serve", ["1-16"], indirect=True)
@pytest.mark.parametrize("signum", [signal.SIGHUP, signal.SIGINT])
def test_a_signal_while_waiting_for_the_scanner_leaves_pins_at_rest_torque_off(
        sim_serve, signum, tmp_path):  # noqa: F811
    from scservo_sdk import COMM_SUCCESS

    from pinarray.hardware.feetech.registers import Register
    from tests.hardware.test_compat import vendor_port

    root = tmp_path / "results"
    with fake_scanner(tr_s=1, volumes=0) as scanner:
        status, _, err = batch_with_scanner(root, scanner, "--port", sim_serve, "--trigger",
                                            f"serial:{scanner.path}", signum=signum)
    assert status == 128 + signum, err
    assert "Traceback" not in err
    assert no_run_was_created(root)
    port, handler = vendor_port(sim_serve)
    torque = [handler.read1ByteTxRx(port, i, Register.TORQUE_ENABLE.address)[:2]
              for i in range(1, 17)]
    port.closePort()
    assert torque == [(0, COMM_SUCCESS)] * 16


@pytest.mark.parametrize(("options", "said"), [
    (["--dummy-volumes", "2"], "pinarray: --dummy-volumes: a scanner trigger is needed too"),
    (["--lsl", "--time-scale", "20"], "pinarray: --lsl: stamped on this machine's clock"),
    (["--trigger", "key", "--time-scale", "20"], "pinarray: --trigger: stamped on this machine"),
    (["--trigger", "usb:/dev/x"], "expected a trigger serial:PATH[:CHAR], key[:CHAR] or emulate"),
])
def test_the_ui_refuses_scanner_options_that_cannot_work_before_it_opens(options, said):
    done = subprocess.run([sys.executable, "-m", "pinarray", "tui", str(DEMO), *options],
                          capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
                          cwd=REPO)
    assert done.returncode == 2 and done.stdout == ""
    # One line (an option argparse rejects comes after its usage lines, as for every option).
    assert said in done.stderr.strip().splitlines()[-1], done.stderr


@realtime
def test_locked_trials_go_on_when_the_trigger_stream_stops(tmp_path, short_protocol):
    """Onsets locked to every 4th volume; the converter goes quiet after volume 3 of the run:
    the later trials start where the TR puts their volumes, on the session's own clock."""
    root = tmp_path / "results"
    with fake_scanner(tr_s=0.25, delay_s=0.3, stop_after=4) as scanner:
        status, out, err = batch_with_scanner(
            root, scanner, "--time-scale", "1", "--trigger", f"serial:{scanner.path}",
            "--dummy-volumes", "1", "--tr", "0.25", "--lock-to-volumes", "4",
            protocol=short_protocol)
    assert status == 0, err
    paths = RunPaths(root, "S", "1", "short", 1)
    volumes = {int(v["volume"]): v for v in tsv(volume_log_path(paths))}
    onsets = [float(e["onset"]) for e in tsv(paths.events_tsv)]
    assert len(onsets) == 3 and onsets == sorted(onsets)
    # Counted volume 4k is volume 4k + 2 (one dummy); trial 1 starts at time zero (volume 2).
    locked = [volumes[4 * k + 2] for k in range(1, 10) if 4 * k + 2 in volumes]
    assert {v["status"] for v in locked} == {"missed"}  # nothing came for them
    slots = [float(v["onset"]) for v in locked]
    # Trial 1's stimulus and interval end at 0.8 s, so trial 2 takes the slot at 1 s (volume 6)
    # and trial 3 a later one; on a busy machine a trial may be ready only after its slot went
    # by and take the next. Whatever the load: each later trial starts at a slot of its own,
    # never before it, and because of it (well inside the 1 s between slots).
    taken = [max(slot for slot in slots if slot <= onset) for onset in onsets[1:]]
    assert taken == sorted(set(taken)), (onsets, slots)
    assert all(onset - slot < 0.5 for onset, slot in zip(onsets[1:], taken, strict=True)), (onsets, slots)
