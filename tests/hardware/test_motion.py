"""What the pins did, measured from their samples: stroke, lag and short cycles on known traces."""

from array import array
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.hardware.delivery import Change, DeliveryLedger
from pinarray.hardware.motion import (
    ARRIVAL_STEPS,
    MAX_GAP_FRACTION,
    MIN_SAMPLES_PER_CYCLE,
    PinSamples,
    PinTrace,
    TrialStrokes,
    measure_pin,
    measure_trial,
    median,
)

MS = 1_000_000
DOWN, UP = 2048, 2162


def train_goals(rate_hz, cycles):
    """A pin's goal changes: up at each cycle's start, down half a cycle later."""
    half_ns = 10**9 // rate_hz // 2
    return [(k * half_ns, UP if k % 2 == 0 else DOWN) for k in range(2 * cycles)]


def horn(goals, reach_steps, lag_ns, every_ns, end_ns):
    """A horn that, ``lag_ns`` after each change, moves linearly over the next 40 % of the
    half cycle towards its goal, stopping ``reach_steps`` from the previous extreme."""
    times = np.arange(0, end_ns, every_ns, dtype=np.int64)
    positions = np.full(len(times), DOWN, dtype=float)
    half_ns = goals[1][0] - goals[0][0]
    for t0, goal in goals:
        start = DOWN if goal == UP else DOWN + reach_steps
        target = DOWN + reach_steps if goal == UP else DOWN
        share = np.clip((times - t0 - lag_ns) / (0.4 * half_ns), 0, 1)
        mine = times >= t0 + lag_ns
        positions[mine] = start + (target - start) * share[mine]
    return PinTrace(6, 6, times, np.round(positions).astype(np.int32))


def test_a_pin_that_moves_the_whole_way_achieves_its_commanded_stroke():
    goals = train_goals(10, 5)
    stroke = measure_pin(horn(goals, UP - DOWN, 5 * MS, MS, 500 * MS), goals, 500 * MS)
    assert (stroke.commanded_steps, stroke.achieved_steps, stroke.median_steps) == (114, 114, 114)
    assert (stroke.cycles, stroke.short_cycles) == (5, 0)
    # arrival: the lag, then 40 % of the 50 ms half cycle, to the sample within 3 steps
    assert 5 * MS + 18 * MS <= stroke.lag_ns <= 5 * MS + 20 * MS


def test_a_pin_that_turns_back_early_is_short_by_what_it_missed():
    goals = train_goals(10, 5)
    stroke = measure_pin(horn(goals, 75, 0, MS, 500 * MS), goals, 500 * MS)
    assert (stroke.commanded_steps, stroke.achieved_steps) == (114, 75)
    assert (stroke.cycles, stroke.short_cycles) == (5, 5)
    # It reached its goal only on the way down, half the changes: no median lag to speak of
    # (the way-down changes' lag alone would say it keeps up).
    assert stroke.lag_ns is None
    strokes = TrialStrokes((stroke,), Fraction(8, 10))
    assert "pin 6 moved 75 of 114 commanded steps (66 %" in strokes.problem()


def test_the_smallest_cycle_is_the_achieved_stroke_and_the_median_stands_beside_it():
    goals = train_goals(10, 5)
    full = horn(goals, 114, 0, MS, 500 * MS)
    positions = full.position_steps.copy()
    third = (full.time_ns >= 200 * MS) & (full.time_ns < 300 * MS)
    positions[third] = np.minimum(positions[third], DOWN + 60)  # one cycle blocked at 60 steps
    stroke = measure_pin(PinTrace(6, 6, full.time_ns, positions), goals, 500 * MS)
    assert (stroke.achieved_steps, stroke.median_steps, stroke.short_cycles) == (60, 114, 1)


def test_too_few_samples_to_judge_a_cycle_is_not_measured_never_short_and_never_passed():
    goals = train_goals(10, 5)
    sparse = horn(goals, 114, 0, 30 * MS, 500 * MS)  # 3 or 4 samples a 100 ms cycle
    stroke = measure_pin(sparse, goals, 500 * MS)
    assert not stroke.measured and stroke.achieved_steps is None and stroke.cycles == 0
    assert (stroke.short_cycles, stroke.unmeasured_cycles) == (0, 5)
    problem = TrialStrokes((stroke,), Fraction(8, 10)).problem()
    assert problem.startswith("pin 6's stroke not measured in 5 of 5 cycles: too few position "
                              "samples to judge (a cycle needs 6, none more than 1/8 of it apart)")
    assert "moved" not in problem


