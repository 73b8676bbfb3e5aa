"""The schedule compiler: exact pulse trains, changed-only servo targets, waves, dense output."""

import math
import tracemalloc
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
from pinarray.protocol.feasibility import check_train
from pinarray.schedule import compile_drives, pulse_indices, render_dense, train_pulses

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


@pytest.mark.parametrize(
    "frequency_hz",
    [
        "3.14159",  # pulse times over a denominator in the millions: exact in 64 bits, split
        "3.1415926535",  # over one past 2**31 (5.6e10): exact in Python's big integers
    ],
)
def test_exotic_decimals_stay_exact_to_the_nanosecond(frequency_hz):
    train = seed_train(Fraction(frequency_hz), duration_s=60, phase=Fraction(7, 360))
    starts, _, _ = train_pulses(train)
    first = int(pulse_indices(train)[0])
    assert [int(s) for s in starts] == [
        exact_start_ns(first + i, train) for i in range(len(starts))
    ]


def test_a_quarter_phase_starts_inside_the_previous_cycle_s_down_part():
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
    with pytest.raises(PinArrayError, match="found pin 6 driven twice at once"):
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
    sample_ns = NS_PER_S / rate_hz  # 1e5 exactly; whole multiples of it are exact floats
    errors_ns = rising * sample_ns - schedule.pulses.start_ns
    assert len(rising) == len(schedule.pulses)
    assert (errors_ns >= 0).all() and (errors_ns < sample_ns).all()


# --- The compiler against a plain reference: one pulse at a time, exact fractions. ---

WIDTHS_NS = (1_000_000, 1_500_000, 2_000_000)


def varied_device(scale: bool = False) -> Device:
    """Pins that differ a little, as real ones do; a 1 ms pulse holds a pin at its rest."""
    grid = Grid(4, 4)
    pins = tuple(
        PinCalibration(
            p,
            p,
            REST + p % 3,
            1900,
            2300,
            ((1_000_000, REST + p % 3), (1_500_000, DOWN), (2_000_000, UP + p)),
        )
        for p in grid.pins
    )
    return Device(grid, ServoSettings(speed_steps_per_s=3000), pins, scale_infeasible=scale)


def reference_schedule(drives, dev: Device):
    """Every pulse and target change the lab would write down by hand, pulse by pulse.

    Pulse k of a train starts at the exact rational time, rounded once; a pulse counts when
    it starts at or after the drive's onset and ends within its signal. Each pin's targets are
    the position of each pulse plus rest at each drive's end, in time order; where two fall
    on one instant the drive that begins later wins; only changes from the previous position
    (rest at first) are kept.
    """
    pulses, raw = [], {}
    for drive in drives:
        train, calibration = drive.train, dev.calibration(drive.pin)
        up = calibration.position_for_width(train.up_width_ns)
        down = calibration.position_for_width(train.down_width_ns)
        if dev.scale_infeasible:
            fraction = check_train(train, calibration, dev).amplitude_fraction
            up = down + int((up - down) * fraction)
        k = -math.floor(train.phase * train.pulses_per_cycle)
        while (start := exact_start_ns(k, train)) <= train.duration_ns:
            is_up = k % train.pulses_per_cycle < train.up_pulses
            width = train.up_width_ns if is_up else train.down_width_ns
            if start >= 0 and start + width <= train.duration_ns:
                pulses.append((drive.delay_ns + start, drive.pin, width))
                raw.setdefault(drive.pin, []).append(
                    (drive.delay_ns + start, drive.delay_ns, up if is_up else down)
                )
            k += 1
        end_ns = drive.delay_ns + train.duration_ns
        raw.setdefault(drive.pin, []).append((end_ns, drive.delay_ns, calibration.rest_steps))
    targets = []
    for pin, entries in raw.items():
        entries.sort(key=lambda e: e[:2])  # time, then the drive that begins later last
        position = dev.calibration(pin).rest_steps
        for i, (time_ns, _, steps) in enumerate(entries):
            if i + 1 < len(entries) and entries[i + 1][0] == time_ns:
                continue  # a later drive's target at the same instant wins
            if steps != position:
                targets.append((time_ns, pin, steps))
            position = steps
    return sorted(pulses), sorted(targets)


def as_lists(schedule):
    p, t = schedule.pulses, schedule.targets
    pulses = list(zip(p.start_ns.tolist(), p.pin.tolist(), p.width_ns.tolist(), strict=True))
    targets = list(zip(t.time_ns.tolist(), t.pin.tolist(), t.position_steps.tolist(), strict=True))
    return pulses, targets


