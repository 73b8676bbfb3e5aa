"""Identification (seed 001, 9.5): the seed's fits in SI, least squares with residuals,
and inverses that stay exact where the textbook quadratic formula cancels."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.softness._checks import SoftnessError
from pinarray.softness.identification import (
    M1_R11_FORCE_AREA,
    M2_R14_FORCE_DISPLACEMENT,
    LinearForceDisplacement,
    QuadraticForceArea,
    fit_force_area,
    fit_force_displacement,
)
from tests.softness.strategies import (
    U,
    forces_n,
    log_uniform,
    quadratic_a_n_per_m4,
    quadratic_b_n_per_m2,
    quadratic_c_n,
    tiny_to_huge,
)

# rtol 1e-15 (9 u) and 1e-14 (90 u) below: SI conversions and these formulas are a few
# correctly rounded operations on once-rounded decimal inputs, within 6 u.


def test_eq_9_4_in_si_units():
    # 1.4 N/cm^4 = 1.4 / (1e-4)^2 = 1.4e8 N/m^4; 0.33 N/cm^2 = 3300 N/m^2
    assert_allclose(M1_R11_FORCE_AREA.a_n_per_m4, 1.4e8, rtol=1e-15)
    assert_allclose(M1_R11_FORCE_AREA.b_n_per_m2, 3300, rtol=1e-15)
    # A = 2 cm^2: 1.4 * 4 + 0.33 * 2 + 0.55 = 5.6 + 0.66 + 0.55 = 6.81 N
    assert_allclose(M1_R11_FORCE_AREA.force_n(2e-4), 6.81, rtol=1e-14)
    assert_allclose(M1_R11_FORCE_AREA.area_m2(6.81), 2e-4, rtol=1e-14)


def test_eq_9_5_in_si_units():
    # 23 N/cm = 2300 N/m; z = 0.5 cm: 23 * 0.5 + 0.97 = 12.47 N
    assert_allclose(M2_R14_FORCE_DISPLACEMENT.slope_n_per_m, 2300, rtol=1e-15)
    assert_allclose(M2_R14_FORCE_DISPLACEMENT.force_n(0.005), 12.47, rtol=1e-14)
    assert_allclose(M2_R14_FORCE_DISPLACEMENT.displacement_m(12.47), 0.005, rtol=1e-14)


def test_forces_below_the_fitted_intercept_have_no_area():
    # F(0) = 0.55 N: the fit says nothing below it
    assert M1_R11_FORCE_AREA.area_m2(0.3) == 0.0
    assert M2_R14_FORCE_DISPLACEMENT.displacement_m(0.5) == 0.0


def test_the_inverse_keeps_full_precision_where_the_textbook_formula_cancels():
    model = QuadraticForceArea(a_n_per_m4=1.0, b_n_per_m2=1e8, c_n=0.0)
    # F = 1e-8 N: A = F / b - a F^2 / b^3 + ... = 1e-16 - 1e-40 m^2; the textbook
    # (-b + sqrt(b^2 + 4 a F)) / 2a gives 0 here because b^2 + 4aF rounds to b^2.
    assert_allclose(model.area_m2(1e-8), 1e-16, rtol=1e-15)
    textbook = (-1e8 + np.sqrt(1e16 + 4e-8)) / 2
    # exact on any IEEE machine: 1e16 + 4e-8 rounds to 1e16, whose sqrt is 1e8
    assert textbook == 0.0  # documents why the stable form is needed


def test_a_pure_square_law_inverts_too():
    # F = 4e8 A^2: F = 1 N -> A = sqrt(1 / 4e8) = 5e-5 m^2
    assert_allclose(QuadraticForceArea(4e8, 0.0, 0.0).area_m2(1.0), 5e-5, rtol=1e-15)


@given(a=quadratic_a_n_per_m4, b=quadratic_b_n_per_m2, c=quadratic_c_n, excess=forces_n)
def test_force_to_area_to_force_round_trip(a, b, c, excess):
    model = QuadraticForceArea(a, b, c)
    force = c + excess
    assert_allclose(model.force_n(model.area_m2(force)), force, rtol=1e-12)


# Force -> area -> force. A = 2 e / (b + sqrt(b b + 4 a e)), e = F - c: e rounds once, the
# sum under the root by at most 2 u (halved by the root), the root, the sum and the quotient
# once each: 5.5 u; the force a A^2 + b A feels A's error at most twice, and rounds four
# times more: 2 * 5.5 + 4 + 1 = 16 u. (b = 0: sqrt(e / a), 2 u, doubled, plus 4 u.)
QUADRATIC_ROUND_TRIP_RTOL = 16 * U
# F -> (F - c) / k -> k z + c: four roundings.
LINEAR_ROUND_TRIP_RTOL = 4 * U


@given(
    a=quadratic_a_n_per_m4,
    b=st.one_of(st.just(0.0), quadratic_b_n_per_m2),
    c=quadratic_c_n,
    excess=tiny_to_huge,
)
def test_the_quadratic_inverse_at_its_edge_and_at_tiny_and_huge_forces(a, b, c, excess):
    model = QuadraticForceArea(a, b, c)
    # the force at zero area is the edge: exactly zero area, and back exactly that force
    assert model.area_m2(c) == 0.0 and model.force_n(0.0) == c
    force = c + excess
    assert_allclose(model.force_n(model.area_m2(force)), force, rtol=QUADRATIC_ROUND_TRIP_RTOL)


@given(slope=log_uniform(1e-3, 1e9), intercept=quadratic_c_n, excess=tiny_to_huge)
def test_the_linear_inverse_at_its_edge_and_at_tiny_and_huge_forces(slope, intercept, excess):
    model = LinearForceDisplacement(slope, intercept)
    assert model.displacement_m(intercept) == 0.0 and model.force_n(0.0) == intercept
    force = intercept + excess
    back = model.force_n(model.displacement_m(force))
    assert_allclose(back, force, rtol=LINEAR_ROUND_TRIP_RTOL)


def test_a_falling_curve_is_not_invertible():
    with pytest.raises(SoftnessError, match="not increasing"):
        QuadraticForceArea(1.0, -5.0, 0.0).area_m2(1.0)
    with pytest.raises(SoftnessError, match="slope must be positive"):
        LinearForceDisplacement(0.0, 1.0).displacement_m(1.0)


def test_the_line_through_three_hand_points():
    # (0, 1), (1 mm, 3), (2 mm, 4) N: mean z = 1 mm, mean F = 8/3 N,
    # Szz = 2e-6 m^2, SzF = 1e-3 * (5/3) + 1e-3 * (4/3) = 3e-3 N m -> k = 1500 N/m,
    # c = 8/3 - 1500 * 1e-3 = 7/6 N; residuals -1/6, 1/3, -1/6 N
    fit = fit_force_displacement([0.0, 1e-3, 2e-3], [1.0, 3.0, 4.0])
    assert_allclose(fit.model.slope_n_per_m, 1500, rtol=1e-12)
    assert_allclose(fit.model.intercept_n, 7 / 6, rtol=1e-12)
    assert_allclose(fit.residuals_n, [-1 / 6, 1 / 3, -1 / 6], atol=1e-12)
    # rms = sqrt((1/36 + 1/9 + 1/36) / 3) = sqrt(1/18)
    assert_allclose(fit.rms_residual_n, np.sqrt(1 / 18), rtol=1e-12)


def test_the_seed_curve_is_recovered_from_its_own_samples():
    area = np.linspace(0, 3e-4, 25)  # 0 to 3 cm^2, as in Fig. 9.7
    fit = fit_force_area(area, M1_R11_FORCE_AREA.force_n(area))
    assert_allclose(
        [fit.model.a_n_per_m4, fit.model.b_n_per_m2, fit.model.c_n], [1.4e8, 3300, 0.55], rtol=1e-9
    )
    # exact samples leave residuals of about cond (of the scaled Vandermonde columns, ~20)
    # times a few u times the forces (up to 13 N): ~1e-13 N at most
    assert fit.max_residual_n < 1e-12


@given(seed=st.integers(0, 2**32 - 1), noise=st.floats(1e-4, 1.0))
def test_residuals_of_a_noisy_fit_are_orthogonal_to_the_model_terms(seed, noise):
    # The defining property of a least-squares solution: residuals r satisfy X^T r = 0.
    rng = np.random.default_rng(seed)
    area = np.sort(rng.uniform(0, 3e-4, 30))
    force = M1_R11_FORCE_AREA.force_n(area) + rng.normal(0, noise, area.size)
    fit = fit_force_area(area, force)
    scaled = area / 3e-4
    for column in (scaled**2, scaled, np.ones_like(scaled)):
        assert abs(column @ fit.residuals_n) < 1e-9 * (1 + np.abs(force).sum())
    # the same computation as the fit's: equal to the bit, on any machine
    assert_allclose(fit.residuals_n, force - fit.model.force_n(area), atol=1e-12)


def test_fits_reject_bad_samples():
    with pytest.raises(SoftnessError, match="at least 3 samples"):
        fit_force_area([1e-4, 2e-4], [1.0, 2.0])
    with pytest.raises(SoftnessError, match="same length"):
        fit_force_displacement([1e-3, 2e-3, 3e-3], [1.0, 2.0])
    with pytest.raises(SoftnessError, match="area_m2 must be finite"):
        fit_force_area([1e-4, np.nan, 2e-4], [1.0, 2.0, 3.0])
    with pytest.raises(SoftnessError, match="force_n must be finite"):
        fit_force_displacement([1e-3, 2e-3], [1.0, np.inf])
    with pytest.raises(SoftnessError, match="zero area or displacement"):
        fit_force_displacement([0.0, 0.0], [1.0, 2.0])