def test_one_cycle_unmeasured_among_judged_ones_still_leaves_the_stroke_unknown():
    goals = train_goals(10, 5)
    full = horn(goals, 114, 0, MS, 500 * MS)
    gap = (full.time_ns > 120 * MS) & (full.time_ns < 135 * MS)  # 15 ms without a sample
    stroke = measure_pin(PinTrace(6, 6, full.time_ns[~gap], full.position_steps[~gap]), goals,
                         500 * MS)
    assert (stroke.achieved_steps, stroke.cycles, stroke.unmeasured_cycles) == (114, 4, 1)
    assert stroke.measured  # a stroke is known from the cycles judged ...
    strokes = TrialStrokes((stroke,), Fraction(8, 10))
    assert strokes.unmeasured == (stroke,)  # ... but not the smallest over all of them
    assert "pin 6's stroke not measured in 1 of 5 cycles" in strokes.problem()


def test_a_pin_that_fell_short_is_named_before_one_that_was_not_measured():
    goals = train_goals(10, 5)
    short = measure_pin(horn(goals, 75, 0, MS, 500 * MS), goals, 500 * MS)
    unmeasured = measure_pin(horn(goals, 114, 0, 30 * MS, 500 * MS), goals, 500 * MS)
    problem = TrialStrokes((unmeasured, short), Fraction(8, 10)).problem()
    assert problem.startswith("pin 6 moved 75 of 114 commanded steps")


def test_a_pin_commanded_no_stroke_has_nothing_to_measure():
    goals = [(0, UP)]  # one goal, held: no cycle, no stroke
    stroke = measure_pin(horn(train_goals(10, 1), 114, 0, 30 * MS, 100 * MS), goals, 100 * MS)
    assert (stroke.commanded_steps, stroke.cycles, stroke.unmeasured_cycles) == (0, 0, 0)
    assert TrialStrokes((stroke,), Fraction(8, 10)).problem() == ""


def test_a_short_pin_makes_the_trial_not_delivered_as_specified_with_its_reason():
    goals = train_goals(10, 3)
    changes = tuple(Change(6, 6, goal, t) for t, goal in goals)
    ledger = DeliveryLedger(changes, 10 * MS)
    for index in range(len(changes)):
        ledger.confirm(index, 0, healed=False)
    strokes = measure_trial([horn(goals, 70, 0, MS, 300 * MS)], changes, 300 * MS)
    record = ledger.record(strokes)
    assert not record.delivered and "pin 6 moved 70 of 114" in record.problem
    assert record.strokes is strokes


@settings(max_examples=40, deadline=None)
@given(st.integers(10, 114), st.integers(0, 15), st.sampled_from([3, 5, 10]))
def test_the_achieved_stroke_is_what_the_horn_reached_within_a_step(reach, lag_ms, rate_hz):
    goals = train_goals(rate_hz, 3)
    end_ns = 3 * 10**9 // rate_hz
    stroke = measure_pin(horn(goals, reach, lag_ms * MS, MS, end_ns), goals, end_ns)
    assert stroke.achieved_steps is not None and abs(stroke.achieved_steps - reach) <= 1
    assert stroke.median_steps is not None and stroke.achieved_steps <= stroke.median_steps


def test_a_stroke_tolerance_of_0_checks_no_stroke_so_no_cycle_unmeasured_matters():
    goals = train_goals(10, 5)
    unmeasured = measure_pin(horn(goals, 114, 0, 30 * MS, 500 * MS), goals, 500 * MS,
                             tolerance=Fraction(0))
    assert unmeasured.unmeasured_cycles == 5
    assert TrialStrokes((unmeasured,), Fraction(0)).problem() == ""
    assert TrialStrokes((unmeasured,), Fraction(1, 100)).problem() != ""


