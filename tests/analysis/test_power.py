"""`pinarray power`: how many subjects, from whole simulated studies analysed per subject."""

import csv
import re
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy import stats as scipy_stats

from pinarray import cli
from pinarray.analysis.power import caption, power_markdown, power_study, t_test_p
from pinarray.grid import DEFAULT_GRID
from pinarray.paradigms.apparent_motion.observer import MotionObserverModel
from pinarray.paradigms.apparent_motion.power import power as motion_power
from pinarray.paradigms.localisation.observer import ObserverModel
from pinarray.paradigms.localisation.power import (
    PAIRED_FREQUENCY,
    Design,
    SubjectCounts,
    analyse_study,
    power,
    protocol_design,
)
from pinarray.protocol.load import load_protocol

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
LOCALISATION = load_protocol(PROTOCOLS / "localisation.yaml")
MOTION = load_protocol(PROTOCOLS / "apparent_motion.yaml")
PINS = (1, 4)


def subject(correct_by_frequency, a_errors=1, pin_correct=(3, 1)):
    """A subject of 8 trials per frequency on pins 1 and 4: correct, A errors, the rest B."""
    rows = [[c, a_errors, 8 - c - a_errors, 0, 0, 0] for c in correct_by_frequency]
    pin_trials = np.zeros(16, dtype=int)
    pin_hits = np.zeros(16, dtype=int)
    pin_trials[[0, 3]] = 4 * len(correct_by_frequency)
    pin_hits[[0, 3]] = pin_correct
    return SubjectCounts(np.array(rows), pin_hits, pin_trials)


DESIGN = Design(tuple((p, f) for p in PINS for f in (3.0, 10.0)) * 4, DEFAULT_GRID)


def test_the_protocols_main_trials_are_what_the_simulated_subjects_answer():
    design = protocol_design(LOCALISATION)
    assert len(design.trials) == 24 and design.pins == (1, 4, 6, 7, 10, 11, 13, 16)
    assert design.frequencies_hz == (3.0, 5.0, 10.0)
    motion = motion_power(MOTION, MotionObserverModel())
    assert sorted(set(motion.trials)) == ["left", "none", "right"] and len(motion.trials) == 12


def test_a_study_where_every_subject_improves_finds_the_frequency_effect():
    found = analyse_study(DESIGN, [subject((2, 5)), subject((3, 6)), subject((1, 5)),
                                   subject((2, 7))], best_pin=1).found
    assert found[PAIRED_FREQUENCY] and found["rising means"]
    assert found["error A on top"] is False  # B errors outnumber A here
    assert found["pin 1 best"]


def test_a_study_where_half_improve_and_half_get_worse_finds_no_frequency_effect():
    found = analyse_study(DESIGN, [subject((2, 6)), subject((6, 2)), subject((3, 5)),
                                   subject((5, 3))], best_pin=4).found
    assert not found[PAIRED_FREQUENCY] and not found["rising means"]
    assert not found["pin 4 best"]


def test_a_tie_for_the_best_pin_does_not_count_as_that_pin_best():
    found = analyse_study(DESIGN, [subject((2, 5), pin_correct=(2, 2))] * 3, best_pin=4).found
    assert not found["pin 4 best"]


# No deadline: scipy's first call can take longer than Hypothesis's 200 ms on a loaded
# machine (it did, with numpy's AVX2 paths off), and timing belongs in benchmarks.
@settings(deadline=None)
@given(st.lists(st.floats(-100, 100, allow_nan=False), min_size=2, max_size=25))
def test_the_t_test_gives_scipys_p_value(values):
    if np.std(values) > 1e-9:
        # Where |mean| >> sd the two sds differ by about u |mean| / sd relative, which moves
        # p by about u * df * t^(1 - df) <= u absolute: atol 1e-12 covers it.
        assert_allclose(t_test_p(values), scipy_stats.ttest_1samp(values, 0.0).pvalue,
                        rtol=1e-6, atol=1e-12)


def test_power_grows_with_subjects_and_the_simulation_repeats_with_its_seed():
    model = power(LOCALISATION, ObserverModel().for_protocol(LOCALISATION))
    curves = power_study("localisation", model, [4, 16], studies=40, seed=3)
    effect = {p.subjects: p.met.pct for p in curves.points if p.criterion == PAIRED_FREQUENCY}
    assert effect[16] > effect[4]
    again = power_study("localisation", model, [4, 16], studies=40, seed=3)
    assert again.points == curves.points
    ten = {p.subjects: p for p in curves.precision if p.measure == "correct at 10 Hz"}
    assert ten[16].t_half_width_pct < ten[4].t_half_width_pct
    assert abs(ten[16].mean_pct - 62.5) < 4 * ten[16].sd_pct / np.sqrt(40)


def test_more_spread_between_subjects_makes_a_studys_estimate_vary_more():
    narrow = power_study("localisation", power(LOCALISATION, ObserverModel(
        subject_sd_logit=0).for_protocol(LOCALISATION)), [8], studies=60, seed=4)
    wide = power_study("localisation", power(LOCALISATION, ObserverModel(
        subject_sd_logit=2).for_protocol(LOCALISATION)), [8], studies=60, seed=4)
    width = {c.model.subject_sd: next(p.sd_pct for p in c.precision
                                      if p.measure == "correct at 10 Hz")
             for c in (narrow, wide)}
    assert width[2.0] > 1.5 * width[0.0]


