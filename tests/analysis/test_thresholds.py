"""Thresholds of adaptive runs as a lab reads them: each procedure's estimate, a fitted
psychometric function per subject, the across-subject mean, thresholds.csv and the figures."""

import argparse
import contextlib
import csv
import io
import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import pytest

from pinarray import cli
from pinarray.adaptive.posterior import threshold_posterior
from pinarray.analysis.load import load_runs, select_runs
from pinarray.analysis.report import summary_markdown
from pinarray.analysis.study import study
from pinarray.analysis.tables import write_tables
from pinarray.analysis.thresholds import parameter_and_unit
from pinarray.cli.analysis import register
from pinarray.journal.records import AdaptiveCells
from tests.analysis.adaptive_runs import Written, detection_run, motion_row, motion_run
from tests.analysis.conftest import keep_figures

# One worker builds the module's fixture once (about 20 s: two subjects' runs, fits, figures).
pytestmark = [pytest.mark.xdist_group("thresholds"), pytest.mark.long]

COLUMNS = ["subject", "task", "parameter", "unit", "method", "threshold", "ci_low", "ci_high",
           "n_trials", "procedure", "status", "guess_rate", "lapse_rate",
           "pct_correct_at_threshold"]
# Subject 02's true thresholds are twice subject 01's (60 and 120 ms of SOA; 6 and 12 steps of
# stroke). How far from 2 the ratio of two subjects' estimates falls is the numerics' spread,
# measured on simulated pairs of subjects of this very design with other seeds: over 150 pairs
# of the motion task the ML fits' ratio fell within 1.51-2.83 and the ratio of the means of
# each subject's two staircases within 1.53-2.88 (a single staircase's ratio has a long tail,
# up to 7, from lapses high on its track, so it is not compared alone); over 200 pairs of the
# detection task the QUEST+ posterior means' within 1.54-2.66 and the fits' within 1.48-2.72.
# The tolerance takes in all of them.
RATIO = (1.4, 2.9)


def analyse(*argv):
    parser = argparse.ArgumentParser(prog="pinarray")
    register(parser.add_subparsers())
    args = parser.parse_args(["analyse", *argv])
    return args.func(args)


def read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@dataclass(frozen=True)
class Analysed:
    out: Path
    printed: str
    written: dict[tuple[str, str], Written]  # (subject, task) -> what the simulation wrote
    figures: dict  # stem -> each figure analyse handed to `save`, drawn or not

    def rows(self, **match):
        return [r for r in read_csv(self.out / "thresholds.csv")
                if all(r[k] == v for k, v in match.items())]

    def one(self, **match):
        found = self.rows(**match)
        assert len(found) == 1, found
        return found[0]


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    """Two simulated subjects, the second with twice the first's thresholds, analysed once."""
    folder = tmp_path_factory.mktemp("thresholds")
    root = folder / "results"
    written = {}
    for subject, times, seed in (("01", 1, 11), ("02", 2, 12)):
        written[subject, "motion"] = motion_run(root, subject, 60.0 * times, seed)
        written[subject, "detection"] = detection_run(root, subject, 6.0 * times, seed)
    printed = io.StringIO()
    # Subject 01's tracks and fitted functions drawn and written (each kind, each task); subject
    # 02's, the same functions on the same design, only kept, as the detection and motion
    # tasks' own are (their rooms', drawn in tests/analysis/test_report.py), for the page to
    # link: drawing is most of analyse's time (about 0.6 s of processor a figure).
    with pytest.MonkeyPatch.context() as monkeypatch, contextlib.redirect_stdout(printed):
        figures = keep_figures(monkeypatch, draw=lambda name: name.startswith(
            ("track_sub-01_", "fit_sub-01_")))
        assert analyse(str(root), "--out", str(folder / "analysis")) == 0
    return Analysed(folder / "analysis", printed.getvalue(), written, figures)


def threshold(row):
    return float(row["threshold"])


