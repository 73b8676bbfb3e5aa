"""The CASR cone display (seed 001, 9.4.1): A(z), the volume law, F = p A and its inverses."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.softness._checks import SoftnessError
from pinarray.softness.tf_display import ConeDisplay
from tests.softness.strategies import U, log_uniform, pressures_pa, with_zero

CASR = ConeDisplay()  # R = 6.5 mm, H = 10 mm as in the seed
CONES = st.builds(ConeDisplay, log_uniform(1e-4, 1.0), log_uniform(1e-4, 1.0))

# rtol 1e-14 (90 u) and 1e-13 below: every formula here is a handful of correctly rounded
# operations (products, quotients, sqrt), within 10 u.


def test_area_at_half_and_full_indentation():
    # z = 5 mm: pi (z R / H)^2 = pi (3.25e-3)^2 = pi * 1.05625e-5 = 3.318307e-5 m^2
    assert_allclose(CASR.area_m2(0.005), 3.3183072403542196e-05, rtol=1e-14)
    # z = H: the whole base, pi R^2 = pi * 4.225e-5 = 1.327323e-4 m^2
    assert_allclose(CASR.area_m2(0.01), 1.3273228961416876e-04, rtol=1e-14)
    assert CASR.max_area_m2 == pytest.approx(1.3273228961416876e-04, rel=1e-14)


def test_force_is_pressure_times_area_eq_9_3():
    # 20 kPa at z = 5 mm: 2e4 * 3.3183072e-5 = 0.66366145 N
    assert_allclose(CASR.force_n(20e3, 0.005), 0.6636614480708439, rtol=1e-14)


def test_the_two_inverse_problems_on_the_hand_worked_point():
    force = 0.6636614480708439
    assert_allclose(CASR.indentation_for_force_m(force, 20e3), 0.005, rtol=1e-14)
    assert_allclose(CASR.pressure_for_force_pa(force, 0.005), 20e3, rtol=1e-14)


@given(z_fraction=st.floats(0.01, 0.99))
def test_force_is_minus_pressure_times_volume_rate_eq_9_2(z_fraction):
    # Virtual work: F dz = p dV, so dV/dz of the swept volume must equal A(z).
    z = z_fraction * CASR.height_m
    h = 1e-7
    rate = (CASR.swept_volume_m3(z + h) - CASR.swept_volume_m3(z - h)) / (2 * h)
    assert_allclose(rate, CASR.area_m2(z), rtol=1e-6)


@given(z_fraction=with_zero(st.floats(1e-9, 1.0)), pressure=pressures_pa)
def test_indentation_round_trips_through_force_down_to_nanometres(z_fraction, pressure):
    z = z_fraction * CASR.height_m
    force = CASR.force_n(pressure, z)
    assert_allclose(CASR.indentation_for_force_m(force, pressure), z, rtol=1e-13)
    if z > 0:
        assert_allclose(CASR.pressure_for_force_pa(force, z), pressure, rtol=1e-13)


@given(radius=st.floats(1e-3, 0.1), height=st.floats(1e-3, 0.1), z_fraction=st.floats(0, 1))
def test_area_round_trips_for_any_cone(radius, height, z_fraction):
    display = ConeDisplay(radius, height)
    z = z_fraction * height
    assert_allclose(display.indentation_for_area_m(display.area_m2(z)), z, rtol=1e-13, atol=1e-18)


@given(cone=CONES)
def test_the_base_area_is_exactly_the_full_height(cone):
    assert cone.indentation_for_area_m(cone.max_area_m2) == cone.height_m


# z -> A(z) = pi (z R / H)^2 -> z = (H / R) sqrt(A / pi): A rounds four times, the first two
# squared (6 u), and the way back rounds the quotient (halved under the root), the root, H / R
# and the product: 3.5 + 1 + 2 = 6.5 u. Through a force F = p A and back A = F / p, 1 u more.
ROUND_TRIP_RTOL = 8 * U


@given(cone=CONES, pressure=log_uniform(1e-150, 1e150))
def test_the_full_height_comes_back_through_its_area_and_its_force(cone, pressure):
    height = cone.height_m
    by_area = cone.indentation_for_area_m(cone.area_m2(height))
    force = cone.force_n(pressure, height)
    by_force = cone.indentation_for_force_m(force, pressure)
    for depth in (by_area, by_force):
        assert_allclose(depth, height, rtol=ROUND_TRIP_RTOL)
        cone.area_m2(depth)  # the forward function takes it
    # F / A(H) with F = p A(H): two roundings
    assert_allclose(cone.pressure_for_force_pa(force, height), pressure, rtol=3 * U)


@given(cone=CONES)
def test_areas_truly_past_the_base_are_still_refused(cone):
    # 1e-13 is some 900 u past the base: far beyond the 10 u rounding can carry an area
    with pytest.raises(SoftnessError, match="base area"):
        cone.indentation_for_area_m(cone.max_area_m2 * (1 + 1e-13))


@given(z_fraction=log_uniform(1e-50, 1.0), pressure=log_uniform(1e-150, 1e150))
def test_tiny_and_huge_pressures_and_depths_come_back(z_fraction, pressure):
    z = z_fraction * CASR.height_m
    force = CASR.force_n(pressure, z)
    assert_allclose(CASR.indentation_for_force_m(force, pressure), z, rtol=ROUND_TRIP_RTOL)
    assert_allclose(CASR.pressure_for_force_pa(force, z), pressure, rtol=3 * U)
    assert CASR.indentation_for_force_m(0.0, pressure) == 0.0
    assert CASR.pressure_for_force_pa(0.0, z) == 0.0


def test_arrays_broadcast_pressures_against_indentations():
    forces = CASR.force_n(np.array([[10e3], [20e3]]), np.array([0.0, 0.005, 0.01]))
    assert forces.shape == (2, 3)
    assert forces[0, 0] == 0.0
    # doubling is exact in binary floating point: 2e4 A rounds to exactly twice 1e4 A
    assert_allclose(forces[1], 2 * forces[0], rtol=1e-15)


def test_no_force_needs_no_pressure_even_at_zero_indentation():
    assert CASR.pressure_for_force_pa(0.0, 0.0) == 0.0


def test_a_force_at_zero_indentation_is_impossible():
    with pytest.raises(SoftnessError, match="unbounded"):
        CASR.pressure_for_force_pa(1.0, 0.0)


def test_the_display_cannot_be_pressed_past_its_height():
    with pytest.raises(SoftnessError, match="at most the display height"):
        CASR.area_m2(0.011)
    # 1 N at 1 kPa needs 1e-3 m^2, far beyond the 1.33e-4 m^2 base
    with pytest.raises(SoftnessError, match="base area"):
        CASR.indentation_for_force_m(1.0, 1e3)


@pytest.mark.parametrize("bad", [np.nan, -1.0, np.inf])
def test_bad_pressures_are_rejected(bad):
    with pytest.raises(SoftnessError, match="pressure_pa"):
        CASR.force_n(bad, 0.005)


def test_the_largest_force_at_a_pressure_is_with_the_display_pressed_to_its_base():
    # 10 kPa over pi (6.5 mm)^2 = 1.327323e-4 m^2: 1.327323 N
    assert_allclose(CASR.max_force_n(10e3), 1.3273228961416876, rtol=1e-14)
    assert not CASR.balances(2.0, 10e3)
    assert CASR.balances(2.0, 20e3)


@given(pressure=with_zero(pressures_pa), ulps=st.integers(-40, 40))
def test_a_force_balances_exactly_when_the_indentation_can_be_solved(pressure, ulps):
    # forces within a few dozen ulps either side of the largest: the edge the two must share
    force = float(CASR.max_force_n(pressure)) * (1 + ulps * U)
    if not CASR.balances(force, pressure):
        with pytest.raises(SoftnessError):
            CASR.indentation_for_force_m(force, pressure)
    elif pressure > 0:
        assert CASR.indentation_for_force_m(force, pressure) <= CASR.height_m
    else:
        assert force == 0.0  # an empty display balances nothing but no force
