"""Two-point discrimination (`pinarray.paradigms.two_point`), the paradigm added through the
seam alone: its design read and checked where it is written, distances from the grid's pitch,
the intensity cue warned of, a batch run with its simulated subject, every row read back
checked, and the threshold distance fitted (or said in words where the answers cannot place
it)."""

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.analysis.load import LoadedTrial, RunSelection, load_runs
from pinarray.analysis.seam import Context, EstimateStatus
from pinarray.analysis.subjects import IntervalSettings
from pinarray.analysis.thresholds import NotFitted
from pinarray.cli import main
from pinarray.cli.answer_sheets import check_answers, parse_answers
from pinarray.errors import ProtocolErrors, ResultsError
from pinarray.grid import Grid
from pinarray.journal.rows import read_trials
from pinarray.paradigms.two_point.analysis import two_points
from pinarray.paradigms.two_point.design import TwoPointCondition, distance_mm
from pinarray.paradigms.two_point.observer import TwoPointObserver, TwoPointObserverModel
from pinarray.paradigms.two_point.rows import TwoPointRecord
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol, parse_protocol, protocol_warnings
from tests.lab_protocols import short_copy

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
TWO_POINT = PROTOCOLS / "two_point.yaml"
CONTEXT = Context(RunSelection((), (), False), IntervalSettings(), Grid())


def designed(design: str, pitch: float = 2) -> str:
    return f"""\
protocol: tp
device:
  grid: {{rows: 4, columns: 4, pitch_mm: {pitch}}}
stimuli:
  press: {{frequency_hz: 1, duration_s: 1}}
  firm: {{frequency_hz: 1, duration_s: 1}}
  shape: {{pattern: [6, 7], train: press}}
design:
  paradigm: two_point
{design}"""


def problems(text: str) -> list[str]:
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "p.yaml")
    return [p.located() for p in raised.value.errors]


def test_the_shipped_protocol_pairs_pins_at_six_distances_against_one_pin_at_three_strokes():
    protocol = load_protocol(TWO_POINT)
    conditions = protocol.design.conditions
    pairs = [c for c in conditions if c.count == 2]
    assert [c.distance_mm for c in pairs] == [2, 2.8284, 4, 4.4721, 5.6569, 6]
    assert {c.stimulus for c in pairs} == {"press"}
    singles = [(c.stimulus, c.pins) for c in conditions if c.count == 1]
    assert sorted(singles) == sorted((s, (p,)) for s in ("press_light", "press", "press_deep")
                                     for p in (6, 7))
    assert protocol.design.answers(16) == ("one", "two")
    assert protocol_warnings(protocol) == []  # the single pin's stroke roves: no warning


@given(pitch=st.floats(0.5, 10), a=st.integers(1, 16), b=st.integers(1, 16))
def test_a_pairs_distance_is_the_grids_pitch_times_how_far_apart_its_cells_are(pitch, a, b):
    grid = Grid(4, 4, pitch)
    (ra, ca), (rb, cb) = grid.cell(a), grid.cell(b)
    assert distance_mm(grid, a, b) == pytest.approx(pitch * math.hypot(ra - rb, ca - cb),
                                                    abs=1e-4)
    assert distance_mm(grid, a, b) == distance_mm(grid, b, a)


def test_the_distances_follow_the_protocols_pitch_and_one_pin_trials_default_to_the_pairs_pins():
    protocol = parse_protocol(designed("  stimulus: press\n  pairs: [[1, 2], [1, 6]]\n", 1.5),
                              "p.yaml")
    by_pins = {c.pins: c.distance_mm for c in protocol.design.conditions}
    assert by_pins == {(1, 2): 1.5, (1, 6): 2.1213, (1,): 0, (2,): 0, (6,): 0}


def test_one_train_for_one_pin_and_two_is_warned_of_as_an_intensity_cue():
    protocol = parse_protocol(designed("  stimulus: press\n  pairs: [[6, 7]]\n"), "p.yaml")
    (warning,) = protocol_warnings(protocol)
    assert warning.startswith("two pins press with about twice the force of one")
    roving = parse_protocol(designed("  stimulus: press\n  pairs: [[6, 7]]\n"
                                     "  single_stimuli: [press, firm]\n"), "p.yaml")
    assert protocol_warnings(roving) == []


