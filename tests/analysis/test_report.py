"""`pinarray analyse` as a lab uses it: results folder in, tables, figures and a page out."""

import argparse
import contextlib
import csv
import io
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from pinarray import cli
from pinarray.cli.analysis import register
from pinarray.errors import ResultsError
from pinarray.journal.manifest import RunPaths
from tests.analysis.conftest import keep_figures, localisation_row, write_results

# One worker builds the module's fixture once (make test runs --dist loadgroup).
pytestmark = pytest.mark.xdist_group("report")

FIGURES = ("correct_by_frequency", "error_types", "motion", "confusion_matrix", "pin_accuracy")


def analyse(*argv):
    """Run `pinarray analyse` through its own parser, as the CLI would."""
    parser = argparse.ArgumentParser(prog="pinarray")
    register(parser.add_subparsers())
    args = parser.parse_args(["analyse", *argv])
    return args.func(args)


def read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@dataclass(frozen=True)
class Analysis:
    out: Path
    printed: str
    drawn: dict  # each figure drawn, by name, as saved


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    """The two subjects' results analysed once with the default options (a few seconds of
    figures and fits), for the tests that only read what it wrote, drew and printed."""
    folder = tmp_path_factory.mktemp("report")
    out = folder / "analysis"
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as monkeypatch, contextlib.redirect_stdout(printed):
        drawn = keep_figures(monkeypatch, draw=True)
        assert analyse(str(write_results(folder / "results")), "--out", str(out)) == 0
    return Analysis(out, printed.getvalue(), drawn)


def test_analyse_writes_tables_figures_as_png_and_pdf_and_a_page_that_links_them(analysed):
    out, printed = analysed.out, analysed.printed
    assert "counted 4 run(s): 2 subject(s), 11 localisation trials and 8 motion trials" in printed
    page = (out / "summary.md").read_text()
    for name in FIGURES:
        assert f"({name}.png)" in page and f"({name}.pdf)" in page
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / f"{name}.pdf").read_bytes()[:5] == b"%PDF-"
    for name in ("localisation_subject_level.csv", "localisation_per_subject.csv",
                 "pin_accuracy.csv", "confusion_matrix.csv", "frequency_effect.csv",
                 "motion_subject_level.csv", "motion_per_subject.csv", "runs.csv"):
        assert f"({name})" in page and (out / name).exists()


def test_a_fixed_design_writes_no_thresholds_and_no_threshold_figures(analysed):
    out = analysed.out
    assert not (out / "thresholds.csv").exists()
    assert not list(out.glob("track_*")) and not list(out.glob("fit_*"))
    assert "Thresholds" not in (out / "summary.md").read_text()
    assert "thresholds" not in analysed.printed


def test_results_without_measured_strokes_are_analysed_and_say_there_is_no_stroke_table(
        analysed):
    out = analysed.out
    assert not (out / "stroke_by_frequency.csv").exists()
    assert not (out / "stroke_by_frequency.png").exists()
    page = (out / "summary.md").read_text()
    assert "No stroke table: nothing was measured" in page


def test_no_figures_writes_the_same_tables_and_printout_and_the_page_says_none_were_drawn(
        analysed):
    out = analysed.out.parent / "tables-only"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert analyse(str(analysed.out.parent / "results"), "--out", str(out),
                       "--no-figures") == 0
    assert printed.getvalue().replace(str(out), "OUT") == \
        analysed.printed.replace(str(analysed.out), "OUT")
    tables = sorted(p.name for p in analysed.out.glob("*.csv"))
    assert tables and sorted(p.name for p in out.glob("*.csv")) == tables
    for name in tables:
        assert (out / name).read_bytes() == (analysed.out / name).read_bytes(), name
    assert not list(out.glob("*.png")) and not list(out.glob("*.pdf"))
    page = (out / "summary.md").read_text()
    assert "Not drawn: analysed with `--no-figures`." in page and "*Figure" not in page
    drawn = (analysed.out / "summary.md").read_text()
    assert page.split("## Figures")[0] == drawn.split("## Figures")[0]


