"""`pinarray play` and `batch` say when a stimulus was not delivered as scheduled, and exit 3."""

import subprocess
import sys
from pathlib import Path

import pytest

from tests.commands import pinarray_here

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
DEMO = PROTOCOLS / "demo.yaml"


def strict(tmp_path, tolerance_ms: str) -> Path:
    """The demo protocol, its goal changes due at their servo within ``tolerance_ms``."""
    text = DEMO.read_text().replace("stimuli:", f"device:\n  delivery_tolerance_ms: {tolerance_ms}\n\nstimuli:", 1)
    path = tmp_path / "demo_strict.yaml"
    path.write_text(text)
    return path


# A bus slower than `pinarray validate` reckons (a cable, an adapter): the wire-time check at
# validate is left out, so that the protocol it refuses is played and found late at run time.
# In a process of its own where the exit status of the real entry point is the point.
UNCHECKED = ("import sys; import pinarray.protocol.stimuli as s; s.bus_problem = lambda *a: None; "
             "from pinarray.cli import main; sys.exit(main(sys.argv[1:]))")


def unchecked_process(*args):
    return subprocess.run([sys.executable, "-c", UNCHECKED, *args], capture_output=True,
                          text=True, timeout=300)


@pytest.fixture
def unchecked(monkeypatch):
    """`pinarray ARGS` in this process with the wire-time check left out, as UNCHECKED does."""
    monkeypatch.setattr("pinarray.protocol.stimuli.bus_problem", lambda *a: None)
    return pinarray_here


def test_validate_refuses_a_delivery_tolerance_shorter_than_the_wire_takes(tmp_path):
    result = pinarray_here("validate", strict(tmp_path, "0.000001"))
    assert result.returncode == 2
    assert "the servo bus cannot deliver it: a frame of 1 goal(s)" in result.stderr
    assert "later than the delivery tolerance" in result.stderr


def test_play_reports_what_reached_the_servos_for_each_trial():
    result = pinarray_here("play", DEMO, "--trial", "3")
    assert result.returncode == 0, result.stderr
    trial_line = next(line for line in result.stdout.splitlines() if line.startswith("trial 3"))
    assert "20/20 goal changes confirmed (0 healed, 0 missing)" in trial_line


def test_play_exits_3_when_a_stimulus_is_not_delivered_as_scheduled(tmp_path):
    # 1 ns is less than the wire takes: every goal change arrives "late".
    result = unchecked_process("play", str(strict(tmp_path, "0.000001")), "--trial", "2")
    assert result.returncode == 3, result.stderr
    assert "NOT DELIVERED AS SCHEDULED" in result.stdout
    assert "trial(s) 2 NOT delivered as scheduled" in result.stderr
    assert "16 servo(s) at rest" in result.stdout and "Traceback" not in result.stderr


def test_batch_presents_a_failed_trial_again_then_gives_up_leaving_the_run_resumable(
        tmp_path, unchecked):
    out = tmp_path / "out"
    result = unchecked("batch", str(strict(tmp_path, "0.000001")), "--subject", "s1",
                      "--observer", "default", "--results", str(out))
    assert result.returncode == 3, result.stderr
    assert "trial 1, attempt 3 of 3: the stimulus was not delivered as scheduled" in result.stderr
    assert "--resume" in result.stderr.splitlines()[-1]
    (beh,) = out.rglob("*_beh.tsv")
    rows = beh.read_text().splitlines()[1:]
    assert len(rows) == 3 and all("\tinvalid\t" in row for row in rows)
