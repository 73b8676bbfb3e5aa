"""The tap-counting paradigm as pinarray sees it once the package is installed: found by its
entry point, its protocol validated (problems located in the file), run in batch with its
simulated subject, its rows read back and checked, and analysed with every estimate's status.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest
from pinarray_tap_count import PARADIGM, TapCountCondition
from pinarray_tap_count.rows import TapCountRecord

import pinarray
from pinarray import registry
from pinarray.errors import ProtocolErrors, ResultsError
from pinarray.paradigms.base import missing_faces
from pinarray.protocol.load import parse_protocol

HERE = Path(__file__).resolve().parents[1]
PROTOCOL = HERE / "tap_count.yaml"


def pinarray_command(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pinarray", *args], capture_output=True,
                          text=True, timeout=300)


# --8<-- [start:found]
def test_pinarray_finds_the_paradigm_by_its_entry_point_and_it_implements_the_whole_seam() -> None:
    assert "tap_count" in registry.names()
    assert registry.room("tap_count") is PARADIGM
    assert isinstance(PARADIGM, pinarray.Paradigm) and missing_faces(PARADIGM) == []
# --8<-- [end:found]


def test_the_protocol_validates_with_one_condition_per_pin_and_count() -> None:
    result = pinarray_command("validate", str(PROTOCOL))
    assert result.returncode == 0, result.stderr
    assert "ok (tap_count, 40 trials in 1 block(s), 2 practice)" in result.stdout
    protocol = pinarray.load_protocol(PROTOCOL)
    assert {(c.pin, c.taps) for c in protocol.design.conditions
            if isinstance(c, TapCountCondition)} == {(p, t) for p in (6, 11) for t in range(2, 6)}
    assert protocol.design.answers(16) == ("2", "3", "4", "5")


def test_a_problem_of_the_design_is_said_where_it_is_written() -> None:
    text = PROTOCOL.read_text().replace("taps: [2, 3, 4, 5]", "taps: [2, 30, 4, 5]")
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "t.yaml")
    (problem,) = raised.value.errors
    line = text.splitlines().index("  taps: [2, 30, 4, 5]") + 1
    assert (problem.line, problem.col) == (line, 13)
    assert problem.message == "expected a tap count of at most 9, found 30"


def test_every_condition_is_checked_as_it_would_play_by_pinarray() -> None:
    # 9 taps in 0.1 s is 90 Hz: its 2 ms pulses do not fit their period, said at the count.
    text = PROTOCOL.read_text().replace("duration_s: 1\n", "duration_s: 0.1\n").replace(
        "taps: [2, 3, 4, 5]", "taps: [2, 9]")
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "t.yaml")
    (problem,) = raised.value.errors
    assert (problem.line, problem.col) == (text.splitlines().index("  taps: [2, 9]") + 1, 13)
    assert "at 90 Hz" in problem.message


def test_a_batch_run_is_written_read_back_and_analysed(tmp_path: Path) -> None:
    results, out = tmp_path / "results", tmp_path / "analysis"
    ran = pinarray_command("batch", str(PROTOCOL), "--subject", "01", "--observer", "default",
                           "--seed", "1", "--results", str(results))
    assert ran.returncode == 0, ran.stderr
    (run,) = pinarray.read_results(results)
    assert len(run.records) == 42 and all(isinstance(r, TapCountRecord) for r in run.records)
    assert all(r.response in ("2", "3", "4", "5") for r in run.records)
    analysed = pinarray_command("analyse", str(results), "--out", str(out), "--no-figures")
    assert analysed.returncode == 0, analysed.stderr
    assert "40 tap-counting trials" in analysed.stdout
    with open(out / "estimates.csv", newline="") as handle:
        estimates = [r for r in csv.DictReader(handle) if r["paradigm"] == "tap_count"]
    assert {r["measure"] for r in estimates} == {f"correct_{t}_taps" for t in range(2, 6)}
    assert all(r["status"] == "estimated" for r in estimates)
    assert (out / "tap_count.csv").exists()


def test_a_row_edited_by_hand_is_refused_where_it_is(tmp_path: Path) -> None:
    results = tmp_path / "results"
    assert pinarray_command("batch", str(PROTOCOL), "--subject", "01", "--observer",
                            "default", "--seed", "2", "--results",
                            str(results)).returncode == 0
    beh = next(results.rglob("*_beh.tsv"))
    header, first, *rest = beh.read_text().splitlines()
    cells = first.split("\t")
    column = header.split("\t").index("taps")
    cells[column] = str(int(cells[column]) % 5 + 2)  # another count than the plan's
    beh.write_text("\n".join([header, "\t".join(cells), *rest]) + "\n")
    with pytest.raises(ResultsError, match=f"{beh}:2: trial 1: "):
        pinarray.read_results(results)
