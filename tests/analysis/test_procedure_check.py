"""Checking a protocol's procedures on simulated subjects before running people."""

from pathlib import Path

import pytest

from pinarray.adaptive.psychometric import Psychometric
from pinarray.analysis.procedure_check import check_procedures, target_probability
from pinarray.cli import main
from pinarray.protocol.load import load_protocol
from tests.commands import pinarray_here

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"


def test_a_one_up_two_down_staircase_aims_at_seventy_point_seven_percent_correct():
    adaptive = load_protocol(PROTOCOLS / "staircase_motion.yaml").design.adaptive
    assert [target_probability(p) for p in adaptive.procedures] == \
        [pytest.approx(0.5 ** 0.5)] * 2


# Subjects per check: over seeds 0-19, QUEST+'s ratio of the two means fell within 1.919-2.018
# with 30 subjects (1.932-2.006 with 60) and its largest bias took 0.24 of the bound below
# (0.20 with 60); the staircases' ratio fell within 1.727-2.148 with 30 subjects, too near
# the tolerance's 1.7, so they keep 60.
@pytest.mark.parametrize(("name", "subjects"), [("quest_stroke.yaml", 30),
                                                ("staircase_motion.yaml", 60)])
def test_doubling_the_simulated_threshold_doubles_the_mean_estimate(name, subjects):
    adaptive = load_protocol(PROTOCOLS / name).design.adaptive
    low = float(adaptive.values[len(adaptive.values) // 4])
    means = []
    for threshold in (low, 2 * low):
        function = Psychometric("weibull", threshold, 3.0, float(adaptive.guess_rate), 0.02)
        checks = check_procedures(adaptive, function, subjects, seed=3)
        means.append([c.bias + c.truth for c in checks])
        for check in checks:
            # Unbiased within what the subjects can tell: 4 standard errors, plus one value's
            # step.
            step = float(adaptive.values[1] - adaptive.values[0])
            assert abs(check.bias) < 4 * check.sd / subjects ** 0.5 + step, check.name
            assert max(check.trials) <= next(p.stop_after_trials for p in adaptive.procedures
                                              if p.name == check.name)
    for before, after in zip(*means, strict=True):
        assert after / before == pytest.approx(2, rel=0.15)


def test_power_on_an_adaptive_protocol_prints_each_procedures_bias_and_writes_a_table(tmp_path):
    done = pinarray_here("power", PROTOCOLS / "quest_stroke.yaml", "--studies", "20",
                         "--observer", "threshold=40", "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "each run by 20 simulated subjects" in done.stdout
    assert any(line.startswith("quest ") for line in done.stdout.splitlines())
    rows = (tmp_path / "procedure_check.csv").read_text().splitlines()
    assert rows[0].startswith("procedure,truth,truth_is,unit,bias") and len(rows) == 2


def test_power_refuses_an_observer_key_an_adaptive_design_does_not_have(tmp_path):
    done = pinarray_here("power", PROTOCOLS / "quest_stroke.yaml", "--observer",
                         "correct_5hz=0.5", "--out", tmp_path)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "unknown parameter 'correct_5hz'" in done.stderr


def test_power_refuses_procedures_that_would_run_for_hours_with_the_estimate_and_what_to_change(
        tmp_path, capsys):
    # One QUEST+ of 1 200 000 points (inside the grid limit) to 2000 trials, for 100 subjects.
    text = (PROTOCOLS / "quest_stroke.yaml").read_text()
    text = text.replace("threshold_prior: {mean: 40, sd: 30} # in steps: a broad guess",
                        "thresholds: {from: 1, to: 1000, step: 1}").replace(
        "slopes: [1, 1.5, 2, 3, 4, 6]", "slopes: [1, 1.5, 2, 3, 4, 5, 6, 7, 8, 9]").replace(
        "lapse_rates: [0, 0.02, 0.05]", "lapse_rates: [0, 0.01, 0.02, 0.05]").replace(
        "stop_after_trials: 60", "stop_after_trials: 2000")
    path = tmp_path / "big.yaml"
    path.write_text(text)
    status = main(["power", str(path), "--studies", "100", "--out", str(tmp_path / "power")])
    out, err = capsys.readouterr()
    assert (status, out) == (2, "")
    assert err.startswith("pinarray: power: 100 simulated subjects (--studies) running 1 "
                          "procedure(s) to their trial limits would take about 1 h; at most 30 min")
    assert "at most 30 min: fewer --studies, or a design with smaller QUEST+ grids" in err
    assert not (tmp_path / "power").exists()


def test_a_design_whose_quest_grids_add_up_past_the_limit_is_refused_where_its_procedures_are(
        tmp_path):
    from pinarray.errors import ProtocolErrors
    from pinarray.protocol.load import load_protocol

    quest = ("        method: quest_plus\n        thresholds: {from: 1, to: 1000, step: 1}\n"
             "        slopes: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n"
             "        lapse_rates: [0, 0.01, 0.02, 0.05]\n        stop_after_trials: 60\n")
    text = (PROTOCOLS / "quest_stroke.yaml").read_text()
    start, end = text.index("      quest:\n"), text.index("  inter_trial_interval_s")
    path = tmp_path / "sixteen.yaml"
    path.write_text(text[:start] + "".join(f"      q{i}:\n{quest}" for i in range(16))
                    + text[end:])
    with pytest.raises(ProtocolErrors) as refused:
        load_protocol(path)
    (error,) = refused.value.errors
    assert error.message == ("expected QUEST+ grids of at most 4,000,000 points in all (values x "
                             "thresholds x slopes x lapse rates, summed over the procedures), "
                             "found 19,200,000")
    assert error.line == text[:start].count("\n") + 1  # the first of them
