"""The schedule compiler: exact pulse trains, changed-only servo targets, waves, dense output."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.errors import PinArrayError
from pinarray.grid import Grid
from pinarray.protocol import (
    NS_PER_S,
    Device,
    PinCalibration,
    PinDrive,
    ServoSettings,
    Train,
    Wave,
    WaveKind,
)
from pinarray.schedule import compile_drives, render_dense, train_pulses

UP, DOWN, REST = 2162, 2048, 2048


def device(rows: int = 4, columns: int = 4, speed: int = 3000, scale: bool = False) -> Device:
    grid = Grid(rows, columns)
    pins = tuple(
        PinCalibration(p, p, REST, 2000, 2200, ((1_500_000, DOWN), (2_000_000, UP)))
        for p in grid.pins
    )
    return Device(grid, ServoSettings(speed_steps_per_s=speed), pins, scale_infeasible=scale)


def seed_train(frequency_hz, duration_s=10, phase=Fraction(0)) -> Train:
    return Train(Fraction(frequency_hz), int(Fraction(duration_s) * NS_PER_S), phase=phase)


def exact_start_ns(k: int, train: Train) -> int:
    """Pulse k's start as an exact rational, rounded once (halves up), computed independently."""
    t = (
        (k + train.phase * train.pulses_per_cycle)
        * Fraction(NS_PER_S)
        / (train.frequency_hz * train.pulses_per_cycle)
    )
    return int((2 * t + 1) // 2)


def test_the_seed_train_at_10_hz_is_1000_pulses_of_which_half_lift_the_pin():
    schedule = compile_drives([PinDrive(10, seed_train(10))], device())
    assert len(schedule.pulses) == 1000  # 10 s x 10 cycles/s x 10 pulses
    widths = schedule.pulses.width_ns.reshape(100, 10)
    assert (widths[:, :5] == 2_000_000).all() and (widths[:, 5:] == 1_500_000).all()
    assert schedule.pulses.start_ns[:3].tolist() == [0, 10_000_000, 20_000_000]


def test_servo_targets_hold_only_changes_two_per_cycle_ending_at_rest():
    schedule = compile_drives([PinDrive(10, seed_train(10))], device())
    targets = schedule.targets
    assert len(targets) == 200  # up and down once per cycle, 100 cycles
    assert targets.time_ns[:4].tolist() == [0, 50_000_000, 100_000_000, 150_000_000]
    assert targets.position_steps[:4].tolist() == [UP, DOWN, UP, DOWN]
    assert targets.position_steps[-1] == REST
    assert (np.diff(targets.position_steps) != 0).all()


def test_a_third_of_a_hertz_stays_exact_for_a_whole_day():
    train = seed_train(Fraction(1, 3), duration_s=24 * 3600)
    starts, widths, _ = train_pulses(train)
    assert len(starts) == 24 * 3600 * 10 // 3  # 28 800 cycles x 10 pulses
    last = len(starts) - 1
    assert starts[-1] == exact_start_ns(last, train)  # 0 ns error after 86 400 s
    assert starts[-1] == 86_399_700_000_000  # 287 999 x 0.3 s
    assert starts[-1] + widths[-1] <= train.duration_ns


def test_a_tenth_of_a_hertz_is_not_a_binary_float():
    train = seed_train(Fraction(1, 10), duration_s=24 * 3600)
    starts, _, _ = train_pulses(train)
    assert starts[1] == 1_000_000_000 and starts[-1] == 86_399 * 10**9


def test_exotic_decimals_fall_back_to_exact_big_integers():
    train = seed_train(Fraction("3.14159"), duration_s=60)
    starts, _, _ = train_pulses(train)
    assert [int(s) for s in starts[-3:]] == [
        exact_start_ns(k, train) for k in range(len(starts) - 3, len(starts))
    ]


def test_phase_delays_the_pattern_and_wraps_at_a_full_cycle():
    quarter = seed_train(10, 1, Fraction(1, 4))
    starts, _, is_up = train_pulses(quarter)
    # a quarter cycle = 2.5 slots: the first pulse is k=-2 at 5 ms, still in the previous cycle's
    # down part; the first up pulse (k=0) comes at 25 ms
    assert starts[0] == 5_000_000 and not is_up[0]
    assert starts[is_up][0] == 25_000_000


@settings(max_examples=60, deadline=None)
@given(
    # frequencies p/q Hz whose slot is a whole number of ns for some whole number of cycles
    numerator=st.integers(1, 2000),
    denominator=st.sampled_from([1, 2, 3, 4, 5, 8, 10, 100]),
    cycles=st.integers(1, 30),
    per_cycle=st.sampled_from([2, 4, 10]),
)
def test_pulse_counts_equal_duration_times_rate_exactly(numerator, denominator, cycles, per_cycle):
    frequency = Fraction(numerator, 100 * denominator)
    # scale the cycle count so that the duration is a whole number of nanoseconds
    cycles *= (Fraction(cycles) / frequency * NS_PER_S).denominator
    duration = Fraction(cycles) / frequency
    train = Train(frequency, int(duration * NS_PER_S), per_cycle, per_cycle // 2, 1000, 500)
    starts, widths, _ = train_pulses(train)
    assert len(starts) == cycles * per_cycle
    assert (np.diff(starts) > 0).all()
    assert (starts + widths <= train.duration_ns).all()
    assert all(int(s) == exact_start_ns(k, train) for k, s in enumerate(starts[:5]))


@settings(max_examples=60, deadline=None)
@given(
    phase_deg=st.integers(0, 3 * 360),
    frequency=st.sampled_from([Fraction(3), Fraction(5), Fraction(10), Fraction(1, 3)]),
)
def test_phases_are_exact_and_no_event_lies_beyond_the_signal_length(phase_deg, frequency):
    train = seed_train(frequency, 3, Fraction(phase_deg, 360) % 1)
    schedule = compile_drives([PinDrive(3, train, delay_ns=7)], device())
    p = schedule.pulses
    first_k = -int(train.phase * train.pulses_per_cycle)
    assert p.start_ns[0] == 7 + exact_start_ns(first_k, train)
    assert (p.start_ns >= 7).all() and (p.start_ns + p.width_ns <= 7 + train.duration_ns).all()
    assert schedule.targets.time_ns.max() <= 7 + train.duration_ns
    assert (p.width_ns <= train.slot_ns).all()


def test_a_rightwards_wave_starts_each_pin_one_soa_after_its_left_neighbour():
    wave = Wave(WaveKind.RIGHTWARDS, 2, (5, 6, 7), seed_train(5, Fraction(2, 5)), 175_300_000)
    schedule = compile_drives(wave.drives(), device())
    first = {pin: int(schedule.pulses.start_ns[schedule.pulses.pin == pin][0]) for pin in (5, 6, 7)}
    assert first == {5: 0, 6: 175_300_000, 7: 350_600_000}


def test_a_leftwards_wave_mirrors_it_and_the_no_wave_alternates_centre_and_sides():
    train = seed_train(5, Fraction(2, 5))
    left = Wave(WaveKind.LEFTWARDS, 2, (5, 6, 7), train, 100_000_000).drives()
    assert [(d.pin, d.delay_ns) for d in left] == [(7, 0), (6, 100_000_000), (5, 200_000_000)]
    still = Wave(WaveKind.NONE, 2, (5, 6, 7), train, 250_000_000).drives()
    assert [(d.pin, d.delay_ns) for d in still] == [
        (6, 0),
        (5, 250_000_000),
        (7, 250_000_000),
        (6, 500_000_000),
    ]


def test_a_pin_driven_twice_at_once_is_refused():
    still = Wave(WaveKind.NONE, 2, (5, 6, 7), seed_train(5, Fraction(2, 5)), 100_000_000)
    with pytest.raises(PinArrayError, match="pin 6 is driven twice at once"):
        compile_drives(still.drives(), device())


def test_back_to_back_trains_on_one_pin_send_no_redundant_targets():
    train = seed_train(5, Fraction(2, 5))
    schedule = compile_drives(
        [PinDrive(6, train, 0), PinDrive(6, train, train.duration_ns)], device()
    )
    positions = schedule.targets.position_steps
    assert (np.diff(positions) != 0).all()
    assert len(schedule.targets) == 8  # 4 cycles, up and down each


def test_idle_pins_and_array_size_cost_nothing():
    small = compile_drives([PinDrive(1, seed_train(10))], device(4, 4))
    large = compile_drives([PinDrive(1, seed_train(10))], device(64, 64))
    assert len(small.pulses) == len(large.pulses) and len(small.targets) == len(large.targets)
    assert set(large.targets.pin.tolist()) == {1}


def test_an_unfollowable_stroke_is_scaled_when_the_protocol_allows():
    # 40 Hz: a half-cycle of 12.5 ms at 3000 steps/s reaches 37.5 of the 114 steps
    schedule = compile_drives([PinDrive(2, seed_train(40, 1))], device(scale=True))
    assert set(schedule.targets.position_steps.tolist()) == {DOWN + 37, DOWN}


def test_dense_rendering_moves_each_edge_by_less_than_one_sample():
    train = seed_train(Fraction(1, 3) * 10, 3)
    schedule = compile_drives([PinDrive(4, train)], device())
    rate_hz = 10_000
    dense = render_dense(schedule.pulses, [4, 5], rate_hz, schedule.end_ns)
    assert not dense[1].any()  # an idle pin stays low
    rising = np.flatnonzero(np.diff(dense[0].astype(int)) == 1) + 1
    if dense[0][0]:
        rising = np.concatenate(([0], rising))
    sample_ns = NS_PER_S / rate_hz
    errors_ns = rising * sample_ns - schedule.pulses.start_ns
    assert len(rising) == len(schedule.pulses)
    assert (errors_ns >= 0).all() and (errors_ns < sample_ns).all()
