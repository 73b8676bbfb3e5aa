"""Results files that were damaged after the run: named with the reason, never read as data
without a word, and left out only when the analyst asks to go on without them."""

import contextlib
import io
import shutil

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from pinarray.analysis.load import DamagedResults, load_runs, scan_runs, select_runs
from pinarray.cli import main
from tests.analysis.conftest import _write, localisation_row


def two_runs(root):
    good = _write(root, "A", "localisation", [localisation_row(n, 4, "4") for n in range(1, 6)])
    other = _write(root, "B", "localisation", [localisation_row(n, 4, "3") for n in range(1, 6)])
    return good, other


def analyse(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["analyse", *argv])
    return status, out.getvalue(), err.getvalue()


@pytest.mark.parametrize(("damage", "where", "why"), [
    (b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR", ":3:1:", "found a NUL byte (a binary file?)"),
    ("trial\tblock\nsé".encode("latin-1"), ":2:2:", "expected UTF-8 text, found byte 0xe9"),
    (b"hello\tworld\n1\t2\n", ":1:", "expected the columns"),
    # A line break of another system (a lone carriage return) inside a row.
    (b"trial\tblock\n1\t\r2\n", ":2:3:", "found a carriage return inside a row"),
])
def test_a_damaged_file_stops_the_analysis_naming_the_file_the_line_and_why(
        tmp_path, damage, where, why):
    _, broken = two_runs(tmp_path / "results")
    broken.beh_tsv.write_bytes(damage)
    status, out, err = analyse(str(tmp_path / "results"), "--out", str(tmp_path / "report"))
    assert status == 2 and out == ""
    first, hint = err.splitlines()
    assert first.startswith(f"pinarray: {broken.beh_tsv}{where}") and why in first
    assert hint == ("pinarray: 1 damaged results file(s); --skip-damaged analyses the rest "
                    "without them")
    assert not (tmp_path / "report").exists()


def test_skip_damaged_analyses_the_rest_and_says_what_it_left_out(tmp_path):
    _, broken = two_runs(tmp_path / "results")
    broken.beh_tsv.write_bytes(b"\0" * 10 + b"\n" + b"\0" * 10)
    status, out, err = analyse(str(tmp_path / "results"), "--out", str(tmp_path / "report"),
                               "--skip-damaged", "--no-figures")
    assert status == 0
    assert err == (f"pinarray: {broken.beh_tsv}:1:1: expected a tab-separated results table, "
                   "found a NUL byte (a binary file?) (skipped)\n")
    assert out.startswith("counted 1 run(s): 1 subject(s), 5 localisation")


def test_analyse_counts_a_copied_run_folder_once_and_says_what_it_passed_over(tmp_path):
    good, _ = two_runs(tmp_path / "results")
    copy = tmp_path / "results" / "sub-A copy"
    shutil.copytree(tmp_path / "results" / "sub-A", copy)
    status, out, err = analyse(str(tmp_path / "results"), "--out", str(tmp_path / "report"),
                               "--no-figures")
    assert status == 0
    assert err == (f"pinarray: {copy / good.relative_dir.relative_to('sub-A') / good.beh_tsv.name}"
                   f": passed over: a file of {good.label} belongs in sub-A/ses-1/beh/, not in "
                   "sub-A copy/ses-1/beh/ (a copy?); rename or remove the copy\n")
    assert out.startswith("counted 2 run(s): 2 subject(s), 10 localisation")


def test_a_completed_run_cut_short_is_left_out_with_the_trials_it_lacks(tmp_path):
    _, short = two_runs(tmp_path / "results")
    lines = short.beh_tsv.read_bytes().splitlines(keepends=True)
    short.beh_tsv.write_bytes(b"".join(lines[:3]))  # header and trials 1 and 2
    runs = select_runs(load_runs([tmp_path / "results"]))
    (left_out,) = runs.excluded
    assert left_out.paths.subject == "B"
    assert left_out.incomplete_reason == ("manifest says completed, but trial(s) 3, 4, 5 have no "
                                          "finished row (the file was cut short?)")


def test_a_completed_run_with_a_row_set_to_invalid_by_hand_is_left_out_saying_what_was_found(
        tmp_path):
    _, edited = two_runs(tmp_path / "results")
    header, *rows = edited.beh_tsv.read_text().splitlines()
    status = header.split("\t").index("status")
    cells = rows[1].split("\t")  # trial 2
    cells[status] = "invalid"
    rows[1] = "\t".join(cells)
    edited.beh_tsv.write_text("\n".join([header, *rows[:-1]]) + "\n")  # and trial 5 cut
    (left_out,) = select_runs(load_runs([tmp_path / "results"])).excluded
    assert left_out.incomplete_reason == (
        "manifest says completed, but trial(s) 5 have no finished row (the file was cut "
        "short?); trial(s) 2 have rows but none with status ok (found invalid; edited by hand?)")


def test_a_torn_last_row_is_left_out_and_said(tmp_path):
    _, torn = two_runs(tmp_path / "results")
    data = torn.beh_tsv.read_bytes()
    torn.beh_tsv.write_bytes(data[: len(data) - 20])
    status, out, _ = analyse(str(tmp_path / "results"), "--out", str(tmp_path / "report"),
                             "--no-figures")
    assert status == 0
    assert f"  {torn.beh_tsv}: its last row was cut short by an interrupted write" in out
    assert "trial(s) 5 have no finished row" in out


@settings(max_examples=60, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(cut=st.integers(0, 10_000), insert=st.binary(max_size=8), at=st.integers(0, 10_000))
@example(cut=543, insert=b"\r", at=0)  # once a traceback: a carriage return before the header
def test_any_damage_to_a_results_file_loads_it_or_names_it(tmp_path_factory, cut, insert, at):
    root = tmp_path_factory.mktemp("results")
    _, damaged = two_runs(root)
    data = damaged.beh_tsv.read_bytes()
    data = data[: min(cut, len(data))] if cut < len(data) else data
    at = min(at, len(data))
    damaged.beh_tsv.write_bytes(data[:at] + insert + data[at:])
    runs, broken = scan_runs([root])
    assert len(runs) + len(broken) == 2
    for run in broken:
        assert run.reason.startswith(str(run.source)) and "\n" not in run.reason
    if broken:
        with pytest.raises(DamagedResults):
            load_runs([root])