@pytest.mark.parametrize("lab_setting", ["figure.constrained_layout.use", "figure.autolayout"])
def test_a_labs_matplotlibrc_asking_for_a_layout_engine_changes_no_figure(analysed, lab_setting,
                                                                        monkeypatch):
    # Under constrained layout a figure with a colour bar refused to be laid out (a traceback);
    # under autolayout the axes were laid over the caption in the PDFs.
    import matplotlib

    out = analysed.out.parent / f"under-{lab_setting}"
    keep_figures(monkeypatch, draw=lambda name: name in ("confusion_matrix", "error_types"))
    with matplotlib.rc_context({lab_setting: True}), contextlib.redirect_stdout(io.StringIO()):
        assert analyse(str(analysed.out.parent / "results"), "--out", str(out)) == 0
    for name in ("confusion_matrix.png", "confusion_matrix.pdf", "error_types.pdf"):
        assert (out / name).read_bytes() == (analysed.out / name).read_bytes(), name


def test_the_page_and_the_printout_give_subject_means_and_label_the_pooled_numbers(analysed):
    out, printed = analysed.out, analysed.printed
    # 3 Hz: subject A 25 %, subject B 50 %: mean 37.5 %; the 6 trials pooled: 2/6.
    # The subject bootstrap of two subjects spans the two: [25, 50] (see test_subjects).
    assert "3 Hz: 37.5 % [25.0, 50.0] (2 subj., 6 trials); trial-pooled 33.3 % [9.7, 70.0]" \
        in printed
    page = (out / "summary.md").read_text()
    assert "| 3 Hz | 2 | 6 | 37.5 % | [25.0, 50.0] | 33.3 % [9.7, 70.0] (2/6) | 6.25 % |" in page
    assert "95 % subject bootstrap (percentile; 10000 resamples of subjects, seed 20240501; " \
           "stays within 0-100 %)" in page
    assert "Trial-pooled" in page and "not fitted: needs at least 6 subjects" in page


INTERVAL = re.compile(r"\[(-?[0-9.]+), (-?[0-9.]+)\]")


def test_no_interval_of_a_percentage_leaves_0_to_100_by_default(analysed):
    # Two subjects at 25 and 50 % correct: their t interval is [-121.3, 196.3] %.
    out, printed = analysed.out, analysed.printed
    shown = [(m.group(0), float(m.group(1)), float(m.group(2))) for text in
             (printed, (out / "summary.md").read_text()) for m in INTERVAL.finditer(text)]
    for csv_name in ("localisation_subject_level.csv", "pin_accuracy.csv",
                     "motion_subject_level.csv"):
        for row in read_csv(out / csv_name):
            for column in row:
                if column.endswith("_low_pct") and row[column] != "n/a":
                    high = column.replace("_low_pct", "_high_pct")
                    shown.append((f"{csv_name} {column}", float(row[column]), float(row[high])))
    assert len(shown) > 20
    assert [s for s in shown if not 0 <= s[1] <= s[2] <= 100] == []


def test_the_old_t_interval_is_there_when_asked_for_and_says_it_is_not_bounded(results_root,
                                                                              tmp_path, capsys):
    out = tmp_path / "analysis"
    analyse(str(results_root), "--out", str(out), "--interval", "t", "--no-figures")
    assert "3 Hz: 37.5 % [-121.3, 196.3] (2 subj., 6 trials)" in capsys.readouterr().out
    page = (out / "summary.md").read_text()
    assert "| 3 Hz | 2 | 6 | 37.5 % | [-121.3, 196.3] | [25.0, 50.0] | 33.3 % [9.7, 70.0] (2/6) " \
           "| 6.25 % |" in page
    assert "t interval across subjects (mean ± t(N-1) · SD/√N; not bounded: may pass 0 or " \
           "100 %)" in page
    three = next(r for r in read_csv(out / "localisation_subject_level.csv")
                 if (r["frequency_hz"], r["category"]) == ("3", "correct"))
    assert (three["t95_low_pct"], three["bootstrap95_low_pct"]) == ("-121.3", "25.0")


def test_every_caption_states_n_the_unit_and_the_interval(results_root, tmp_path, monkeypatch):
    # The page's captions are the figures': drawing them (the module's fixture does) adds
    # nothing to what the page says.
    kept = keep_figures(monkeypatch)
    out = tmp_path / "analysis"
    analyse(str(results_root), "--out", str(out), "--interval", "bootstrap",
            "--bootstrap-seed", "9")
    page = (out / "summary.md").read_text()
    captions = [line for line in page.splitlines() if line.startswith("*Figure")]
    assert len(captions) == len(FIGURES) == len(kept)
    for caption in captions:
        assert "N = " in caption and "unit: " in caption
    for caption in captions:
        if "trial-pooled" not in caption and "per pin" not in caption:
            assert "subject bootstrap (percentile; 10000 resamples of subjects, seed 9; " \
                   "stays within 0-100 %)" in caption


