"""Psychometric functions and the simulated subject who answers from one."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric, probability_correct
from pinarray.errors import PinArrayError


def test_a_weibull_has_risen_1_minus_1_over_e_of_the_way_at_its_threshold():
    weibull = Psychometric("weibull", threshold=40.0, slope=3.5, guess=0.5, lapse=0.04)
    expected = 0.5 + (1 - 0.5 - 0.04) * (1 - math.exp(-1))
    assert float(weibull.probability(40.0)) == pytest.approx(expected, rel=1e-15)
    assert weibull.probability([0.0, -3.0]).tolist() == [0.5, 0.5]
    assert float(weibull.probability(1e6)) == pytest.approx(0.96, rel=1e-15)


def test_a_logistic_is_half_way_at_its_threshold():
    logistic = Psychometric("logistic", threshold=-2.0, slope=0.5, guess=0.0, lapse=0.1)
    assert float(logistic.probability(-2.0)) == pytest.approx(0.45, rel=1e-15)
    assert float(logistic.probability(1.0)) == pytest.approx(0.9 / (1 + math.exp(-1.5)), rel=1e-14)
    assert float(logistic.probability(-1e6)) == 0.0


def test_probabilities_keep_the_shape_of_the_intensities():
    weibull = Psychometric("weibull", 2.0, 3.0, 0.5, 0.0)
    assert weibull.probability(np.ones((3, 4))).shape == (3, 4)
    assert weibull.probability(2.0).dtype == np.float64


@given(kind=st.sampled_from(["weibull", "logistic"]), threshold=st.floats(0.1, 100.0),
       slope=st.floats(0.2, 10.0), guess=st.floats(0.0, 0.5), lapse=st.floats(0.0, 0.1),
       share=st.floats(0.01, 0.99))
def test_intensity_for_inverts_probability(kind, threshold, slope, guess, lapse, share):
    function = Psychometric(kind, threshold, slope, guess, lapse)
    p = guess + share * (1 - guess - lapse)
    # Inverting and applying again loses a few ulps of p, amplified where the function is flat.
    assert float(function.probability(function.intensity_for(p))) == pytest.approx(p, abs=1e-9)


@pytest.mark.parametrize(("parameters", "message"), [
    (("weibull", 0.0, 1.0, 0.5, 0.0), "Weibull threshold must be above 0, found 0.0"),
    (("logistic", 1.0, -1.0, 0.5, 0.0), "slope must be above 0, found -1.0"),
    (("logistic", 1.0, 1.0, 0.6, 0.4), "guess \\+ lapse below 1, found guess 0.6, lapse 0.4"),
    (("logistic", float("nan"), 1.0, 0.5, 0.0), "must be finite numbers"),
    (("cumulative normal", 1.0, 1.0, 0.5, 0.0), "weibull or logistic, found 'cumulative normal'"),
])
def test_an_impossible_function_is_refused_saying_what_was_found(parameters, message):
    with pytest.raises(PinArrayError, match=message):
        Psychometric(*parameters)


def test_a_probability_the_function_never_reaches_has_no_intensity():
    with pytest.raises(PinArrayError, match="between 0.5 and 0.98 \\(exclusive\\), asked for 0.99"):
        Psychometric("weibull", 1.0, 2.0, 0.5, 0.02).intensity_for(0.99)


def test_a_simulated_subject_answers_correctly_as_often_as_its_function_says():
    function = Psychometric("weibull", threshold=20.0, slope=3.0, guess=0.5, lapse=0.02)
    observer = PsychometricObserver(function, seed=3)
    for intensity in (5.0, 20.0, 40.0):
        p = float(function.probability(intensity))
        rate = np.mean([observer.answer(trial, intensity) for trial in range(1, 4001)])
        # Five binomial standard deviations of a rate over 4000 trials.
        assert abs(rate - p) <= 5 * math.sqrt(p * (1 - p) / 4000), (intensity, rate, p)


def test_a_simulated_subject_answers_a_trial_the_same_way_every_time():
    observer = PsychometricObserver(Psychometric("logistic", 100.0, 0.05, 0.5, 0.02), seed=8)
    first = [observer.answer(t, 90.0) for t in range(1, 200)]
    assert first == [PsychometricObserver(observer.function, 8).answer(t, 90.0) for t in range(1, 200)]
    other = [PsychometricObserver(observer.function, 9).answer(t, 90.0) for t in range(1, 200)]
    assert first != other


def test_a_slope_so_steep_its_power_overflows_rises_fully_without_a_warning_on_stderr():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's RuntimeWarning would reach the user's stderr
        p = probability_correct("weibull", [0.5, 2.0], 1.0, 1e308, 0.5, 0.0)
    assert list(p) == [0.5, 1.0]