# numpy's measure, as the player measured strokes before it went without numpy: the reference
# the pure-Python measure must equal exactly (median_steps a float, bit for bit).
def numpy_peak_to_peak(times, positions, start_ns, stop_ns):
    first, last = np.searchsorted(times, [start_ns, stop_ns])
    if last - first < MIN_SAMPLES_PER_CYCLE:
        return None
    edges = np.concatenate(([start_ns], times[first:last], [stop_ns]))
    if int(np.diff(edges).max()) > (stop_ns - start_ns) * MAX_GAP_FRACTION:
        return None
    window = positions[first:last]
    return int(window.max()) - int(window.min())


def numpy_lags(times, positions, goals, end_ns):
    lags = []
    for k, (time_ns, goal) in enumerate(goals):
        until_ns = goals[k + 1][0] if k + 1 < len(goals) else end_ns
        first, last = np.searchsorted(times, [time_ns, until_ns])
        near = np.flatnonzero(np.abs(positions[first:last].astype(np.int64) - goal)
                              <= ARRIVAL_STEPS)
        if len(near):
            lags.append(int(times[first + near[0]]) - time_ns)
    return sorted(lags)


@st.composite
def sampled_pins(draw):
    """A pin's goal changes and its samples: any times and positions a servo could report."""
    end_ns = draw(st.integers(10 * MS, 2_000 * MS))
    change_ns = sorted(draw(st.sets(st.integers(0, end_ns - 1), min_size=1, max_size=12)))
    goals = [(t, draw(st.sampled_from([2048, 2162, draw(st.integers(0, 4095))])))
             for t in change_ns]
    # The samples' times and positions come from one drawn random generator: hundreds of
    # separate draws per example made this the suite's most expensive test (12 CPU-s).
    bulk = draw(st.randoms(use_true_random=True))  # seeded by the draw: repeatable
    if draw(st.booleans()):  # scattered
        sample_ns = sorted(bulk.sample(range(end_ns), bulk.randint(0, 200)))
    else:  # every so often, some missed (as a busy bus does), so that cycles are measured
        every_ns = end_ns // draw(st.integers(20, 400))
        sample_ns = [t for t in range(draw(st.integers(0, every_ns)), end_ns, every_ns)
                     if bulk.randint(0, 20)]
    goal_values = [g for _, g in goals]
    positions = [bulk.randint(-32767, 32767) if bulk.getrandbits(1)
                 else bulk.choice(goal_values) + bulk.randint(-2 * ARRIVAL_STEPS, 2 * ARRIVAL_STEPS)
                 for _ in sample_ns]
    return goals, np.array(sample_ns, dtype=np.int64), np.array(positions, dtype=np.int32), end_ns


@settings(max_examples=300)
@given(sampled_pins())
def test_the_stroke_measured_without_numpy_is_numpys_exactly(pin):
    goals, times, positions, end_ns = pin
    values = [g for _, g in goals]
    starts = [t for k, (t, g) in enumerate(goals) if g > (goals[k - 1][1] if k else min(values))]
    stops = [*starts[1:], end_ns] if starts else []
    peaks = [p for p in (numpy_peak_to_peak(times, positions, a, b)
                         for a, b in zip(starts, stops, strict=True)) if p is not None]
    lags = numpy_lags(times, positions, goals, end_ns)
    low, high = (len(goals) - 1) // 2, len(goals) // 2

    for trace in (PinTrace(3, 3, times, positions),
                  PinSamples(3, 3, array("q", times.tolist()), array("i", positions.tolist()))):
        stroke = measure_pin(trace, goals, end_ns)
        assert stroke.cycles == len(peaks) and stroke.unmeasured_cycles == len(starts) - len(peaks)
        assert stroke.achieved_steps == (min(peaks) if peaks else None)
        if peaks:
            numpys = float(np.median(peaks))
            assert stroke.median_steps == numpys and repr(stroke.median_steps) == repr(numpys)
        else:
            assert stroke.median_steps is None
        assert stroke.lag_ns == ((lags[low] + lags[high]) // 2 if high < len(lags) else None)


@given(st.lists(st.integers(-(2**53), 2**53), min_size=1, max_size=40))
def test_the_median_of_integers_is_numpys_bit_for_bit(values):
    numpys = float(np.median(np.array(values, dtype=np.int64)))
    assert median(values).hex() == numpys.hex()