def test_the_tables_hold_the_hand_counted_numbers(analysed):
    out = analysed.out
    means = {(r["frequency_hz"], r["category"]): r
             for r in read_csv(out / "localisation_subject_level.csv")}
    ten = means[("10", "correct")]
    assert (ten["subjects"], ten["trials"], ten["subject_mean_pct"], ten["trial_pooled_pct"]) \
        == ("2", "5", "25.0", "40.0")
    assert (ten["bootstrap_seed"], ten["chance_pct"]) == ("20240501", "6.25")
    assert means[("3", "none")]["subject_mean_pct"] == "12.5"  # nothing felt: its own row
    assert means[("3", "none")]["chance_pct"] == "n/a"
    per_subject = {(r["subject"], r["frequency_hz"]): r
                   for r in read_csv(out / "localisation_per_subject.csv")}
    assert per_subject[("B", "3")]["C_pct"] == "50.0"
    assert per_subject[("A", "3")]["none"] == "1"
    motion = {r["measure"]: r for r in read_csv(out / "motion_subject_level.csv")}
    assert motion["direction_right_of_felt"]["subject_mean_pct"] == "66.7"
    assert motion["direction_right_of_felt"]["chance_pct"] == "50.00"


def test_nothing_felt_appears_in_the_confusion_matrix_and_rows_divide_by_all_trials(analysed):
    out = analysed.out
    rows = {r["stimulated_pin"]: r for r in read_csv(out / "confusion_matrix.csv")}
    ten = rows["10"]
    assert ten["nothing_felt"] == "1" and ten["trials"] == "5"
    answered = sum(int(v) for k, v in ten.items() if k.startswith("answer_"))
    assert answered + int(ten["nothing_felt"]) == int(ten["trials"])
    assert set(rows) == {"1", "4", "10"}  # only stimulated pins get a row


def test_pin_accuracy_numbers_pins_rows_and_columns_from_1(analysed):
    out = analysed.out
    pins = {r["pin"]: r for r in read_csv(out / "pin_accuracy.csv")}
    assert (pins["1"]["row"], pins["1"]["column"]) == ("1", "1")  # bottom-left
    assert (pins["16"]["row"], pins["16"]["column"]) == ("4", "4")  # top-right
    assert (pins["10"]["row"], pins["10"]["column"]) == ("3", "2")
    assert pins["10"]["trial_pooled_pct"] == "20.0" and pins["2"]["subject_mean_pct"] == "n/a"


def test_the_error_figure_draws_nothing_felt_and_the_chance_levels(analysed):
    drawn = analysed.drawn
    errors = drawn["error_types"].axes[0]
    _, labels = errors.get_legend_handles_labels()
    assert sorted(labels) == ["chance", "error A", "error B", "error C", "error D",
                              "nothing felt"]
    nothing_felt = errors.containers[-1]  # the last bars drawn: nothing felt, 3 and 10 Hz
    # 100 / 8 and 100 / 16 are exact quotients: == holds on any IEEE machine
    assert [round(bar.get_height(), 1) for bar in nothing_felt] == [12.5, 0.0]
    correct = drawn["correct_by_frequency"].axes[0]
    assert [line.get_ydata()[0] for line in correct.lines if line.get_linestyle() == "--"] \
        == [6.25]


def test_an_aborted_run_is_listed_and_left_out_unless_asked_for(results_root, tmp_path,
                                                                  write_run, capsys):
    write_run(results_root, "C", "localisation", [localisation_row(1, 4, "4")],
              status="aborted")
    out = tmp_path / "analysis"
    analyse(str(results_root), "--out", str(out), "--no-figures")
    printed = capsys.readouterr().out
    assert ("left out: sub-C ses-1 task-localisation run-1: manifest says aborted "
            "(1 counted trial(s)); --include-incomplete counts it") in printed
    assert "2 subject(s)" in printed
    runs = {r["subject"]: r for r in read_csv(out / "runs.csv") if r["task"] == "localisation"}
    assert (runs["C"]["included"], runs["C"]["incomplete_reason"]) == \
        ("no", "manifest says aborted")
    analyse(str(results_root), "--out", str(out), "--include-incomplete", "--no-figures")
    printed = capsys.readouterr().out
    assert "3 subject(s)" in printed and "counted on request: sub-C" in printed


