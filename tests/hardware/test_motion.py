"""What the pins did, measured from their samples: stroke, lag and short cycles on known traces."""

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.hardware.delivery import Change, DeliveryLedger
from pinarray.hardware.motion import PinTrace, TrialStrokes, measure_pin, measure_trial

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