# Frequencies whose slot is whole, a half (20.48 Hz: 4 882 812.5 ns), a seventh, a third, or
# has a denominator of 314 159 (3.14159 Hz) that needs more than 64 bits in one product.
FREQUENCIES_HZ = [Fraction(f) for f in ("10", "7", "1/3", "5", "20.48", "3.14159", "40", "2.5")]


@st.composite
def trains(draw, frequency=None):
    frequency = frequency or draw(st.sampled_from(FREQUENCIES_HZ))
    per_cycle = draw(st.sampled_from([1, 2, 4, 5, 10]))
    while NS_PER_S / (frequency * per_cycle) < max(WIDTHS_NS):
        per_cycle //= 2 or 1  # keep every pulse inside its period
        if per_cycle == 0:
            per_cycle = 1
            break
    up_pulses = draw(st.integers(0, per_cycle))
    up, down = draw(st.sampled_from(WIDTHS_NS)), draw(st.sampled_from(WIDTHS_NS))
    # a phase of 0 or a whole number of slots puts a pulse at the drive's onset
    phase = Fraction(draw(st.sampled_from([0, 0, 18, 36, 90, 180, 270, 359])), 360)
    train = Train(frequency, NS_PER_S, per_cycle, up_pulses, up, down, phase)
    if draw(st.booleans()):
        return Train(*astuple_with(train, duration_ns=draw(st.integers(1, 3 * NS_PER_S // 2))))
    # the signal ends exactly as some pulse does
    k = draw(st.integers(0, 30)) - math.floor(phase * per_cycle)
    width = up if k % per_cycle < up_pulses else down
    return Train(*astuple_with(train, duration_ns=max(1, exact_start_ns(k, train) + width)))


def astuple_with(train: Train, **changes):
    fields = dict(vars(train), **changes)
    return [fields[name] for name in Train.__dataclass_fields__]


@st.composite
def trials(draw):
    """Drives on a few pins, several in a row on one pin, some back to back, some shared."""
    shared = draw(trains())
    drives = []
    for pin in draw(st.lists(st.integers(1, 16), min_size=1, max_size=4, unique=True)):
        at_ns = draw(st.sampled_from([0, 0, 7, 100_000_000]))
        for _ in range(draw(st.integers(1, 3))):
            train = shared if draw(st.booleans()) else draw(trains())
            drives.append(PinDrive(pin, train, at_ns))
            at_ns += train.duration_ns + draw(st.sampled_from([0, 0, 1, 3_000_000]))
    return draw(st.permutations(drives)) if draw(st.booleans()) else drives


def in_time_order(drives):
    return sorted(drives, key=lambda d: d.delay_ns)


@settings(max_examples=150, deadline=None)
@given(drives=trials(), scale=st.booleans())
def test_every_pulse_and_target_change_matches_the_pulse_by_pulse_reference(drives, scale):
    dev = varied_device(scale)
    assert as_lists(compile_drives(drives, dev)) == reference_schedule(in_time_order(drives), dev)


@settings(max_examples=40, deadline=None)
@given(train=trains(), pins=st.lists(st.integers(1, 16), min_size=2, max_size=16, unique=True))
def test_one_train_on_many_pins_interleaves_them_by_start_then_pin(train, pins):
    drives = [PinDrive(pin, train) for pin in pins]
    dev = varied_device()
    schedule = compile_drives(drives, dev)
    assert as_lists(schedule) == reference_schedule(drives, dev)
    assert len(schedule.pulses) == len(pins) * len(train_pulses(train)[0])


@settings(max_examples=5, deadline=None)  # each example computes a day of pulses (8.64 M at 10 Hz)
@given(
    frequency=st.sampled_from(FREQUENCIES_HZ),
    phase_deg=st.integers(0, 359),
    picks=st.lists(st.floats(0, 1), min_size=1, max_size=20),
)
def test_any_pulse_of_a_day_long_train_lands_on_its_exact_rational_time(
    frequency, phase_deg, picks
):
    train = seed_train(frequency, 24 * 3600, Fraction(phase_deg, 360))
    starts, widths, is_up = train_pulses(train)
    k = pulse_indices(train)
    assert starts[0] >= 0 and starts[-1] + widths[-1] <= train.duration_ns
    for pick in [0.0, 1.0, *picks]:
        i = min(len(starts) - 1, int(pick * len(starts)))
        assert int(starts[i]) == exact_start_ns(int(k[i]), train)
        assert bool(is_up[i]) == (int(k[i]) % 10 < 5)


def test_a_rightwards_wave_matches_the_reference_and_ends_every_pin_at_rest():
    wave = Wave(WaveKind.RIGHTWARDS, 2, (5, 6, 7, 8), seed_train(Fraction(1, 3) * 10, 1), 10**8)
    dev = varied_device()
    schedule = compile_drives(wave.drives(), dev)
    assert as_lists(schedule) == reference_schedule(wave.drives(), dev)
    last = {pin: steps for _, pin, steps in as_lists(schedule)[1]}
    assert last == {pin: dev.calibration(pin).rest_steps for pin in (5, 6, 7, 8)}


def test_a_train_that_starts_as_the_previous_one_ends_takes_over_at_that_instant():
    train = seed_train(5, Fraction(2, 5))
    dev = varied_device()  # pin 7 rests at 2049, one step off its down position
    drives = [PinDrive(7, train, 0), PinDrive(7, train, train.duration_ns)]
    schedule = compile_drives(drives, dev)
    at_handover = schedule.targets.time_ns == train.duration_ns
    assert schedule.targets.position_steps[at_handover].tolist() == [UP + 7]
    # listed the other way round, the trial is the same
    assert as_lists(compile_drives(drives[::-1], dev)) == as_lists(schedule)


def test_a_pulse_that_ends_exactly_as_the_signal_does_is_played():
    # 10 Hz: pulse 99 is a down pulse from 990 ms to 991.5 ms
    ends_with_it = Train(Fraction(10), 991_500_000)
    assert train_pulses(ends_with_it)[0][-1] == 990_000_000
    assert train_pulses(Train(Fraction(10), 991_499_999))[0][-1] == 980_000_000


def test_pulses_wider_than_their_period_or_of_no_width_are_refused():
    # 400 Hz x 10 pulses: a 0.25 ms period cannot hold a 2 ms pulse
    with pytest.raises(PinArrayError, match="widths of at least 1 ns within the pulse period"):
        compile_drives([PinDrive(1, seed_train(400, 1))], device())
    with pytest.raises(PinArrayError, match="found a 0 ms pulse"):
        train_pulses(Train(Fraction(10), NS_PER_S, down_width_ns=0))


def test_an_hour_long_train_holds_little_more_than_its_own_pulses_in_memory():
    # 1 h at 10 Hz: 360 000 pulses of 18 bytes (pin, start, width) and 72 000 targets of 14
    # (up and down each cycle; the last down is the rest position already)
    train = seed_train(10, 3600)
    tracemalloc.start()
    try:
        schedule = compile_drives([PinDrive(1, train)], device())
        peak_bytes = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(schedule.pulses) == 360_000 and len(schedule.targets) == 72_000
    assert peak_bytes / len(schedule.pulses) < 24  # the outputs alone are 20.8 bytes a pulse


def lifts_played_ns(train: Train) -> list[int]:
    """How long each run of up pulses holds the pin up as the schedule plays it: until the
    next (down) pulse starts, or the signal's end sends it to rest."""
    starts, _, is_up = train_pulses(train)
    lifts, begun = [], None
    for start, up in zip(starts.tolist(), is_up.tolist(), strict=True):
        if up and begun is None:
            begun = start
        elif not up and begun is not None:
            lifts.append(start - begun)
            begun = None
    if begun is not None:
        lifts.append(train.duration_ns - begun)
    return lifts


@settings(max_examples=300, deadline=None)
@given(frequency=st.integers(1, 40), per_cycle=st.integers(2, 12), up=st.integers(1, 11),
       phase=st.fractions(0, 1).filter(lambda p: p < 1), duration_ms=st.integers(1, 2000))
def test_the_shortest_lift_feasibility_judges_is_the_shortest_the_schedule_plays(
        frequency, per_cycle, up, phase, duration_ms):
    from pinarray.protocol.feasibility import shortest_lift_ns

    train = Train(Fraction(frequency), duration_ms * 1_000_000, per_cycle, min(up, per_cycle - 1),
                  2_000_000 // per_cycle, 1_500_000 // per_cycle, phase)
    played = lifts_played_ns(train)
    judged = shortest_lift_ns(train)
    if not played:
        assert judged is None
    else:  # the schedule rounds each pulse to the ns
        assert abs(judged - min(played)) <= 1


def test_a_signal_that_cuts_a_cycle_short_is_judged_on_that_lift_not_on_the_half_cycle():
    # 5 Hz for 220 ms: a whole cycle, then 20 ms up before rest; 114 steps need 38 ms.
    whole, cut = seed_train(5, Fraction(200, 1000)), seed_train(5, Fraction(220, 1000))
    calibration = device().calibration(6)
    assert check_train(whole, calibration, device()).feasible
    refused = check_train(cut, calibration, device())
    assert not refused.feasible and refused.cut_lift_ms == 20.0
    assert round(refused.reachable_steps) == 60
    assert "leaving a lift of 20.0 ms, in which only 60 of the 114 steps" in refused.describe(
        device().servo, 0.01)