def test_a_subject_with_twice_the_threshold_gets_about_twice_the_fitted_and_procedure_estimates(
        analysed):
    for task in ("motion", "detection"):
        first, second = (threshold(analysed.one(subject=s, task=task, procedure="pooled"))
                         for s in ("01", "02"))
        assert RATIO[0] < second / first < RATIO[1], (task, first, second)
    staircases = [sum(threshold(r) for r in analysed.rows(subject=s, method="reversal_mean"))
                  for s in ("01", "02")]
    assert RATIO[0] < staircases[1] / staircases[0] < RATIO[1], staircases
    quest = [threshold(analysed.one(subject=s, method="questplus_posterior")) for s in ("01", "02")]
    assert RATIO[0] < quest[1] / quest[0] < RATIO[1], quest


def test_thresholds_csv_has_the_columns_and_a_row_per_procedure_fit_and_across_subject_mean(
        analysed):
    with open(analysed.out / "thresholds.csv", newline="") as handle:
        assert next(csv.reader(handle)) == COLUMNS
    rows = analysed.rows()
    per_subject = Counter((r["subject"], r["task"], r["method"]) for r in rows)
    for subject in ("01", "02"):
        assert per_subject[subject, "motion", "reversal_mean"] == 2  # ascending, descending
        assert per_subject[subject, "motion", "bayes_weibull"] == 1
        assert per_subject[subject, "detection", "questplus_posterior"] == 1
        assert per_subject[subject, "detection", "bayes_weibull"] == 1
    across = [r for r in rows if r["subject"] == "all"]
    assert sorted((r["task"], r["method"], r["procedure"]) for r in across) == [
        ("detection", "bayes_weibull", "pooled"), ("detection", "questplus_posterior", "quest"),
        ("motion", "bayes_weibull", "pooled"), ("motion", "reversal_mean", "ascending"),
        ("motion", "reversal_mean", "descending")]
    assert len(rows) == 2 * 5 + 5
    assert {(r["parameter"], r["unit"]) for r in rows if r["task"] == "motion"} == {("soa", "ms")}
    assert {(r["parameter"], r["unit"]) for r in rows if r["task"] == "detection"} == {
        ("stroke", "steps")}
    for m in across:  # the subject is the unit: the plain mean of the two subjects' thresholds
        same = [threshold(r) for r in rows if r["subject"] != "all" and all(
            r[k] == m[k] for k in ("task", "method", "procedure"))]
        assert threshold(m) == pytest.approx(sum(same) / 2, abs=1e-3)
        # Two subjects: every bootstrap mean lies between them, and both ends are reached.
        assert (float(m["ci_low"]), float(m["ci_high"])) == pytest.approx(
            (min(same), max(same)), abs=1e-3)
        assert m["n_trials"] == str(sum(int(r["n_trials"]) for r in rows if r["subject"] != "all"
                                        and r["task"] == m["task"]
                                        and r["procedure"] == m["procedure"]))


def test_each_procedure_gives_the_estimate_of_its_last_counted_row(analysed):
    for subject in ("01", "02"):
        motion = analysed.written[subject, "motion"]
        for name, estimate in motion.estimates.items():
            row = analysed.one(subject=subject, task="motion", procedure=name)
            assert row["method"] == "reversal_mean"
            assert threshold(row) == pytest.approx(estimate, abs=5e-4)
            assert (row["ci_low"], row["ci_high"]) == ("n/a", "n/a")
            # Practice, catch and invalid rows move no staircase: 100 trials each, as its rule.
            assert row["n_trials"] == "100"
        mean, low, high = analysed.written[subject, "detection"].estimates["quest"]
        row = analysed.one(subject=subject, task="detection", procedure="quest")
        assert row["method"] == "questplus_posterior"
        assert [float(row[k]) for k in ("threshold", "ci_low", "ci_high")] == pytest.approx(
            [mean, low, high], abs=5e-4)