def test_every_problem_of_the_design_is_said_where_it_is_written():
    found = problems(designed("  stimulus: press\n  pairs: [[6, 7], [7, 6], [6, 17], [3, 3], "
                              "[1, 2, 3]]\n  single_stimuli: [firm, shape, nothing]\n"))
    assert found == [
        "p.yaml:11:19: expected each pair once, found pins 6 and 7 again",
        "p.yaml:11:31: expected a pin from 1 to 16 on the 4x4 grid, found 17",
        "p.yaml:11:36: expected two different pins, found [3, 3]",
        "p.yaml:11:44: expected two different pins, found [1, 2, 3]",
        "p.yaml:12:26: expected the name of a pulse train, found 'shape'; the stimuli section "
        "has firm, press",
        "p.yaml:12:33: expected the name of a pulse train, found 'nothing'; the stimuli section "
        "has firm, press"]
    assert problems(designed("  stimulus: press\n"))[0] == (
        "p.yaml:9:3: expected a 'pairs' key in a two_point design, found none")


def test_every_pair_is_checked_against_the_servo_bus_where_it_is_written():
    text = designed("  stimulus: press\n  pairs: [[6, 7]]\n").replace(
        "device:\n", "device:\n  delivery_tolerance_ms: 0.12\n")
    # One goal a frame (0.11 ms on the wire) is in time; the two of a pair are not.
    found = problems(text)
    assert "p.yaml:12:11: pins 6 and 7 (2 mm apart): the servo bus cannot deliver it: a frame " \
           "of 2 goal(s)" in "\n".join(found)
    assert not any(": pin 6 alone" in line or ": pin 7 alone" in line for line in found)


