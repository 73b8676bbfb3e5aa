"""The forceps pipeline (seed 000, 4.1): force/displacement samples -> modulus -> force/area
through Hertz -> the pressure a display needs to replicate the tissue."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.softness._checks import SoftnessError
from pinarray.softness.forceps import TissueModel, fit_tissue
from pinarray.softness.hertz import HertzContact
from pinarray.softness.tf_display import ConeDisplay
from tests.softness.strategies import (
    FEW_ULPS,
    U,
    forces_n,
    log_uniform,
    moduli_pa,
    radii_m,
    strains,
    tiny_to_huge,
    with_zero,
)

LINEAR = TissueModel(radius_m=0.01, e0_pa=1e5)  # E = 75 kPa, nu = 0.5
STIFFENING = TissueModel(radius_m=0.01, e0_pa=1e5, e1_pa=1e6)
# Growth e1 / e0 of a softening tissue: its force stops rising at eps = 0.75 / |growth|.
SOFTENING_GROWTH = log_uniform(1e-2, 1e2).map(lambda growth: -growth)

# Force -> area -> force. The inverse's strain is the exact one of a nearby force: w = 3 F /
# (4 R^2 e0) and g = e1 / e0 round by 3 u and u, Newton stops at the rounding of its residual,
# at most 10 u of the force (twice that if the last step is dropped as noise), and the
# closed form of a constant modulus puts cbrt's FEW_ULPS three times into the force. Area and
# strain round by 4.5 u, which the force feels at most 4-fold (d ln F / d ln eps <= 4); the
# forward function rounds by 8 u. 3 + 1 + 20 + 18 + 8 = 50 u (cbrt: 3 * 8 + 18 + 8 = 50 u).
ROUND_TRIP_RTOL = 64 * U
assert 3 * 2 * FEW_ULPS + 18 + 8 <= 64


def test_a_constant_modulus_tissue_by_hand():
    # rtol 1e-14 is 90 u: the force and the pressure take a dozen correctly rounded operations
    # (sqrt, products, quotients), the area two cbrt of FEW_ULPS each, doubled by the square.
    # delta = 1e-4 m -> eps = sqrt(1e-4 / 0.01) = 0.1, a = 1 mm;
    # F = (4/3) R^2 eps^3 E* = (4/3) * 1e-4 * 1e-3 * 1e5 = 0.04/3 N
    assert_allclose(LINEAR.force_for_approach_n(1e-4), 0.04 / 3, rtol=1e-14)
    assert_allclose(LINEAR.area_for_force_m2(0.04 / 3), np.pi * 1e-6, rtol=1e-14)
    # p = F / A = (0.04/3) / (pi 1e-6) = 4244.13 Pa = 4 E* eps / (3 pi)
    assert_allclose(LINEAR.display_pressure_pa(np.pi * 1e-6), 4e4 / (3 * np.pi), rtol=1e-14)
    # E = E* (1 - nu^2) = 1e5 * 0.75: exact but for 0.5**2 (pow, a few ulps diluted by a
    # third) and one product; rtol 1e-15 is 9 u
    assert_allclose(LINEAR.young_modulus_pa(0.1), 75e3, rtol=1e-15)


def test_a_stiffening_tissue_by_hand():
    # eps = 0.1: E* = 1e5 + 1e6 * 0.1 = 2e5 Pa, so twice the force of the linear tissue
    # (one product and one sum: 2 u, inside rtol 1e-15 = 9 u). The force as above; the area
    # from Newton is off by its ~26 u of force times d ln A / d ln F = 2 / 3.5, plus 4.5 u:
    # inside 1e-13 = 900 u.
    assert_allclose(STIFFENING.effective_modulus_pa(0.1), 2e5, rtol=1e-15)
    assert_allclose(STIFFENING.force_for_approach_n(1e-4), 0.08 / 3, rtol=1e-14)
    assert_allclose(STIFFENING.area_for_force_m2(0.08 / 3), np.pi * 1e-6, rtol=1e-13)


@given(force=with_zero(forces_n), radius=radii_m, modulus=moduli_pa)
def test_a_constant_modulus_agrees_with_the_hertz_contact(force, radius, modulus):
    tissue = TissueModel(radius, modulus)
    hertz = HertzContact(radius, modulus)
    # two closed forms, each a cbrt (FEW_ULPS) of an argument rounded thrice, squared and
    # scaled: within 2 * (2 * 8 u + 3 u) + 4 u of each other, far inside 1e-13 = 900 u
    assert_allclose(tissue.area_for_force_m2(force), hertz.contact_area_m2(force), rtol=1e-13)


@given(force=forces_n, radius=radii_m, e0=moduli_pa, growth=log_uniform(1e-3, 1e3))
def test_area_round_trips_for_stiffening_tissue_from_micronewtons(force, radius, e0, growth):
    tissue = TissueModel(radius, e0, e0 * growth)
    area = tissue.area_for_force_m2(force)
    assert_allclose(tissue.force_for_area_n(area), force, rtol=1e-12)


@given(strain=strains, e0=moduli_pa, softening=st.floats(0.01, 0.74))
def test_area_round_trips_for_softening_tissue_on_its_rising_branch(strain, e0, softening):
    # e1 = -softening * e0 keeps force rising up to eps = 0.75 / softening > 1
    tissue = TissueModel(0.01, e0, -softening * e0)
    force = tissue.force_for_strain_n(strain)
    assert_allclose(tissue.strain_for_area(tissue.area_for_force_m2(force)), strain, rtol=1e-12)


def test_softening_past_the_rising_branch_is_refused():
    tissue = TissueModel(0.01, 1e5, -1e6)  # force stops rising at eps = 0.075
    with pytest.raises(SoftnessError, match="stops rising"):
        tissue.force_for_strain_n(0.1)
    with pytest.raises(SoftnessError, match="beyond the largest force"):
        tissue.area_for_force_m2(10.0)


@given(area=st.floats(0.0, ConeDisplay().max_area_m2))
def test_the_display_pressure_reproduces_the_tissue_force_on_the_cone(area):
    cone = ConeDisplay()
    pressure = STIFFENING.display_pressure_pa(area)
    rendered = cone.force_n(pressure, cone.indentation_for_area_m(area))
    assert_allclose(rendered, STIFFENING.force_for_area_n(area), rtol=1e-12, atol=1e-300)


def test_the_fit_recovers_a_stiffening_tissue_from_forceps_samples():
    approach = np.linspace(0, 3e-3, 40)
    fit = fit_tissue(approach, STIFFENING.force_for_approach_n(approach), radius_m=0.01)
    assert_allclose([fit.model.e0_pa, fit.model.e1_pa], [1e5, 1e6], rtol=1e-9)
    # least squares on exact samples leaves residuals of about cond (18 for these scaled
    # columns) times a few u times the forces (up to 14 N): ~1e-13 N at most
    assert fit.rms_residual_n < 1e-12


def test_a_constant_fit_of_stiffening_samples_leaves_residuals():
    approach = np.linspace(0, 3e-3, 40)
    force = STIFFENING.force_for_approach_n(approach)
    constant = fit_tissue(approach, force, radius_m=0.01, strain_dependent=False)
    assert constant.model.e1_pa == 0.0
    assert constant.rms_residual_n > 1e-3


@given(seed=st.integers(0, 2**32 - 1))
def test_noisy_samples_give_residuals_orthogonal_to_the_model_terms(seed):
    rng = np.random.default_rng(seed)
    approach = np.sort(rng.uniform(0, 3e-3, 30))
    force = STIFFENING.force_for_approach_n(approach) + rng.normal(0, 0.01, approach.size)
    fit = fit_tissue(approach, force, radius_m=0.01)
    for column in (np.sqrt(0.01) * approach**1.5, approach**2):
        assert abs(column @ fit.residuals_n) < 1e-9 * np.linalg.norm(column) * np.linalg.norm(force)


def test_samples_that_are_not_a_contact_are_refused():
    with pytest.raises(SoftnessError, match="never closed"):
        fit_tissue([0.0, 0.0, 0.0], [0.0, 0.1, 0.2], radius_m=0.01)
    with pytest.raises(SoftnessError, match="not positive"):
        fit_tissue([1e-3, 2e-3, 3e-3], [-1.0, -2.0, -3.0], radius_m=0.01)
    with pytest.raises(SoftnessError, match="approach_m"):
        fit_tissue([1e-3, -2e-3], [1.0, 2.0], radius_m=0.01)
    with pytest.raises(SoftnessError, match="poisson"):
        TissueModel(0.01, 1e5, poisson=0.6)


# No deadline: 21 000 samples an example took 253 ms on a loaded machine with numpy's AVX
# paths off (milliseconds unloaded); timing belongs in the benchmarks.
@settings(deadline=None)
@given(
    e0=moduli_pa,
    growth=st.one_of(log_uniform(1e-3, 1e3), st.floats(-0.74, -0.01)),
    seed=st.integers(0, 2**32 - 1),
)
def test_a_long_batch_of_forces_inverts_sample_by_sample_with_zeros_exact(e0, growth, seed):
    # more samples than one block of the solver, in a 2-D shape, with zeros among them
    tissue = TissueModel(0.01, e0, growth * e0)
    rng = np.random.default_rng(seed)
    strain = 10.0 ** rng.uniform(-6, 0, (3, 7001))
    strain[rng.random(strain.shape) < 0.01] = 0.0
    force = tissue.force_for_strain_n(strain)
    area = tissue.area_for_force_m2(force)
    assert area.shape == force.shape
    assert (area[force == 0] == 0).all()
    assert_allclose(tissue.strain_for_area(area), strain, rtol=1e-12)
    single = [float(tissue.area_for_force_m2(f)) for f in force.flat[::997]]
    # A sample alone stops at its first step below the last-step threshold (8 u when
    # softening; one landing within an ulp of the root when stiffening); in a block it may take
    # a few more, each shrinking, so no more than 8 + 6 + 4 + 2 = 20 u of strain, 40 u of
    # area: inside 1e-14 = 90 u.
    assert_allclose(area.flat[::997], single, rtol=1e-14)


def test_the_largest_force_of_a_softening_tissue_reaches_its_largest_strain():
    tissue = TissueModel(0.01, 1e5, -1e6)  # force stops rising at eps = 0.075
    top_n = tissue.force_for_strain_n(tissue.max_strain)
    forces = np.array([top_n, top_n * (1 - 1e-9), top_n / 2])
    strain = tissue.strain_for_area(tissue.area_for_force_m2(forces))
    # Flat at the top: F = F_top (1 - 6 d^2) a relative strain d below it, so the ~50 u the
    # force may be off (ROUND_TRIP_RTOL) move the strain by sqrt(50 u / 6) = 3e-8; and a force
    # 1e-9 below the top sits sqrt(1e-9 / 6) = 1.3e-5 below the largest strain.
    assert_allclose(strain[0], tissue.max_strain, rtol=1e-7)
    assert 1e-5 < 1 - strain[1] / tissue.max_strain < 2e-5
    assert_allclose(tissue.force_for_strain_n(strain), forces, rtol=ROUND_TRIP_RTOL)


@given(radius=radii_m, e0=moduli_pa, growth=SOFTENING_GROWTH)
def test_the_largest_force_of_any_softening_tissue_comes_back_at_the_largest_strain(
    radius, e0, growth
):
    tissue = TissueModel(radius, e0, growth * e0)
    top_n = tissue.force_for_strain_n(tissue.max_strain)
    area = tissue.area_for_force_m2(top_n)
    # the area's strain may come back rounding steps past the largest: it is the largest
    strain = tissue.strain_for_area(area)
    assert strain <= tissue.max_strain * (1 + 6 * U)
    assert_allclose(tissue.force_for_area_n(area), top_n, rtol=ROUND_TRIP_RTOL)
    assert_allclose(strain, tissue.max_strain, rtol=1e-7)  # sqrt(50 u / 6), as above


@given(
    radius=radii_m,
    e0=moduli_pa,
    growth=SOFTENING_GROWTH,
    below=log_uniform(1e-17, 1e-2),
)
def test_forces_just_below_the_flat_top_come_back_through_their_area(radius, e0, growth, below):
    # Within rounding of the top the forward force may exceed the largest force it computes at
    # the largest strain: the inverse takes it as the largest.
    tissue = TissueModel(radius, e0, growth * e0)
    force = tissue.force_for_strain_n(tissue.max_strain * (1 - below))
    area = tissue.area_for_force_m2(force)
    assert_allclose(tissue.force_for_area_n(area), force, rtol=ROUND_TRIP_RTOL)


@given(radius=radii_m, e0=moduli_pa, growth=SOFTENING_GROWTH)
def test_strains_and_forces_truly_past_the_top_are_still_refused(radius, e0, growth):
    # 1e-13 is some 900 u: far past what rounding can carry a value (6 u and 16 u)
    tissue = TissueModel(radius, e0, growth * e0)
    with pytest.raises(SoftnessError, match="stops rising"):
        tissue.force_for_strain_n(tissue.max_strain * (1 + 1e-13))
    top_n = float(tissue.force_for_strain_n(tissue.max_strain))
    with pytest.raises(SoftnessError, match="beyond the largest force"):
        tissue.area_for_force_m2(top_n * (1 + 1e-13))


@given(
    radius=radii_m,
    e0=moduli_pa,
    growth=st.one_of(st.just(0.0), log_uniform(1e-3, 1e3), SOFTENING_GROWTH),
    magnitude=tiny_to_huge,
)
def test_tiny_and_huge_forces_come_back_through_their_area(radius, e0, growth, magnitude):
    tissue = TissueModel(radius, e0, growth * e0)
    if growth < 0:  # a fraction of the largest force, down to 1e-200 of it
        force = min(magnitude, 1.0) * tissue.force_for_strain_n(tissue.max_strain)
    else:
        force = magnitude
    area = tissue.area_for_force_m2(force)
    assert_allclose(tissue.force_for_area_n(area), force, rtol=ROUND_TRIP_RTOL)
    assert tissue.area_for_force_m2(0.0) == 0.0 and tissue.force_for_area_n(0.0) == 0.0
