"""Hertz contact (seed 000 eqs. 1-7): the lab's hand-worked numbers, round trips, limits."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.softness._checks import SoftnessError
from pinarray.softness.hertz import (
    SMALL_CONTACT_FRACTION,
    HertzContact,
    effective_modulus_pa,
    relative_radius_m,
)
from tests.softness.strategies import (
    FEW_ULPS,
    U,
    forces_n,
    moduli_pa,
    poisson_ratios,
    radii_m,
    tiny_to_huge,
    with_zero,
)

# A sphere of R = 1 cm with E* = 1e5 Pa (E = 75 kPa, nu = 0.5, on a rigid plane).
# Choosing 3 F R / (4 E*) = 1e-9 m^3 makes a = 1 mm: F = 4 * 1e5 * 1e-9 / (3 * 0.01) = 0.04/3 N.
CONTACT = HertzContact(relative_radius_m=0.01, effective_modulus_pa=1e5)
FORCE_FOR_1_MM_N = 0.04 / 3


# rtol 1e-15 (9 u) below: a handful of correctly rounded operations on exact or once-rounded
# inputs, at most 4 u.


def test_effective_modulus_of_a_tissue_on_a_rigid_jaw():
    # 1/E* = (1 - 0.25) / 75e3 = 1e-5 -> E* = 1e5 Pa
    assert_allclose(effective_modulus_pa(75e3, 0.5), 1e5, rtol=1e-15)


def test_effective_modulus_of_two_elastic_bodies():
    # 1/E* = 0.75 / 1e5 + 1 / 2e5 = 7.5e-6 + 5e-6 = 1.25e-5 -> E* = 8e4 Pa
    assert_allclose(effective_modulus_pa(1e5, 0.5, 2e5, 0.0), 8e4, rtol=1e-15)


def test_relative_radius_of_two_spheres_and_of_a_sphere_on_a_flat():
    # 1/R = 1/0.01 + 1/0.03 = 100 + 33.33 = 133.33 -> R = 7.5 mm
    assert_allclose(relative_radius_m(0.01, 0.03), 0.0075, rtol=1e-15)
    # exact on any IEEE machine: 1 / 0.01 rounds to 100 and 1 / 100 to 0.01
    assert relative_radius_m(0.01) == 0.01


def test_the_hand_worked_contact_of_one_millimetre():
    # rtol 1e-14 = 90 u: one cbrt (FEW_ULPS, 8 u) and a few correctly rounded operations
    force = FORCE_FOR_1_MM_N
    assert_allclose(CONTACT.contact_radius_m(force), 1e-3, rtol=1e-14)
    # A = pi a^2 = pi * 1e-6 m^2
    assert_allclose(CONTACT.contact_area_m2(force), np.pi * 1e-6, rtol=1e-14)
    # delta = a^2 / R = 1e-6 / 0.01 = 1e-4 m
    assert_allclose(CONTACT.approach_m(force), 1e-4, rtol=1e-14)
    # p0 = 2 E* a / (pi R) = 2e5 * 1e-3 / (pi * 0.01) = 20000 / pi = 6366.1977 Pa
    assert_allclose(CONTACT.peak_pressure_pa(force), 6366.197723675814, rtol=1e-14)


def test_pressure_is_elliptic_and_vanishes_outside_the_contact():
    p0 = 20000 / np.pi
    pressures = CONTACT.pressure_pa([0.0, 0.5e-3, 1e-3, 2e-3], FORCE_FOR_1_MM_N)
    # p(a/2) = p0 sqrt(1 - 1/4) = 0.8660 p0 (a cbrt, 8 u, and a few roundings: 1e-13 is 900 u)
    assert_allclose(pressures, [p0, p0 * np.sqrt(0.75), 0.0, 0.0], rtol=1e-13, atol=1e-9)


def test_pressure_integrates_to_the_force_eq_6():
    r = np.linspace(0.0, 1e-3, 200_001)
    integrand = CONTACT.pressure_pa(r, FORCE_FOR_1_MM_N) * 2 * np.pi * r
    integral = np.sum((integrand[1:] + integrand[:-1]) / 2 * np.diff(r))
    # the sqrt edge at r = a limits the trapezoid rule to about 1e-7 relative here
    assert_allclose(integral, FORCE_FOR_1_MM_N, rtol=1e-6)


@given(r_fraction=st.floats(0.0, 1.0))
def test_displacements_inside_the_contact_satisfy_eq_4(r_fraction):
    # (pi p0 / (4 a E*)) (2 a^2 - r^2) = delta - r^2 / (2 R) for every r <= a
    a, p0, delta = 1e-3, 20000 / np.pi, 1e-4
    r = r_fraction * a
    left = np.pi * p0 / (4 * a * 1e5) * (2 * a**2 - r**2)
    assert_allclose(left, delta - r**2 / (2 * 0.01), rtol=1e-12)
    assert_allclose(CONTACT.approach_m(FORCE_FOR_1_MM_N), delta, rtol=1e-14)


def test_zero_force_is_exactly_no_contact():
    # exact everywhere: cbrt(0), sqrt(0) and 0 ** 3 are 0 (IEEE 754 and C99 Annex F)
    assert CONTACT.contact_area_m2(0.0) == 0.0
    assert CONTACT.approach_m(0.0) == 0.0
    assert CONTACT.peak_pressure_pa(0.0) == 0.0
    assert np.all(CONTACT.pressure_pa([0.0, 1e-3], 0.0) == 0.0)
    assert CONTACT.force_for_area_n(0.0) == 0.0


def test_arrays_keep_their_shape():
    forces = np.full((3, 4), FORCE_FOR_1_MM_N)
    assert CONTACT.contact_area_m2(forces).shape == (3, 4)


@given(force=with_zero(forces_n), radius=radii_m, modulus=moduli_pa)
def test_area_and_approach_invert_back_to_the_force(force, radius, modulus):
    contact = HertzContact(radius, modulus)
    assert_allclose(contact.force_for_area_n(contact.contact_area_m2(force)), force, rtol=1e-12)
    assert_allclose(contact.force_for_approach_n(contact.approach_m(force)), force, rtol=1e-12)


# Force -> area (or approach) -> force: a = cbrt(3 F R / 4 E*) is one cbrt (FEW_ULPS) of an
# argument rounded twice; A = pi a^2 and back a = sqrt(A / pi) round four times more (the
# power of 2 counted as FEW_ULPS); the force F = 4 E* a^3 / (3 R) feels a's error three times
# and rounds a^3 (FEW_ULPS) and three products and quotients more:
# 3 * (8 + 1 + 2 + 8 / 2 + 1) u + 8 u + 3 u = 59 u.
ROUND_TRIP_RTOL = 64 * U
assert 3 * (2 * FEW_ULPS + 1 + 2 + FEW_ULPS + 1) + 2 * FEW_ULPS + 3 <= 64


@given(force=tiny_to_huge, radius=radii_m, modulus=moduli_pa)
def test_tiny_and_huge_forces_come_back_through_area_and_approach(force, radius, modulus):
    contact = HertzContact(radius, modulus)
    for there, back in (
        (contact.contact_area_m2, contact.force_for_area_n),
        (contact.approach_m, contact.force_for_approach_n),
    ):
        assert_allclose(back(there(force)), force, rtol=ROUND_TRIP_RTOL)
        assert there(0.0) == 0.0 and back(0.0) == 0.0


@given(force=forces_n, radius=radii_m, modulus=moduli_pa)
def test_area_grows_as_force_to_the_two_thirds(force, radius, modulus):
    contact = HertzContact(radius, modulus)
    # (8 F)^(2/3) = 4 F^(2/3): two cbrt of FEW_ULPS each, squared: 2 * 2 * 8 u + 4 u, inside
    # 1e-13 = 900 u
    assert_allclose(
        contact.contact_area_m2(8 * force), 4 * contact.contact_area_m2(force), rtol=1e-13
    )
    # mean pressure F / A is two thirds of the peak (eq. 6)
    mean = force / contact.contact_area_m2(force)
    assert_allclose(mean, 2 / 3 * contact.peak_pressure_pa(force), rtol=1e-12)


@given(modulus=moduli_pa, nu=poisson_ratios)
def test_a_rigid_partner_adds_no_compliance(modulus, nu):
    # nu nu as the module squares it (1 - nu^2 would magnify a power's error 49-fold): the
    # same 1 - nu^2 on every machine, then a quotient or two: 3 u, inside 1e-15 = 9 u
    assert_allclose(
        effective_modulus_pa(modulus, nu, np.inf, 0.3), modulus / (1 - nu * nu), rtol=1e-15
    )


@pytest.mark.parametrize("bad", [np.nan, -1e-3, np.inf])
def test_bad_forces_are_rejected_naming_the_argument(bad):
    with pytest.raises(SoftnessError, match=r"force_n must be finite and non-negative: found"):
        CONTACT.contact_area_m2([0.1, bad])


def test_an_error_says_where_in_the_array_the_bad_value_is():
    with pytest.raises(SoftnessError, match=r"found nan at index 2"):
        CONTACT.approach_m([0.1, 0.2, np.nan])


def test_impossible_bodies_are_rejected():
    with pytest.raises(SoftnessError, match="both infinite"):
        effective_modulus_pa(np.inf, 0.5, np.inf, 0.5)
    with pytest.raises(SoftnessError, match="poisson_1"):
        effective_modulus_pa(1e5, 0.7)
    with pytest.raises(SoftnessError, match="relative_radius_m"):
        HertzContact(0.0, 1e5)
    with pytest.raises(SoftnessError, match="radius_1_m"):
        relative_radius_m(np.nan)


@given(radius=radii_m, modulus=moduli_pa)
def test_the_small_contact_limit_force_makes_a_contact_a_tenth_of_the_radius(radius, modulus):
    contact = HertzContact(radius, modulus)
    # F = 4 E* (0.1 R)^3 / (3 R): 0.1 R and the products round at most 4 u, the cube FEW_ULPS
    # ulps (8 u); a = cbrt(0.75 F R / E*) adds 3 u under the root (divided by 3 by it) and
    # FEW_ULPS ulps for cbrt: 8 u + (12 u + 3 u) / 3 + u for 0.1 R itself, within 16 u.
    a = contact.contact_radius_m(contact.small_contact_force_n)
    assert_allclose(a, SMALL_CONTACT_FRACTION * radius, rtol=16 * U)


def test_the_hand_worked_contact_of_one_millimetre_is_at_the_small_contact_limit():
    # a = 1 mm is 0.1 R on the 10 mm sphere; rtol 1e-14 as in the hand-worked test above
    assert_allclose(CONTACT.small_contact_force_n, FORCE_FOR_1_MM_N, rtol=1e-14)