def test_a_batch_run_is_analysed_into_a_threshold_in_mm(tmp_path, capsys):
    results, out = tmp_path / "results", tmp_path / "analysis"
    assert main(["batch", str(TWO_POINT), "--subject", "01", "--observer", "default",
                 "--seed", "1", "--results", str(results)]) == 0
    rows = read_trials(next(results.rglob("*_beh.tsv")))
    assert len(rows) == 124 and all(isinstance(r, TwoPointRecord) for r in rows)
    assert {r.distance_mm for r in rows} == {0, 2, 2.8284, 4, 4.4721, 5.6569, 6}
    assert main(["analyse", str(results), "--out", str(out), "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert "120 two-point trials" in printed and "mean threshold_mm" in printed
    (row,) = [r for r in (out / "two_point.csv").read_text().splitlines()[1:]
              if r.startswith("01,")]
    cells = row.split(",")
    assert cells[5] == "estimated" and 2 < float(cells[2]) < 6
    assert float(cells[3]) < float(cells[2]) < float(cells[4])
    assert "two_point,twopoint,01,threshold_mm,mm," in (out / "estimates.csv").read_text()


def _rows(model: TwoPointObserverModel, repetitions: int, seed: int = 0):
    """A subject of ``model`` answering ``repetitions`` trials at each distance and as many
    one-pin trials."""
    subject = TwoPointObserver(model, seed)
    rows, trial = [], 0
    for pins, distance in (((6,), 0.0), ((6, 7), 2.0), ((6, 11), 2.8284), ((6, 8), 4.0),
                           ((1, 11), 5.6569), ((5, 8), 6.0)):
        for _ in range(repetitions):
            trial += 1
            said = subject(TwoPointCondition("press", pins, distance))
            rows.append(LoadedTrial("01", "1", 1, None, TwoPointRecord(
                trial=trial, block=1, task="tp", onset_ns=0, duration_ns=1, stimulus="press",
                pins=pins, distance_mm=distance, response=said)))
    return rows


def shipped_rows(model: TwoPointObserverModel, seed: int):
    """A subject of ``model`` (seeded ``seed``) answering protocols/two_point.yaml's main
    trials as planned with that seed."""
    subject = TwoPointObserver(model, seed)
    return [LoadedTrial("01", "1", 1, None, TwoPointRecord(
        trial=t.trial, block=1, task="tp", onset_ns=0, duration_ns=1,
        stimulus=t.condition.stimulus, pins=t.condition.pins,
        distance_mm=t.condition.distance_mm, response=subject(t.condition)))
        for t in make_plan(shipped(), seed).trials if not t.practice]


@functools.cache
def shipped():
    """protocols/two_point.yaml, read once by the first test that asks (not as every test
    process collects this file)."""
    return load_protocol(TWO_POINT)


def test_the_fit_finds_the_threshold_distance_subjects_were_given():
    # 40 subjects of the shipped design, thresholds 2-5 mm, false alarms 0-15 %, lapse rates
    # 0-4 %: the 95 % credible intervals hold the truth for most (300 such: 94.3 %, the
    # coverage the method's words state).
    rng = np.random.default_rng(1)
    held, placed = 0, 0
    for seed in range(40):
        model = TwoPointObserverModel(threshold_mm=float(rng.uniform(2, 5)),
                                      false_alarm=float(rng.uniform(0, 0.15)),
                                      lapse=float(rng.uniform(0, 0.04)), subject_sd=0)
        (fit,) = two_points(shipped_rows(model, seed), CONTEXT).fits
        if fit.threshold.status is EstimateStatus.ESTIMATED:
            placed += 1
            held += fit.threshold.ci_low < model.threshold_mm < fit.threshold.ci_high
        assert fit.false_alarm.status is EstimateStatus.ESTIMATED
    assert placed >= 38 and held >= 0.85 * placed


@pytest.mark.parametrize(("model", "status", "words"), [
    (TwoPointObserverModel(threshold_mm=0.5, false_alarm=0, lapse=0, subject_sd=0),
     EstimateStatus.BOUNDED, "below the lowest value tested"),
    (TwoPointObserverModel(threshold_mm=40, false_alarm=0, lapse=0, subject_sd=0),
     EstimateStatus.BOUNDED, "above the highest value tested"),
    (TwoPointObserverModel(false_alarm=0.95, lapse=0, subject_sd=0),
     EstimateStatus.NOT_RESOLVED, "not fitted"),
])
def test_answers_that_cannot_place_the_threshold_give_words_not_a_number(model, status, words):
    (fit,) = two_points(_rows(model, 20), CONTEXT).fits
    assert (fit.threshold.status, fit.threshold.words) == (status, words)
    assert math.isnan(fit.threshold.value)
    if words == "not fitted":
        assert isinstance(fit.fit, NotFitted) and "one-pin trials" in fit.fit.reason


def test_every_cell_read_back_is_checked_against_the_record_and_the_plan(tmp_path):
    results = tmp_path / "results"
    assert main(["batch", str(short_copy("two_point", tmp_path)), "--subject", "01",
                 "--observer", "default", "--seed", "2", "--results", str(results)]) == 0
    beh = next(results.rglob("*_beh.tsv"))
    lines = beh.read_text().splitlines()
    header = lines[0].split("\t")
    first = lines[1].split("\t")

    def refused(column, value, match):
        edited = list(first)
        edited[header.index(column)] = value
        beh.write_text("\n".join([lines[0], "\t".join(edited), *lines[2:]]) + "\n")
        with pytest.raises(ResultsError, match=match):
            load_runs([results])

    two = first[header.index("pins")].count(" ") == 1
    refused("response", "three", "a two-point response is one or two, found 'three'")
    refused("distance", "3" if two else "2", "mm")
    refused("correct", "false" if first[header.index("correct")] == "true" else "true",
            "correct")
    refused("pins", "1 2 3", "one pin or two different pins")


def test_an_answer_sheet_may_say_one_or_two_in_words_or_digits():
    protocol = load_protocol(TWO_POINT)
    plan = make_plan(protocol, 1)
    text = "trial,response\n" + "".join(f"{t.trial},{('1', 'Two', 'one', '2')[t.trial % 4]}\n"
                                        for t in plan.trials)
    answers = check_answers(parse_answers(text, "a.csv"), "a.csv", protocol)
    assert answers[1] == "two" and answers[2] == "one" and answers[4] == "one"


def test_the_simulated_subject_says_two_more_often_the_further_apart_the_pins():
    model = TwoPointObserverModel(subject_sd=0)
    p = [model.p_two(d) for d in (0, 1, 2, 3, 4, 6, 8)]
    assert p[0] == model.false_alarm and all(b > a for a, b in zip(p, p[1:], strict=False))
    assert p[-1] == pytest.approx(1 - model.lapse, abs=1e-3)
    cued = TwoPointObserverModel(intensity_cue=0.5, subject_sd=0)
    assert cued.p_two(0.5) > 0.5 > model.p_two(0.5)
    rng = np.random.default_rng(0)
    assert all(0 < m.p_two(2.0) < 1 for m in (model.individual(rng) for _ in range(50)))
