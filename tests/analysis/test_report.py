"""`pinarray analyse` as a lab uses it: results folder in, tables, figures and a page out."""

import argparse
import csv
import subprocess
import sys

import pytest

from pinarray.analysis.commands import register
from pinarray.errors import ResultsError
from pinarray.manifest import RunPaths


def analyse(*argv):
    """Run `pinarray analyse` through its own parser, as the CLI would."""
    parser = argparse.ArgumentParser(prog="pinarray")
    register(parser.add_subparsers())
    args = parser.parse_args(["analyse", *argv])
    return args.func(args)


def read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_analyse_writes_tables_figures_and_a_page_that_links_them(results_root, tmp_path, capsys):
    out = tmp_path / "analysis"
    assert analyse(str(results_root), "--out", str(out)) == 0
    assert "21 trial rows from 4 file(s), 2 subject(s)" in capsys.readouterr().out
    page = (out / "summary.md").read_text()
    for name in ("correct_by_frequency.png", "error_types.png", "motion.png",
                 "confusion_matrix.png", "pin_accuracy.png", "localisation_by_frequency.csv",
                 "pin_accuracy.csv", "motion.csv", "confusion_matrix.csv"):
        assert f"({name})" in page
        assert (out / name).exists()
    for png in out.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "33.3 % [9.7, 70.0] (2/6)" in page


def test_the_tables_hold_the_hand_counted_numbers(results_root, tmp_path):
    out = tmp_path / "analysis"
    analyse(str(results_root), "--out", str(out))
    by_frequency = {(r["group"], r["frequency_hz"]): r
                    for r in read_csv(out / "localisation_by_frequency.csv")}
    ten = by_frequency[("all", "10")]
    assert (ten["trials"], ten["correct"], ten["correct_pct"], ten["error_A_pct"]) == \
        ("5", "2", "40.0", "40.0")
    assert by_frequency[("sub-B", "3")]["error_C_pct"] == "50.0"
    motion = {r["group"]: r for r in read_csv(out / "motion.csv")}
    assert (motion["all"]["felt"], motion["all"]["direction_right_pct"]) == ("5", "60.0")
    confusion = read_csv(out / "confusion_matrix.csv")
    assert confusion[3]["reported_4"] == "2" and confusion[3]["reported_8"] == "1"
    pins = {(r["group"], r["pin"]): r for r in read_csv(out / "pin_accuracy.csv")}
    assert pins[("all", "10")]["correct_pct"] == "20.0"
    assert pins[("all", "2")]["correct_pct"] == "n/a"


def test_a_single_file_can_be_analysed_and_a_torn_last_row_is_ignored(results_root, tmp_path):
    beh = RunPaths(results_root, "B", "1", "localisation", 1).beh_tsv
    with open(beh, "a") as handle:
        handle.write("4\t1\tlocalisation\t4\tn/a")
    out = tmp_path / "one"
    assert analyse(str(beh), "--out", str(out)) == 0
    rows = read_csv(out / "localisation_by_frequency.csv")
    assert sum(int(r["trials"]) for r in rows if r["group"] == "all") == 3
    assert not (out / "motion.png").exists()


def test_a_missing_or_empty_results_path_is_a_results_error_naming_it(tmp_path):
    with pytest.raises(ResultsError, match="nowhere: no such results file or folder"):
        analyse(str(tmp_path / "nowhere"), "--out", str(tmp_path / "o"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ResultsError, match=r"no \*_beh.tsv files found in .*empty"):
        analyse(str(tmp_path / "empty"), "--out", str(tmp_path / "o"))
    assert not (tmp_path / "o").exists()


def test_registering_the_command_loads_neither_numpy_nor_matplotlib():
    probe = ("import sys, argparse, pinarray.analysis.commands as c;"
             "c.register(argparse.ArgumentParser().add_subparsers());"
             "print(sorted(m for m in ('numpy', 'matplotlib') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            timeout=60)
    assert result.stdout.strip() == "[]", result.stderr
