"""Maximum-likelihood psychometric fits: known parameters recovered from large simulated data,
the bootstrap interval covering the truth, the gradient and the log-likelihood checked."""

import numpy as np
import pytest
from scipy.optimize import check_grad
from scipy.stats import binom

from pinarray.adaptive.fit import _Model, fit_psychometric
from pinarray.adaptive.psychometric import Psychometric
from pinarray.errors import PinArrayError

STROKES_MM = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0])


def simulated(truth: Psychometric, trials: int, seed: int):
    n = np.full(len(STROKES_MM), trials)
    return n, np.random.default_rng(seed).binomial(n, truth.probability(STROKES_MM))


@pytest.mark.parametrize("truth", [
    Psychometric("weibull", threshold=2.0, slope=3.0, guess=0.5, lapse=0.03),
    Psychometric("logistic", threshold=2.0, slope=2.5, guess=0.5, lapse=0.03),
])
def test_a_fit_recovers_known_parameters_from_large_simulated_data(truth):
    n, k = simulated(truth, trials=4000, seed=5)
    fit = fit_psychometric(truth.kind, STROKES_MM, k, n, guess=0.5, lapse="fit", seed=1)
    # 32 000 trials: the threshold's standard error is ~1 %, the slope's ~5 %, the lapse's ~0.005.
    assert fit.threshold == pytest.approx(truth.threshold, rel=0.05)
    assert fit.slope == pytest.approx(truth.slope, rel=0.25)
    assert fit.lapse == pytest.approx(truth.lapse, abs=0.02)
    assert fit.lapse_fitted and fit.resamples == 500
    assert fit.ci_low <= truth.threshold <= fit.ci_high
    assert fit.ci_low < fit.threshold < fit.ci_high


def test_the_bootstrap_interval_covers_the_truth_for_most_small_data_sets():
    truth = Psychometric("weibull", threshold=2.0, slope=3.0, guess=0.5, lapse=0.0)
    covered = 0
    for seed in range(10):
        n, k = simulated(truth, trials=40, seed=seed)
        fit = fit_psychometric("weibull", STROKES_MM, k, n, guess=0.5, lapse=0.0,
                               resamples=200, seed=seed)
        covered += fit.ci_low <= truth.threshold <= fit.ci_high
    # A 95 % interval misses about 1 in 20; 8 of 10 or more has probability 0.99.
    assert covered >= 8


def test_a_stated_lapse_rate_is_kept():
    truth = Psychometric("logistic", threshold=2.0, slope=2.5, guess=0.5, lapse=0.03)
    n, k = simulated(truth, trials=200, seed=2)
    fit = fit_psychometric("logistic", STROKES_MM, k, n, guess=0.5, lapse=0.03, resamples=100)
    assert fit.lapse == 0.03 and not fit.lapse_fitted


def test_the_log_likelihood_is_that_of_the_data_under_the_fitted_function():
    truth = Psychometric("weibull", threshold=2.0, slope=3.0, guess=0.5, lapse=0.03)
    n, k = simulated(truth, trials=100, seed=3)
    fit = fit_psychometric("weibull", STROKES_MM, k, n, guess=0.5, lapse="fit", resamples=100)
    direct = binom.logpmf(k, n, fit.function.probability(STROKES_MM)).sum()
    assert fit.log_likelihood == pytest.approx(direct, rel=1e-9)
    # The maximum: no nearby function explains the data better.
    for factor in (0.97, 1.03):
        nearby = Psychometric("weibull", fit.threshold * factor, fit.slope, 0.5, fit.lapse)
        assert binom.logpmf(k, n, nearby.probability(STROKES_MM)).sum() < fit.log_likelihood


@pytest.mark.parametrize("kind", ["weibull", "logistic"])
@pytest.mark.parametrize("fixed_lapse", [None, 0.02])
def test_the_analytic_gradient_agrees_with_finite_differences(kind, fixed_lapse):
    truth = Psychometric(kind, threshold=2.0, slope=3.0, guess=0.5, lapse=0.03)
    n, k = simulated(truth, trials=50, seed=4)
    bounds = ((-5.0, 5.0), (-3.0, 3.0)) + (((0.0, 0.1),) if fixed_lapse is None else ())
    model = _Model(kind, STROKES_MM, 0.5, fixed_lapse, bounds)
    theta = model.coordinates(1.7, 2.2, 0.04)
    cost = lambda t: model.cost(t, k.astype(float), n.astype(float))[0]  # noqa: E731
    gradient = lambda t: model.cost(t, k.astype(float), n.astype(float))[1]  # noqa: E731
    # check_grad's forward differences (steps of 1.5e-8) err by about 1e-6 on a gradient of
    # order 10..100: 1e-4 of its norm leaves a wide margin and still catches a wrong term.
    assert check_grad(cost, gradient, theta) <= 1e-4 * max(1.0, np.linalg.norm(gradient(theta)))


def test_the_same_seed_gives_the_same_interval():
    truth = Psychometric("weibull", threshold=2.0, slope=3.0, guess=0.5, lapse=0.0)
    n, k = simulated(truth, trials=30, seed=9)
    first, again = (fit_psychometric("weibull", STROKES_MM, k, n, guess=0.5, lapse=0.0,
                                     resamples=100, seed=4) for _ in range(2))
    assert (first.ci_low, first.ci_high) == (again.ci_low, again.ci_high)


@pytest.mark.parametrize(("arguments", "message"), [
    ({"intensities": [1.0, 2.0], "n_correct": [1], "n_trials": [2, 2]}, "one count of correct answers and of trials per intensity"),
    ({"intensities": [1.0, 1.0], "n_correct": [1, 1], "n_trials": [2, 2]}, "2 distinct finite intensities or more"),
    ({"intensities": [0.0, 1.0], "n_correct": [1, 1], "n_trials": [2, 2]}, "Weibull fit needs intensities above 0, found 0.0"),
    ({"intensities": [1.0, 2.0], "n_correct": [3, 1], "n_trials": [2, 2]}, "0 <= correct <= trials"),
    ({"intensities": [1.0, 2.0], "n_correct": [1, 1], "n_trials": [2, 2], "lapse": 0.6}, "guess \\+ lapse below 1"),
    ({"intensities": [1.0, 2.0], "n_correct": [1, 1], "n_trials": [2, 2], "resamples": 10}, "100 resamples or more, found 10"),
    ({"kind": "probit", "intensities": [1.0, 2.0], "n_correct": [1, 1], "n_trials": [2, 2]}, "weibull or logistic, found 'probit'"),
])
def test_bad_fit_data_are_refused_saying_what_was_found(arguments, message):
    with pytest.raises(PinArrayError, match=message):
        fit_psychometric(**{"kind": "weibull", "guess": 0.5, "lapse": "fit"} | arguments)
