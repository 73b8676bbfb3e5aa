"""The simulated horn's motion: a closed-form trapezoid that respects speed, acceleration, lash."""

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from pinarray.hardware.feetech.models import STS3215_C001, STS3215_C018
from pinarray.hardware.feetech.registers import Register, to_bytes
from pinarray.hardware.feetech.sim_motion import NS_PER_S, Drive, MotionState, plan_move
from pinarray.hardware.feetech.sim_servo import SimServo

from ..strategies import positions_steps, servo_drives


def at_rest(position: float) -> MotionState:
    return MotionState(position, 0.0, position)


def sampled(move, start_ns: int, end_ns: int, count: int = 400):
    times = np.unique(np.linspace(start_ns, end_ns, count).astype(np.int64))
    return times, np.array([move.state_at(int(t)).horn_steps for t in times])


@given(servo_drives(), positions_steps, positions_steps)
def test_the_horn_ends_on_its_goal_and_never_outruns_the_servo(drive, start, goal):
    move = plan_move(0, at_rest(start), goal, drive)
    assert math.isclose(move.state_at(move.end_ns + 1).horn_steps, goal, abs_tol=1e-6)
    times, horn = sampled(move, 0, move.end_ns + 1_000_000)
    speeds = np.abs(np.diff(horn)) / (np.diff(times) / NS_PER_S)
    assert speeds.max(initial=0.0) <= drive.up_speed_steps_per_s * (1 + 1e-4)  # ns rounding of piece starts
    for piece in move.pieces:
        assert abs(piece.accel_steps_per_s2) <= drive.accel_steps_per_s2 * (1 + 1e-9)
        assert abs(piece.speed_steps_per_s) <= drive.up_speed_steps_per_s * (1 + 1e-9)


@given(servo_drives(), st.sampled_from((-1, 0, 1)), positions_steps, positions_steps,
       positions_steps, st.integers(0, 10**9), st.integers(-10**6, 2 * 10**9))
def test_the_encoder_reads_the_horn_of_the_motion_state(drive, load, start, first, goal,
                                                        switch_ns, time_ns):
    # `horn_at` (every sample asks it) is `state_at`'s horn to the last bit, also on a move
    # started mid-way through another (lash taken up or not, a load pressing one side).
    drive = drive._replace(load_direction=load)
    move = plan_move(0, at_rest(start), first, drive)
    move = plan_move(switch_ns, move.state_at(switch_ns), goal, drive)
    assert move.horn_at(time_ns) == move.state_at(time_ns).horn_steps


@given(servo_drives(lash=False), positions_steps, positions_steps)
def test_without_lash_a_move_takes_the_trapezoid_time(drive, start, goal):
    v, a, d = drive.up_speed_steps_per_s, drive.accel_steps_per_s2, abs(goal - start)
    expected_s = d / v + v / a if d >= v * v / a else 2 * math.sqrt(d / a)
    move = plan_move(0, at_rest(start), goal, drive)
    assert math.isclose(move.end_ns / NS_PER_S, expected_s, rel_tol=1e-6, abs_tol=2e-9)


@given(servo_drives(), positions_steps, positions_steps, st.floats(0.01, 0.99))
def test_replanning_mid_move_to_the_same_goal_changes_nothing(drive, start, goal, share):
    first = plan_move(0, at_rest(start), goal, drive)
    switch_ns = round(first.end_ns * share)
    again = plan_move(switch_ns, first.state_at(switch_ns), goal, drive)
    for t in np.linspace(switch_ns, first.end_ns + 1000, 25).astype(np.int64):
        assert math.isclose(
            again.state_at(int(t)).horn_steps, first.state_at(int(t)).horn_steps, abs_tol=1e-3
        )