def test_the_fit_pools_every_counted_trial_of_the_task_and_is_the_same_on_every_run(analysed):
    rows = [r for r in analysed.written["02", "motion"].rows
            if r.status == "ok" and not r.practice and r.adaptive.procedure != "catch"]
    counts = Counter((r.adaptive.intensity, r.adaptive.correct) for r in rows)
    intensities = sorted({x for x, _ in counts})
    fit = threshold_posterior("weibull", intensities, [counts[x, True] for x in intensities],
                              [counts[x, True] + counts[x, False] for x in intensities], guess=0.5)
    row = analysed.one(subject="02", task="motion", procedure="pooled")
    assert row["n_trials"] == "200"
    assert [float(row[k]) for k in ("threshold", "ci_low", "ci_high")] == pytest.approx(
        [fit.threshold, fit.ci_low, fit.ci_high], abs=5e-4)
    assert row["status"] == "estimated"
    assert float(row["lapse_rate"]) == pytest.approx(fit.lapse, abs=5e-4)
    # The Weibull's threshold: 63.2 % of its way from the guess rate to 1 - lapse rate.
    assert float(row["pct_correct_at_threshold"]) == pytest.approx(
        100 * (0.5 + (0.5 - fit.lapse) * (1 - 1 / 2.718281828459045)), abs=0.05)


def test_the_sidecar_describes_every_column_and_defines_the_fit_s_threshold(analysed):
    sidecar = json.loads((analysed.out / "thresholds.json").read_text())
    assert list(sidecar) == COLUMNS
    definition = sidecar["threshold"]["Description"]
    assert "63.2 %" in definition and "guess rate (0.5" in definition and "guess rate (0," \
        in definition  # the motion task's 2AFC and the detection task's guess rates
    assert "81.6 % correct at a lapse rate of 0" in definition
    method = sidecar["method"]["Levels"]["bayes_weibull"]
    assert "credible interval" in method and "simulated subjects" in method
    assert set(sidecar["status"]["Levels"]) >= {"estimated", "below the lowest value tested",
                                                "above the highest value tested", "not estimable"}


def test_the_tracks_and_fitted_functions_are_drawn_and_the_summary_shows_and_links_them(
        analysed):
    page = (analysed.out / "summary.md").read_text()
    assert "## Thresholds (adaptive procedures)" in page
    assert "subject `all` in thresholds.csv" in page and "(thresholds.csv)" in page
    assert "| motion | soa | ms | `bayes_weibull` | pooled | 2 | 400 |" in page
    for subject in ("01", "02"):
        for task, parameter in (("motion", "soa"), ("detection", "stroke")):
            for kind in ("track", "fit"):
                stem = f"{kind}_sub-{subject}_task-{task}_{parameter}"
                assert stem in analysed.figures  # made and handed to `save`, which writes:
                if subject == "01":
                    png = (analysed.out / f"{stem}.png").read_bytes()
                    assert png[:8] == b"\x89PNG\r\n\x1a\n"
                    assert (analysed.out / f"{stem}.pdf").read_bytes()[:5] == b"%PDF-"
                assert f"![{stem}]({stem}.png)" in page
    assert "thresholds, mean of per-subject thresholds" in analysed.printed
    assert "motion soa_ms bayes_weibull (pooled)" in analysed.printed
    # The method and its measured coverage, and the threshold's definition, are named.
    assert "Bayesian Weibull fit" in page and "simulated subjects" in page
    assert "63.2 %" in page and "(thresholds.json)" in page


# A fixed design's analysis writes no thresholds: tests/analysis/test_report.py, on the analysis
# of its fixed-design results that it makes once for all its tests.


def staircase_row(trial, intensity, correct, estimate=None, guess=0.5, **fields):
    return motion_row(trial, AdaptiveCells("only", "soa_ms", intensity, guess, correct, False,
                                            estimate), correct, **fields)


