"""The mixed-effects logistic fit of the frequency effect: right answers on known data."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import integrate

from pinarray.paradigms.localisation.frequency_effect import (
    QUADRATURE_NODES,
    Cell,
    FitSkipped,
    FrequencyEffect,
    _Data,
    fit_frequency_effect,
)

FREQUENCIES_HZ = (3.0, 5.0, 10.0)


def simulated_cells(subjects, trials, slope, subject_sd, seed, intercept=0.0):
    rng = np.random.default_rng(seed)
    centre = np.mean(np.log2(FREQUENCIES_HZ))
    cells = []
    for s in range(subjects):
        u = rng.normal(0, subject_sd)
        for f in FREQUENCIES_HZ:
            p = 1 / (1 + math.exp(-(intercept + slope * (math.log2(f) - centre) + u)))
            cells.append(Cell(f"s{s}", f, int(rng.binomial(trials, p)), trials))
    return cells


def test_a_large_simulated_study_gives_back_its_slope_and_subject_spread():
    fit = fit_frequency_effect(simulated_cells(300, 20, slope=0.8, subject_sd=0.7, seed=1))
    assert isinstance(fit, FrequencyEffect) and fit.converged
    assert abs(fit.slope_per_doubling - 0.8) < 3 * fit.slope_se
    assert abs(fit.subject_sd_logit - 0.7) < 0.1
    assert fit.lrt_p < 1e-6 and fit.subjects == 300 and fit.trials == 300 * 3 * 20


def test_no_frequency_effect_in_the_data_gives_no_significant_slope():
    fit = fit_frequency_effect(simulated_cells(40, 12, slope=0.0, subject_sd=0.7, seed=5))
    assert isinstance(fit, FrequencyEffect)
    low, high = fit.odds_ratio_interval
    assert low < 1 < high and fit.lrt_p > 0.05


def test_identical_subjects_give_the_ordinary_logistic_slope_and_no_spread():
    # Every subject 3/10 at 3 Hz and 7/10 at 10 Hz: no spread to estimate; with two
    # frequencies the ordinary logistic fit goes through both empirical log-odds.
    cells = [Cell(f"s{s}", f, k, 10) for s in range(8) for f, k in ((3.0, 3), (10.0, 7))]
    fit = fit_frequency_effect(cells)
    assert isinstance(fit, FrequencyEffect)
    logit = lambda p: math.log(p / (1 - p))  # noqa: E731
    expected = (logit(0.7) - logit(0.3)) / (math.log2(10) - math.log2(3))
    assert_allclose(fit.slope_per_doubling, expected, rtol=1e-3)
    assert fit.subject_sd_logit < 0.05
    assert_allclose(fit.typical_subject_pct, (30.0, 70.0), atol=0.1)


@pytest.mark.parametrize("subject_sd", [0.2, 1.0, 2.5])
@pytest.mark.parametrize("trials", [8, 40, 100])
def test_the_quadrature_likelihood_equals_direct_numerical_integration(subject_sd, trials):
    cells = simulated_cells(5, trials, slope=0.7, subject_sd=subject_sd, seed=trials)
    data = _Data(cells, QUADRATURE_NODES)
    b0, b1 = 0.1, 0.7
    total = 0.0
    for i in range(data.subjects):
        mine = data.subject == i

        def integrand(u, mine=mine):
            eta = b0 + b1 * data.x[mine] + u
            log_p = (-data.k[mine] * np.logaddexp(0, -eta)
                     - (data.n[mine] - data.k[mine]) * np.logaddexp(0, eta)
                     + data.log_binomial[mine]).sum()
            return math.exp(log_p - u * u / (2 * subject_sd ** 2)) / (
                subject_sd * math.sqrt(2 * math.pi))

        value, _ = integrate.quad(integrand, -12 * subject_sd, 12 * subject_sd, limit=400,
                                  epsabs=0, epsrel=1e-12,
                                  points=[0.0])
        total += math.log(value)
    assert_allclose(data.negative_log_likelihood(b0, b1, math.log(subject_sd)), -total,
                    rtol=1e-7)


def test_too_few_subjects_or_one_frequency_is_said_not_fitted():
    few = fit_frequency_effect(simulated_cells(3, 8, slope=0.5, subject_sd=0.5, seed=2))
    assert isinstance(few, FitSkipped) and "at least 6 subjects" in few.reason
    assert "found 3" in few.describe()
    one = fit_frequency_effect([Cell(f"s{s}", 10.0, 4, 8) for s in range(8)])
    assert isinstance(one, FitSkipped) and "2 frequencies, found 1" in one.reason
