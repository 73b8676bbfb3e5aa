"""The telescopic display (seed 000, 4.2): a staircase F_i = p_0 A_i, and pressures that
make it follow a tissue's force/area curve."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.softness._checks import SoftnessError
from pinarray.softness.telescopic import TelescopicDisplay, staircase_points
from tests.softness.strategies import FEW_ULPS, U, log_uniform

# A_0 = 10 mm^2, each cylinder doubles the area, a new one every 1 mm, four cylinders.
DISPLAY = TelescopicDisplay(
    central_area_m2=1e-5, area_ratio=2.0, step_height_m=1e-3, cylinder_count=4
)


def test_areas_grow_by_the_ratio_on_each_step():
    # dA^i is numpy's power (FEW_ULPS), times A_0 (one rounding)
    assert_allclose(
        DISPLAY.step_areas_m2, [1e-5, 2e-5, 4e-5, 8e-5], rtol=(2 * FEW_ULPS + 1) * U
    )


def test_the_finger_meets_one_more_cylinder_every_step_height():
    # 0.5 mm: central only; 1.5 mm: second; 3.5 mm: fourth; 10 mm: still the fourth (the last)
    assert_allclose(
        DISPLAY.area_m2([0.0, 0.5e-3, 1.5e-3, 3.5e-3, 10e-3]), [1e-5, 1e-5, 2e-5, 8e-5, 8e-5]
    )


def test_a_constant_pressure_gives_a_force_staircase():
    # 10 kPa: F_i = 1e4 * A_i = 0.1, 0.2, 0.4, 0.8 N
    assert_allclose(DISPLAY.force_n(1e4, [0.5e-3, 1.5e-3, 2.5e-3, 3.5e-3]), [0.1, 0.2, 0.4, 0.8])


def test_a_pressure_schedule_puts_every_step_on_the_target_curve():
    def target(area):  # F = 1e4 A + 1e9 A^2
        return 1e4 * area + 1e9 * area**2

    # p_i = F(A_i) / A_i = 1e4 + 1e9 A_i = 2e4, 3e4, 5e4, 9e4 Pa (a few roundings each: 1e-14
    # is 90 u; the best constant pressure adds two dot products of four terms: 1e-13 is 900 u)
    assert_allclose(DISPLAY.pressure_schedule_pa(target), [2e4, 3e4, 5e4, 9e4], rtol=1e-14)
    # one pressure for all: sum F_i A_i / sum A_i^2 with F_i = 0.2, 0.6, 2.0, 7.2 N:
    # (2e-6 + 1.2e-5 + 8e-5 + 5.76e-4) / (1e-10 * (1 + 4 + 16 + 64)) = 6.7e-4 / 8.5e-9
    assert_allclose(DISPLAY.best_constant_pressure_pa(target), 6.7e-4 / 8.5e-9, rtol=1e-13)


@given(
    area=st.floats(1e-7, 1e-4),
    ratio=st.floats(1.01, 4.0),
    count=st.integers(1, 12),
    pressure=st.floats(1.0, 1e6),
)
def test_force_never_falls_as_the_finger_goes_deeper(area, ratio, count, pressure):
    display = TelescopicDisplay(area, ratio, 1e-3, count)
    depth = np.linspace(0, 1.5e-3 * count, 200)
    assert np.all(np.diff(display.force_n(pressure, depth)) >= 0)


@given(
    step=log_uniform(1e-6, 1.0),
    count=st.integers(1, 300),
    ratio=st.floats(1.01, 4.0),
    pressure=log_uniform(1e-3, 1e6),
)
def test_each_step_starts_where_the_staircase_says_it_does(step, count, ratio, pressure):
    # The staircase's own corner i dh is on step i, not a rounding step short of it; past the
    # last step the finger stays on the last cylinder.
    display = TelescopicDisplay(1e-5, ratio, step, count)
    depth, force = staircase_points(display, pressure)
    starts = depth[::2]
    assert display.step_index(starts).tolist() == list(range(count))
    assert display.step_index(starts[-1] + 10 * step) == count - 1
    # the display's force at each corner is the staircase's: p A_i, exactly the same product
    assert (display.force_n(pressure, starts) == force[::2]).all()


@given(step=log_uniform(1e-6, 1.0), count=st.integers(1, 50), scale=log_uniform(1e-100, 1e100))
def test_a_pressure_schedule_puts_the_target_force_on_each_step_from_its_first_depth(
    step, count, scale
):
    display = TelescopicDisplay(1e-5, 1.5, step, count)

    def target(area):
        return scale * area * (1 + area)

    starts = np.arange(count) * step
    rendered = display.force_n(display.pressure_schedule_pa(target), starts)
    # (F / A) A rounds twice
    assert_allclose(rendered, target(display.step_areas_m2), rtol=3 * U)


def test_staircase_points_trace_each_step_flat():
    depth, force = staircase_points(DISPLAY, 1e4)
    assert_allclose(depth, [0, 1e-3, 1e-3, 2e-3, 2e-3, 3e-3, 3e-3, 4e-3])
    assert_allclose(force, [0.1, 0.1, 0.2, 0.2, 0.4, 0.4, 0.8, 0.8])


def test_impossible_displays_are_rejected():
    with pytest.raises(SoftnessError, match="area_ratio must be greater than 1"):
        TelescopicDisplay(1e-5, 1.0, 1e-3, 3)
    with pytest.raises(SoftnessError, match="cylinder_count"):
        TelescopicDisplay(1e-5, 2.0, 1e-3, 0)
    with pytest.raises(SoftnessError, match="step_height_m"):
        TelescopicDisplay(1e-5, 2.0, -1e-3, 3)
    with pytest.raises(SoftnessError, match="indentation_m"):
        DISPLAY.area_m2(np.nan)
    # 20 mm^2 grown by 1e9 a step: the 36th cylinder would be past the largest float.
    with pytest.raises(SoftnessError, match=r"below 10\^308 m\^2 .*found 10\^310 m\^2"):
        TelescopicDisplay(20e-6, 1e9, 1e-3, 36)


def test_the_best_single_pressure_of_a_display_near_the_largest_float_is_finite():
    # Its 35th cylinder is 2 10^301 m^2: the squares the fit sums would overflow unscaled.
    display = TelescopicDisplay(20e-6, 1e9, 1e-3, 35)
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        assert display.best_constant_pressure_pa(lambda areas: 2.0 * areas) == \
            pytest.approx(2.0, rel=1e-12)