def test_a_staircase_without_reversals_and_a_single_intensity_give_n_a_not_a_number(
        tmp_path, write_run):
    root = tmp_path / "results"
    write_run(root, "01", "motion", [staircase_row(n, 50.0, True) for n in (1, 2, 3)])
    out = tmp_path / "analysis"
    with contextlib.redirect_stdout(io.StringIO()):
        assert analyse(str(root), "--out", str(out), "--no-figures") == 0
    rows = read_csv(out / "thresholds.csv")
    by_method = {(r["subject"], r["method"]): r for r in rows}
    assert by_method["01", "reversal_mean"]["threshold"] == "n/a"
    assert by_method["01", "bayes_weibull"]["threshold"] == "n/a"
    assert by_method["01", "bayes_weibull"]["n_trials"] == "3"
    assert "no fit: answers at 1 intensity" in (out / "summary.md").read_text()
    # No subject has an estimate: the across-subject rows say so with n/a, never nan.
    assert all(r["threshold"] == "n/a" for r in rows if r["subject"] == "all")
    assert not any("nan" in cell for r in rows for cell in r.values())


def test_rows_of_one_task_that_disagree_on_the_guess_rate_are_one_line_error_with_status_2(
        tmp_path, write_run, capsys):
    root = tmp_path / "results"
    write_run(root, "01", "motion", [staircase_row(1, 50.0, True),
                                     staircase_row(2, 60.0, True, guess=0.25)])
    assert cli.main(["analyse", str(root), "--out", str(tmp_path / "analysis")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "expected one guess_rate for task motion (soa_ms) of subject 01, found 0.25, 0.5" \
        in err


def test_answers_that_cannot_place_the_threshold_give_words_not_a_zero_width_interval(
        tmp_path, write_run):
    # Subject 01 answers every trial right, subject 02 every trial wrong; the tables and the
    # page are written without figures (drawing them is the slow part of analyse).
    root = tmp_path / "results"
    soas = (40.0, 80.0, 120.0, 160.0)
    for subject, right in (("01", True), ("02", False)):
        write_run(root, subject, "motion", [staircase_row(n, soas[n % 4], right)
                                            for n in range(1, 41)])
    found = study(select_runs(load_runs([root])))
    out = tmp_path / "analysis"
    out.mkdir()
    tables = write_tables(found.thresholds, found.runs, out)
    rows = read_csv(out / "thresholds.csv")
    fits = {r["subject"]: r for r in rows if r["procedure"] == "pooled"}
    assert (fits["01"]["status"], fits["02"]["status"]) == (
        "below the lowest value tested", "above the highest value tested")
    assert fits["01"]["threshold"] == fits["02"]["threshold"] == "n/a"
    # The one bound the answers give, near the end of the tested range the words name.
    assert fits["01"]["ci_low"] == "n/a" and float(fits["01"]["ci_high"]) < 80.0
    assert fits["02"]["ci_high"] == "n/a" and float(fits["02"]["ci_low"]) > 120.0
    # Left out of the across-subject mean: no subject has a threshold.
    assert fits["all"]["threshold"] == "n/a"
    page = summary_markdown(found, tables, [])
    assert "subject 01, task motion: threshold **below the lowest value tested** (below" in page
    assert "subject 02, task motion: threshold **above the highest value tested** (above" in page


@pytest.mark.parametrize(("adapted", "parameter", "unit"), [
    ("soa_ms", "soa", "ms"), ("stroke_steps", "stroke", "steps"), ("stroke_us", "stroke", "us"),
    ("frequency_hz", "frequency", "Hz"), ("duration_ms", "duration", "ms"),
    ("pulse_width_us", "pulse_width", "us"), ("amplitude", "amplitude", "n/a"),
])
def test_the_unit_is_the_adapted_parameters_suffix(adapted, parameter, unit):
    assert parameter_and_unit(adapted) == (parameter, unit)