def test_the_power_command_prints_the_table_and_writes_csv_and_figures(tmp_path, capsys):
    out = tmp_path / "power"
    status = cli.main(["power", str(PROTOCOLS / "apparent_motion.yaml"), "--subjects", "4,8",
                       "--studies", "20", "--seed", "5", "--out", str(out)])
    assert status == 0
    printed = capsys.readouterr().out
    assert "direction above chance" in printed and "motion felt more on waves" in printed
    with open(out / "power.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert {(r["criterion"], r["subjects"]) for r in rows} == {
        (c, n) for c in ("direction above chance", "motion felt more on waves")
        for n in ("4", "8")}
    assert all(r["seed"] == "5" and r["studies"] == "20" for r in rows)
    assert (out / "power_curves.png").exists() and (out / "power_curves.pdf").exists()
    assert (out / "precision.csv").exists()


def small_localisation_study():
    return power_study("localisation", power(LOCALISATION,
                                             ObserverModel().for_protocol(LOCALISATION)),
                       [4], studies=10, seed=2)


def test_power_does_not_call_its_paired_t_test_the_frequency_effect_analyse_fits():
    # `pinarray analyse` reports "frequency effect" from a mixed-effects logistic regression;
    # a reader of both outputs must not take power's paired t-test for it.
    curves = small_localisation_study()
    assert PAIRED_FREQUENCY in curves.criteria
    assert [c for c in curves.criteria if "frequency effect" in c] == []
    page = power_markdown(curves, "power_curves.png")
    assert f"- **{PAIRED_FREQUENCY}** (test): paired t-test" in page
    assert "mixed-effects logistic regression" in page


def test_the_caption_calls_only_the_tests_tests_and_the_pin_best_a_descriptive_finding():
    curves = small_localisation_study()
    text = caption(curves)
    tests = re.search(r"Tests, two-sided at p < 0.05 with subjects as the unit: ([^.]*)\.", text)
    descriptive = re.search(r"Descriptive findings, not tests[^:]*: ([^.]*)\.", text)
    assert tests and descriptive, text
    assert tests.group(1).split("; ") == [PAIRED_FREQUENCY]
    assert descriptive.group(1).split("; ") == ["rising means", "error A on top", "pin 4 best"]
    assert "tests are two-sided" not in text


# -- the work, not only each input, is bounded -------------------------------------------------

MAXIMA = ",".join(str(1000 - k) for k in range(20))


def run_power(capsys, *argv):
    status = cli.main(["power", *map(str, argv)])
    out, err = capsys.readouterr()
    return status, out, err


def test_studies_and_subjects_each_within_their_limits_but_days_of_work_together_are_refused(
        tmp_path, capsys):
    status, out, err = run_power(capsys, PROTOCOLS / "localisation.yaml", "--studies", 10_000,
                                 "--subjects", MAXIMA, "--out", tmp_path / "power")
    assert (status, out) == (2, "")
    assert err.count("\n") == 1 and err.startswith(
        "pinarray: power: 10,000 studies for each of 20 numbers of subjects (19,810 simulated "
        "subjects a round) would take about ")
    assert err.endswith("; at most 30 min: fewer --studies, fewer or smaller --subjects\n")
    assert list(tmp_path.iterdir()) == []


def test_power_refuses_an_out_it_could_not_write_before_simulating_anything(tmp_path, capsys):
    (tmp_path / "power").write_text("a file where the folder should be")
    status, out, err = run_power(capsys, PROTOCOLS / "apparent_motion.yaml", "--studies", 10,
                                 "--subjects", 2, "--out", tmp_path / "power")
    assert (status, out) == (2, "")  # nothing simulated, nothing printed
    assert err == f"pinarray: {tmp_path / 'power'}: cannot write there: it is a file, expected a folder\n"


def test_power_hears_of_each_study_by_the_simulated_subjects_done():
    heard = []
    model = motion_power(MOTION, MotionObserverModel())
    power_study("apparent_motion", model, [2, 3], 10, seed=1, progress=heard.append)
    assert heard == [2 * k for k in range(1, 11)] + [20 + 3 * k for k in range(1, 11)]


def test_power_that_may_take_a_while_says_how_far_it_is(tmp_path, capsys, monkeypatch):
    from pinarray.cli import common

    monkeypatch.setattr(common, "PROGRESS_AFTER_S", 0.0)  # an adaptive design: no figures
    status, out, err = run_power(capsys, PROTOCOLS / "staircase_motion.yaml", "--studies", 10,
                                 "--out", tmp_path / "power")
    assert status == 0
    lines = [line for line in err.splitlines() if line.startswith("power: simulated subjects: ")]
    assert lines[0].startswith("power: simulated subjects: 1 of 10 (10 %), about ")
    assert lines[-1] == "power: simulated subjects: 10 of 10 (100 %)" and len(lines) == 10
