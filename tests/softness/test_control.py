"""Combined CASR + DHD control (seed 001, eqs. 9.6-9.9) and the force-ramp tracking run."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.softness._checks import SoftnessError
from pinarray.softness.control import (
    SEED_EXAMPLE_MATERIAL,
    ActuatorLags,
    Material,
    ValveRange,
    control_commands,
    first_order_lag,
    simulate_force_ramp,
)
from pinarray.softness.identification import M1_R11_FORCE_AREA, M2_R14_FORCE_DISPLACEMENT
from pinarray.softness.tf_display import ConeDisplay
from tests.softness.strategies import U, log_uniform, with_zero

CASR = ConeDisplay()
CONES = st.builds(ConeDisplay, log_uniform(1e-4, 1.0), log_uniform(1e-4, 1.0))
ALPHAS_N_PER_M4 = log_uniform(1e-50, 1e50)
# alpha = 1.4e8 N/m^4 keeps the cone unbottomed up to alpha (pi R^2)^2 = 2.4665 N
UNBOTTOMED_FORCES_N = with_zero(log_uniform(1e-6, 2.4))


def test_the_seed_material_in_si_units():
    # rtol 1e-15 (9 u) here and below: a few correctly rounded operations on once-rounded
    # decimal inputs, within 6 u
    # alpha = 1.4 N/cm^4 = 1.4e8 N/m^4; beta = 1/23 cm/N = 1/2300 m/N
    assert_allclose(SEED_EXAMPLE_MATERIAL.alpha_n_per_m4, 1.4e8, rtol=1e-15)
    assert_allclose(SEED_EXAMPLE_MATERIAL.beta_m_per_n, 1 / 2300, rtol=1e-15)
    from_fits = Material.from_fits(M1_R11_FORCE_AREA, M2_R14_FORCE_DISPLACEMENT)
    assert_allclose(from_fits.alpha_n_per_m4, 1.4e8, rtol=1e-15)
    assert_allclose(from_fits.beta_m_per_n, 1 / 2300, rtol=1e-15)


def test_commands_for_one_point_four_newtons_by_hand():
    commands = control_commands(SEED_EXAMPLE_MATERIAL, 1.4)
    # A_m = sqrt(1.4 / 1.4e8) = 1e-4 m^2; p = alpha A_m = 1.4e4 Pa (eq. 9.7)
    assert_allclose(commands.material_area_m2, 1e-4, rtol=1e-15)
    assert_allclose(commands.pressure_pa, 1.4e4, rtol=1e-15)
    # z_C = (H / R) sqrt(A / pi) = (0.01 / 0.0065) * 5.6418958e-3 = 8.67983975e-3 m
    assert_allclose(commands.casr_displacement_m, 8.6798397469e-3, rtol=1e-9)
    # z_m = 1.4 / 2300 = 6.0869565e-4 m; z_D = z_m - z_C = -8.07114409e-3 m: the DHD must pull
    assert_allclose(commands.material_displacement_m, 6.086956522e-4, rtol=1e-9)
    assert_allclose(commands.dhd_displacement_m, -8.0711440947e-3, rtol=1e-9)
    assert commands.dhd_must_pull and not commands.pressure_out_of_range
    assert not commands.display_bottomed


def test_a_soft_enough_material_lets_the_dhd_push():
    # beta = 1 cm/N: z_m = 14 mm at 1.4 N, more than z_C = 8.68 mm
    commands = control_commands(Material(1.4e8, 0.01), 1.4)
    assert_allclose(commands.dhd_displacement_m, 0.014 - 8.6798397469e-3, rtol=1e-9)
    assert not commands.dhd_must_pull


@given(force=UNBOTTOMED_FORCES_N)
def test_the_casr_pushes_back_with_the_material_force_at_the_material_area(force):
    commands = control_commands(SEED_EXAMPLE_MATERIAL, force)
    assert_allclose(
        CASR.area_m2(commands.casr_displacement_m), commands.material_area_m2, rtol=1e-12
    )
    rendered = CASR.force_n(commands.pressure_pa, commands.casr_displacement_m)
    assert_allclose(rendered, force, rtol=1e-12)


@given(force=UNBOTTOMED_FORCES_N, beta=log_uniform(1e-5, 1e-1))
def test_dhd_displacement_matches_eq_9_9(force, beta):
    commands = control_commands(Material(1.4e8, beta), force)
    z_c, p = commands.casr_displacement_m, commands.pressure_pa
    # z_D = beta p pi R^2 / H^2 z_C^2 - z_C
    eq_9_9 = beta * p * np.pi * 0.0065**2 / 0.01**2 * z_c**2 - z_c
    assert_allclose(commands.dhd_displacement_m, eq_9_9, rtol=1e-9, atol=1e-15)
    assert_allclose(z_c + commands.dhd_displacement_m, beta * force, rtol=1e-9, atol=1e-15)


# Force -> A = sqrt(F / alpha) (1.5 u), p = alpha A (1 u more), z_C = (H / R) sqrt(A / pi)
# (3.5 u), A(z_C) = pi (z_C (R / H))^2 (z_C's error doubled, (H / R)(R / H) = 1 within 2 u
# and doubled, then three roundings: 15 u), F = p A(z_C) (one more): 2.5 + 15 + 1 = 18.5 u.
RENDERED_RTOL = 20 * U


@given(cone=CONES, alpha=ALPHAS_N_PER_M4, fraction=with_zero(log_uniform(1e-150, 1.0)))
def test_the_cone_renders_every_force_up_to_the_one_that_fills_it(cone, alpha, fraction):
    # up to the force at which the material's area is the cone's whole base, the display is
    # not bottomed, and at that force it is pressed to its full height
    full_n = alpha * cone.max_area_m2 * cone.max_area_m2
    force = fraction * full_n
    commands = control_commands(Material(alpha, 1e-3), force, cone, ValveRange(0, 1e300))
    assert not commands.display_bottomed
    rendered = cone.force_n(commands.pressure_pa, commands.casr_displacement_m)
    assert_allclose(rendered, force, rtol=RENDERED_RTOL)
    if fraction == 1.0:
        # A within 2.5 u of the base, pi R R within 2 u of pi R^2, halved by the root; the root,
        # the quotient under it, H / R and the product: 2.25 + 3.5 = 5.75 u
        assert_allclose(commands.casr_displacement_m, cone.height_m, rtol=6 * U)


@given(alpha=ALPHAS_N_PER_M4, low=log_uniform(1e-3, 1e3), span=log_uniform(1.01, 1e3))
def test_the_valves_own_limits_are_in_its_range(alpha, low, span):
    valve = ValveRange(low, low * span)
    material = Material(alpha, 1e-3)
    # the forces that need exactly the valve's lowest and highest pressure, p^2 / alpha
    limits_n = [valve.min_pa * valve.min_pa / alpha, valve.max_pa * valve.max_pa / alpha]
    flags = control_commands(material, limits_n, CASR, valve).pressure_out_of_range
    assert flags.tolist() == [False, False]
    # some 900 u beyond them (far past the 4 u rounding can carry a pressure): out of range
    beyond_n = [limits_n[0] * (1 - 1e-13) ** 2, limits_n[1] * (1 + 1e-13) ** 2]
    flags = control_commands(material, beyond_n, CASR, valve).pressure_out_of_range
    assert flags.tolist() == [True, True]


def test_flags_for_the_valve_range_and_a_bottomed_display():
    # p = sqrt(alpha F): 1 N -> 11832 Pa, beyond a 10 kPa valve; 0.5 N -> 8367 Pa is fine
    commands = control_commands(SEED_EXAMPLE_MATERIAL, [0.5, 1.0, 3.0], valve=ValveRange(0, 10e3))
    assert commands.pressure_out_of_range.tolist() == [False, True, True]
    # 3 N wants A = sqrt(3 / 1.4e8) = 1.464e-4 m^2 > pi R^2 = 1.327e-4 m^2
    assert commands.display_bottomed.tolist() == [False, False, True]
    # exact: the inverse maps the base area itself to the full height, not a rounding short
    assert commands.casr_displacement_m[2] == CASR.height_m


def test_a_valve_that_cannot_hold_a_small_pressure_is_flagged():
    commands = control_commands(SEED_EXAMPLE_MATERIAL, [0.0, 1e-4], valve=ValveRange(1e3, 1e5))
    assert commands.pressure_out_of_range.tolist() == [True, True]


def test_a_lag_follows_a_ramp_exactly_whatever_the_step():
    # tau x' = t - x, x(0) = 0: x(t) = t - tau + tau e^(-t/tau); tau = 0.1 s, step 0.25 s.
    # exp and expm1 (a few ulps each) in a recursion that damps by e^-2.5 a step: tens of u at
    # most, inside 1e-13 = 900 u
    time = np.arange(0, 2.01, 0.25)
    expected = time - 0.1 + 0.1 * np.exp(-time / 0.1)
    assert_allclose(first_order_lag(time, 0.25, 0.1), expected, rtol=1e-13, atol=1e-15)


def test_a_lag_on_a_curved_command_converges_at_second_order():
    def error(step):
        time = np.arange(0, 1 + step / 2, step)
        # tau x' = sin(w t) - x, x(0) = 0, tau = 0.05, w = 2 pi: exact solution below
        tau, w = 0.05, 2 * np.pi
        exact = (np.sin(w * time) - w * tau * np.cos(w * time) + w * tau * np.exp(-time / tau)) / (
            1 + (w * tau) ** 2
        )
        return np.max(np.abs(first_order_lag(np.sin(w * time), step, tau) - exact))

    assert error(0.01) / error(0.005) > 3.5


def test_an_ideal_system_tracks_the_material_exactly():
    run = simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 1.0, 1e-3, lags=ActuatorLags(0, 0))
    assert run.time_s.size == 1001
    assert_allclose(run.rendered_area_m2, run.commands.material_area_m2, rtol=1e-12, atol=1e-20)
    assert_allclose(
        run.rendered_displacement_m, run.commands.material_displacement_m, rtol=1e-9, atol=1e-15
    )


def test_lagging_actuators_leave_a_tracking_error_that_shrinks_with_the_lag():
    def worst_error(lag_s):
        run = simulate_force_ramp(
            SEED_EXAMPLE_MATERIAL, 2.0, 1.0, 1e-3, lags=ActuatorLags(lag_s, lag_s)
        )
        return np.max(np.abs(run.displacement_error_m[run.time_s > 0.2]))

    assert worst_error(0.05) > worst_error(0.005) > 0


def test_a_saturated_valve_makes_the_display_too_soft():
    run = simulate_force_ramp(
        SEED_EXAMPLE_MATERIAL, 2.0, 1.0, 1e-3, valve=ValveRange(0, 5e3), lags=ActuatorLags(0, 0)
    )
    flagged = run.commands.pressure_out_of_range
    assert flagged.any() and not flagged.all()
    # where the valve caps the pressure the same force spreads over a larger area
    assert np.all(run.area_error_m2[flagged] > 0)
    assert np.all(run.pressure_pa <= 5e3)


@given(step=st.floats(1e-4, 0.5))
def test_the_ramp_starts_at_zero_and_ends_at_the_peak(step):
    run = simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 1.0, step)
    assert run.commands.force_n[0] == 0.0
    assert_allclose(run.commands.force_n[-1], 2.0)
    assert run.time_s[-1] == 1.0  # exact: linspace sets its last sample to the stop itself
    assert np.all(np.isfinite(run.rendered_displacement_m))


def test_bad_runs_are_rejected():
    with pytest.raises(SoftnessError, match="longer than the ramp"):
        simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 1.0, 2.0)
    with pytest.raises(SoftnessError, match="peak_force_n"):
        simulate_force_ramp(SEED_EXAMPLE_MATERIAL, np.nan, 1.0, 0.01)
    with pytest.raises(SoftnessError, match="min_pa < max_pa"):
        ValveRange(2e4, 1e4)
    with pytest.raises(SoftnessError, match="beta_m_per_n"):
        Material(1e8, -1.0)


def test_the_start_up_lasts_five_time_constants_of_the_slower_actuator():
    run = simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 2.0, 1e-3,
                              lags=ActuatorLags(valve_s=0.02, dhd_s=0.01))
    assert run.startup_s == pytest.approx(0.1, rel=4 * U)  # 5 * 0.02: one rounding
    assert np.array_equal(run.in_startup, run.time_s < run.startup_s)


def test_ideal_actuators_have_no_start_up():
    run = simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 2.0, 1e-3, lags=ActuatorLags(0.0, 0.0))
    assert run.startup_s == 0.0
    assert not run.in_startup.any()


def test_the_first_touch_sinks_a_display_whose_valve_lags_and_only_in_the_start_up():
    # 1 ms in, the command is 374 Pa (sqrt(alpha * 1 mN)) and a 20 ms valve holds 9 Pa: 1 mN
    # presses the cone towards its base. After five lags the area is back near the material's.
    run = simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 2.0, 1e-3)
    desired = run.commands.material_area_m2
    assert run.rendered_area_m2[1] > 0.5 * CASR.max_area_m2 > 10 * desired[1]
    # a lag behind a square-root command errs by about tau / 2t: 10 % at t = 5 tau, then less
    settled = ~run.in_startup
    assert np.all(run.rendered_area_m2[settled] <= 1.2 * desired[settled])
