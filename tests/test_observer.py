"""The simulated subject: defaults that match the seed, and long-run rates that match the model."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.errors import PinArrayError
from pinarray.grid import classify
from pinarray.observer import ObserverModel, SimulatedObserver, parse_observer

DEFAULT = ObserverModel()


def within(observed_count, n, p, sigmas=4.5):
    """Whether a binomial count is within ``sigmas`` standard errors of n * p."""
    return abs(observed_count - n * p) <= sigmas * math.sqrt(n * p * (1 - p)) + 1


def test_the_defaults_give_the_seeds_62_5_percent_correct_at_10_hz():
    assert_allclose(DEFAULT.expected_localisation(10)["correct"], 0.625, atol=1e-9)


def test_the_defaults_localise_better_as_frequency_rises():
    correct = [DEFAULT.expected_localisation(f)["correct"] for f in (3, 4, 5, 7, 10)]
    assert correct == sorted(correct) and len(set(correct)) == 5


@pytest.mark.parametrize("frequency_hz", [3, 5, 10, 4, 7])
def test_error_a_is_the_most_frequent_error_at_every_frequency(frequency_hz):
    rates = DEFAULT.expected_localisation(frequency_hz)
    assert rates["A"] > max(rates["B"], rates["C"], rates["D"])


def test_pin_4_is_best_localised_and_edges_beat_the_centre():
    for frequency_hz in (3, 5, 10):
        accuracy = DEFAULT.expected_pin_accuracy(frequency_hz)  # row 0 = bottom row
        assert np.argmax(accuracy) == 3  # pin 4: bottom row, right column
        corners = [accuracy[0, 0], accuracy[3, 0], accuracy[3, 3]]
        edges = [accuracy[0, 1], accuracy[1, 0], accuracy[2, 3], accuracy[3, 2]]
        centre = [accuracy[1, 1], accuracy[1, 2], accuracy[2, 1], accuracy[2, 2]]
        assert min(corners) > max(edges) > max(centre)


def test_the_defaults_give_77_percent_motion_felt_and_65_percent_of_those_right():
    for direction in ("left", "right"):
        answers = DEFAULT.motion_probabilities(direction)
        felt = 1 - answers["none"]
        assert_allclose(felt, 0.77, atol=1e-12)
        assert_allclose(answers[direction] / felt, 0.65, atol=1e-12)


def test_long_run_localisation_rates_match_the_analytic_expectation():
    observer = SimulatedObserver(seed=20240501)
    pins = np.array(DEFAULT.pins)
    for frequency_hz in (3.0, 10.0):
        n = 16_000
        counts = dict.fromkeys(("correct", "A", "B", "C", "D"), 0)
        for stimulated in np.resize(pins, n):
            reported = observer.respond_localisation(int(stimulated), frequency_hz)
            counts[classify(int(stimulated), reported)] += 1
        expected = DEFAULT.expected_localisation(frequency_hz)
        for name, count in counts.items():
            assert within(count, n, expected[name]), (frequency_hz, name, count / n)


def test_long_run_answers_for_one_pin_match_its_probability_row():
    model = ObserverModel(miss_rate=0.1)
    observer = SimulatedObserver(model, seed=7)
    n = 20_000
    answers = [observer.respond_localisation(10, 5.0) for _ in range(n)]
    row = model.report_probabilities(5.0)[9]
    counts = np.bincount([a or 0 for a in answers], minlength=17)
    for answer, probability in enumerate(row):
        assert within(counts[answer], n, probability), (answer, counts[answer] / n)


def test_long_run_motion_answers_match_the_model_including_the_no_wave_trials():
    model = ObserverModel(no_wave_felt=0.4, unsure_given_felt=0.2)
    observer = SimulatedObserver(model, seed=3)
    n = 12_000
    for direction in ("left", "right", "none"):
        answers = [observer.respond_motion(direction) for _ in range(n)]
        for answer, probability in model.motion_probabilities(direction).items():
            assert within(answers.count(answer), n, probability), (direction, answer)


def test_the_same_seed_gives_the_same_subject():
    runs = [SimulatedObserver(seed=11) for _ in range(2)]
    trials = [(pin, f) for pin in (1, 4, 10, 16) for f in (3.0, 5.0, 10.0)] * 5
    first, second = ([o.respond_localisation(p, f) for p, f in trials] for o in runs)
    assert first == second
    assert len(set(first)) > 1


rising_anchors = st.lists(st.floats(0.1, 0.95), min_size=1, max_size=3, unique=True).map(
    lambda cs: tuple(zip((2.0, 6.0, 20.0), sorted(cs), strict=False))
)


@settings(max_examples=30, deadline=None)
@given(anchors=rising_anchors, miss_rate=st.floats(0.0, 0.04))
def test_any_rising_anchors_are_met_exactly_and_answers_are_a_distribution(anchors, miss_rate):
    model = ObserverModel(correct_by_frequency=anchors, miss_rate=miss_rate)
    for frequency_hz, fraction in anchors:
        rates = model.expected_localisation(frequency_hz)
        assert_allclose(rates["correct"], fraction, atol=1e-6)
        assert_allclose(sum(rates.values()), 1.0, atol=1e-9)
    probabilities = model.report_probabilities(4.0)
    assert (probabilities >= 0).all()
    assert_allclose(probabilities.sum(axis=1), 1.0, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(low=st.floats(0.5, 50), high=st.floats(0.5, 50))
def test_sigma_never_grows_with_frequency(low, high):
    low, high = sorted((low, high))
    assert DEFAULT.sigma(high) <= DEFAULT.sigma(low) * (1 + 1e-12)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"motion_felt": 1.2}, "motion_felt must be a fraction"),
        ({"direction_given_felt": 0.8, "unsure_given_felt": 0.3}, "at most 1"),
        ({"correct_by_frequency": ((3.0, 0.7), (10.0, 0.5))}, "rise with frequency"),
        ({"correct_by_frequency": ((10.0, 0.01),)}, "between chance"),
        ({"pin_acuity": ((17, 0.5),)}, "pin 17 is not on the 4x4 grid"),
    ],
)
def test_impossible_parameters_are_refused_with_the_reason(changes, message):
    with pytest.raises(PinArrayError, match=message):
        ObserverModel(**changes)


def test_a_model_can_be_written_on_the_command_line():
    model = parse_observer("motion_felt=0.9, correct_10hz=0.7,correct_20hz=0.8")
    assert model.motion_felt == 0.9
    assert dict(model.correct_by_frequency) == {3.0: 0.4, 5.0: 0.5, 10.0: 0.7, 20.0: 0.8}
    assert parse_observer("default") == DEFAULT
    with pytest.raises(PinArrayError, match="unknown parameter 'speed'"):
        parse_observer("speed=3")
    with pytest.raises(PinArrayError, match="name=number"):
        parse_observer("motion_felt=lots")


def test_an_off_grid_pin_or_unknown_direction_is_refused():
    observer = SimulatedObserver(seed=1)
    with pytest.raises(PinArrayError, match="pin 0"):
        observer.respond_localisation(0, 10.0)
    with pytest.raises(PinArrayError, match="up"):
        observer.respond_motion("up")