def test_a_single_file_can_be_analysed_and_a_torn_last_row_is_ignored(results_root, tmp_path,
                                                                     monkeypatch):
    beh = RunPaths(results_root, "B", "1", "localisation", 1).beh_tsv
    with open(beh, "a") as handle:
        handle.write("4\t1\tlocalisation\t4\tn/a")
    out = tmp_path / "one"
    kept = keep_figures(monkeypatch)  # which figures; how they are drawn: the module's fixture
    assert analyse(str(beh), "--out", str(out)) == 0
    rows = read_csv(out / "localisation_per_subject.csv")
    assert sum(int(r["trials"]) for r in rows) == 3
    assert sorted(kept) == sorted(set(FIGURES) - {"motion"})  # only the localisation run's


def test_a_missing_or_empty_results_path_is_a_results_error_naming_it(tmp_path):
    with pytest.raises(ResultsError, match="nowhere: no such results file or folder"):
        analyse(str(tmp_path / "nowhere"), "--out", str(tmp_path / "o"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ResultsError, match=r"no \*_beh.tsv files found in .*empty"):
        analyse(str(tmp_path / "empty"), "--out", str(tmp_path / "o"))
    assert not (tmp_path / "o").exists()


def test_bad_options_are_one_line_errors_with_status_2(results_root, tmp_path, capsys):
    out = str(tmp_path / "o")
    assert cli.main(["analyse", str(results_root), "--out", out, "--answer-pins", "1,17"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pin 17 is not on the 4x4 grid" in err
    with pytest.raises(SystemExit) as exit_:
        cli.main(["analyse", str(results_root), "--bootstrap-resamples", "5"])
    assert exit_.value.code == 2 and "expected a whole number from 100 to" in capsys.readouterr().err


@pytest.mark.parametrize("inside", ["sub-A/ses-1/beh", "sub-A", "sourcedata/report", "."])
def test_a_report_is_refused_inside_the_datasets_raw_data(results_root, inside, capsys):
    before = sorted((p, p.read_bytes()) for p in results_root.rglob("*") if p.is_file())
    out = results_root / inside
    assert cli.main(["analyse", str(results_root), "--out", str(out), "--no-figures"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        f"pinarray: {out}: expected a report folder outside the raw data, found one in ")
    assert sorted((p, p.read_bytes()) for p in results_root.rglob("*") if p.is_file()) == before
    # Beside the subjects, in a folder of its own (derivatives/, as BIDS has it), it is written.
    assert cli.main(["analyse", str(results_root), "--out",
                     str(results_root / "derivatives" / "report"), "--no-figures"]) == 0



@pytest.mark.parametrize("inside", ["sub-A/ses-1/beh/report", "sourcedata/report"])
def test_a_report_is_refused_inside_another_datasets_raw_data(results_root, tmp_path, inside,
                                                              capsys):
    other = write_results(tmp_path / "other")
    before = sorted((p, p.read_bytes()) for p in other.rglob("*") if p.is_file())
    out = other / inside
    assert cli.main(["analyse", str(results_root), "--out", str(out), "--no-figures"]) == 2
    err = capsys.readouterr().err
    assert err == (f"pinarray: {out}: expected a report folder outside the raw data, found "
                   f"one in {inside.split('/')[0]}/ of the dataset {other}; write it elsewhere "
                   "(a BIDS dataset keeps it in derivatives/)\n")
    assert sorted((p, p.read_bytes()) for p in other.rglob("*") if p.is_file()) == before
    assert not out.exists()

def test_registering_the_command_loads_neither_numpy_nor_matplotlib():
    probe = ("import sys, argparse, pinarray.cli.analysis as c;"
             "c.register(argparse.ArgumentParser().add_subparsers());"
             "print(sorted(m for m in ('numpy', 'matplotlib', 'scipy') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            timeout=60)
    assert result.stdout.strip() == "[]", result.stderr