@given(servo_drives(), positions_steps, positions_steps, positions_steps, st.floats(0.0, 1.0))
def test_a_new_goal_mid_move_bends_the_path_without_a_jump(drive, start, goal, other, share):
    first = plan_move(0, at_rest(start), goal, drive)
    switch_ns = round(first.end_ns * share)
    before = first.state_at(switch_ns)
    second = plan_move(switch_ns, before, other, drive)
    assert math.isclose(second.state_at(switch_ns).horn_steps, before.horn_steps, abs_tol=1e-6)
    assert math.isclose(second.state_at(switch_ns).speed_steps_per_s, before.speed_steps_per_s,
                        rel_tol=1e-9, abs_tol=1e-6)
    assert math.isclose(second.final.horn_steps, other, abs_tol=1e-6)
    times, horn = sampled(second, switch_ns, second.end_ns + 100_000)
    speeds = np.abs(np.diff(horn)) / (np.diff(times) / NS_PER_S)
    assert speeds.max(initial=0.0) <= drive.up_speed_steps_per_s * (1 + 1e-4)  # ns rounding of piece starts


def test_after_a_reversal_the_horn_waits_while_the_gears_take_up_the_lash():
    drive = Drive(3000.0, 3000.0, 1e9, lash_steps=12.0)  # near-instant acceleration
    up = plan_move(0, at_rest(2048.0), 2148.0, drive)
    down = plan_move(up.end_ns, up.state_at(up.end_ns), 2048.0, drive)
    lash_ns = round(12.0 / 3000.0 * NS_PER_S)  # 4 ms of drive travel moves nothing
    # == holds on any machine: the horn is held at the goal the move snapped it to, and the
    # drive is still 0.3 steps inside the lash, far from rounding
    assert down.state_at(up.end_ns + lash_ns - 100_000).horn_steps == 2148.0
    assert down.state_at(up.end_ns + lash_ns + 1_000_000).horn_steps < 2148.0
    assert math.isclose(down.final.horn_steps, 2048.0)


def test_a_steady_load_keeps_the_lash_on_one_side_and_slows_motion_against_it():
    free = Drive(3000.0, 3000.0, 1e6, 12.0, load_direction=0)
    loaded = Drive(1500.0, 3000.0, 1e6, 12.0, load_direction=-1)
    t_free = plan_move(0, at_rest(1000.0), 3000.0, free).end_ns
    t_up = plan_move(0, MotionState(1006.0, 0.0, 1000.0), 3000.0, loaded).end_ns
    t_down = plan_move(0, MotionState(3006.0, 0.0, 3000.0), 1000.0, loaded).end_ns
    assert math.isclose(t_up / t_free, 2.0, rel_tol=0.02)
    assert math.isclose(t_down / t_free, 1.0, rel_tol=0.02)


def full_speed_turn_s(model, degrees: float, supply_v: float | None = None) -> float:
    """Time a servo at goal speed 0 and acceleration 0 needs to turn ``degrees`` from rest."""
    servo = SimServo(1, 0, position_steps=0, model=model, backlash_steps=0, supply_v=supply_v)
    goal = round(degrees * 4096 / 360)
    servo.write(Register.GOAL_POSITION.address, to_bytes(goal, 2), 0)
    return servo._move.end_ns / NS_PER_S


def test_a_60_degree_turn_takes_the_datasheets_0_222_s_plus_the_motors_spin_up():
    spin_up_s = STS3215_C001.spin_up_s
    assert math.isclose(full_speed_turn_s(STS3215_C001, 60), 0.222 + spin_up_s, rel_tol=0.01)
    assert math.isclose(STS3215_C001.speed_steps_per_s, 3075, rel_tol=0.001)


def test_speed_follows_the_supply_voltage_and_the_12v_variant_is_as_fast_at_12v():
    at_nominal = full_speed_turn_s(STS3215_C001, 180)
    at_6v = full_speed_turn_s(STS3215_C001, 180, supply_v=6.0)
    assert at_6v > at_nominal * 1.15
    assert math.isclose(full_speed_turn_s(STS3215_C018, 180), at_nominal, rel_tol=1e-6)
