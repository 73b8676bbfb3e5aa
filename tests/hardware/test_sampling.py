"""Which samples the measured motion needs: every period while a pin moves, only as often as
the cycle rule asks while every moving pin holds its goal, and one just before each change."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.hardware.delivery import Change
from pinarray.hardware.motion import MAX_GAP_FRACTION, PinTrace, measure_pin
from pinarray.hardware.sampling import NEVER_NS, Holds, PinGoals

MS = 1_000_000
PERIOD_NS = 4 * MS
SAMPLE_NS = 1 * MS  # one sample of the moving servos on this bus
AFTER_NS = 2 * MS  # from a goal change to the first sample after it
UP, REST = 2113, 2048


def square_train(servo_id: int, cycles: int, half_ns: int) -> list[Change]:
    """Up at 0, down at half a cycle, and so on."""
    return [Change(servo_id, servo_id, UP if k % 2 == 0 else REST, k * half_ns)
            for k in range(2 * cycles)]


def holding(holds: Holds, servo_id: int, *at_ms: int, steps: int = UP) -> None:
    for ms in at_ms:
        holds.sampled(servo_id, ms * MS, steps)


def test_a_pin_holding_its_goal_is_sampled_again_when_the_cycle_rule_needs_it():
    holds = Holds(square_train(4, 3, 200 * MS), (4,), 1200 * MS, PERIOD_NS)
    holding(holds, 4, 20, steps=UP - 1)
    assert holds.next_sample_ns(20 * MS, SAMPLE_NS, AFTER_NS) == 24 * MS  # once: not yet
    holding(holds, 4, 24, steps=UP - 1)
    # a 400 ms cycle allows gaps of 50 ms, less what follows a change
    assert holds.next_sample_ns(24 * MS, SAMPLE_NS, AFTER_NS) == (24 + 50 - 2) * MS


def test_the_last_sample_before_a_change_fits_before_its_frame_on_the_period_grid():
    holds = Holds(square_train(4, 3, 200 * MS), (4,), 1200 * MS, PERIOD_NS)
    holding(holds, 4, 170, 174)
    # the change at 200 ms: a sample of 1 ms must end a period before it (by 195 ms), on the
    # grid of samples every period from 174 ms, as sampling every period would have taken it
    assert holds.next_sample_ns(174 * MS, SAMPLE_NS, AFTER_NS) == 194 * MS


def test_a_bus_too_slow_to_leave_room_around_a_change_holds_nothing_back():
    holds = Holds(square_train(4, 3, 200 * MS), (4,), 1200 * MS, PERIOD_NS)
    holding(holds, 4, 20, 24)
    # a sample of 16 servos and the read-back after a change: 30 + 25 ms > a 50 ms gap
    assert holds.next_sample_ns(24 * MS, 30 * MS, 25 * MS) == (24 + 30) * MS


def test_a_pin_still_far_from_its_goal_or_another_still_moving_keeps_every_period():
    changes = square_train(4, 3, 200 * MS) + square_train(9, 3, 200 * MS)
    holds = Holds(sorted(changes, key=lambda c: c.time_ns), (4, 9), 1200 * MS, PERIOD_NS)
    holding(holds, 4, 20, 24)
    holding(holds, 9, 20, 24, steps=UP - 20)  # stopped short: not within 3 steps
    assert holds.next_sample_ns(24 * MS, SAMPLE_NS, AFTER_NS) == 28 * MS


def test_a_goal_change_or_an_unanswered_sample_sends_sampling_back_to_every_period():
    holds = Holds(square_train(4, 3, 200 * MS), (4,), 1200 * MS, PERIOD_NS)
    holding(holds, 4, 20, 24)
    assert holds.next_sample_ns(24 * MS, SAMPLE_NS, AFTER_NS) > 28 * MS
    holds.moved(4)
    assert holds.next_sample_ns(24 * MS, SAMPLE_NS, AFTER_NS) == 28 * MS
    holding(holds, 4, 28)
    assert holds.next_sample_ns(28 * MS, SAMPLE_NS, AFTER_NS) == 32 * MS  # seen holding first


def test_before_its_first_cycle_begins_a_pin_is_sampled_every_period():
    changes = [Change(4, 4, UP, 300 * MS), Change(4, 4, REST, 500 * MS)]
    holds = Holds(changes, (4,), 800 * MS, PERIOD_NS)
    holding(holds, 4, 100, 104, steps=REST)  # no goal in force yet: nothing held
    assert holds.next_sample_ns(104 * MS, SAMPLE_NS, AFTER_NS) == 108 * MS


def test_a_gap_across_a_change_is_judged_by_each_cycle_it_falls_in():
    # Cycles of 400 ms from 0 (the last runs to 1200 ms): at most 50 ms without a sample.
    goals = PinGoals.of(square_train(4, 3, 200 * MS))
    assert goals.gap_fits(150 * MS, 200 * MS, 1200 * MS)  # a down change inside a cycle
    assert not goals.gap_fits(150 * MS, 201 * MS, 1200 * MS)
    # across the up change at 400 ms: 40 ms before it, 40 ms after, each within its cycle
    assert goals.gap_fits(360 * MS, 440 * MS, 1200 * MS)
    assert not goals.gap_fits(340 * MS, 440 * MS, 1200 * MS)
    # after the trial's end nothing is judged
    assert goals.gap_fits(1160 * MS, 1500 * MS, 1200 * MS)


def test_before_its_first_cycle_a_pin_leaves_any_gap_free():
    goals = PinGoals.of([Change(4, 4, UP, 300 * MS), Change(4, 4, REST, 500 * MS)])
    assert goals.gap_fits(0, 300 * MS, 800 * MS)
    # its one cycle runs from 300 ms to the trial's end at 800: 62.5 ms without a sample
    assert goals.gap_fits(0, 362 * MS, 800 * MS) and not goals.gap_fits(0, 363 * MS, 800 * MS)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 1300), st.integers(1, 700))
def test_the_gap_the_sampler_keeps_is_the_one_motion_judges_a_cycle_by(from_ms, length_ms):
    """Samples every ms but none strictly between ``from`` and ``to``: every cycle is judged
    exactly when `PinGoals.gap_fits` says that gap keeps the rule."""
    start_ms, end_ms = 100, 1300
    changes = [Change(4, 4, c.goal_steps, c.time_ns + start_ms * MS)
               for c in square_train(4, 3, 200 * MS)]
    to_ms = from_ms + length_ms
    times = np.array([t for t in range(end_ms) if not from_ms < t < to_ms], dtype=np.int64) * MS
    trace = PinTrace(4, 4, times, np.full(len(times), UP, dtype=np.int32))
    stroke = measure_pin(trace, [(c.time_ns, c.goal_steps) for c in changes], end_ms * MS)
    fits = PinGoals.of(changes).gap_fits(from_ms * MS, to_ms * MS, end_ms * MS)
    assert (stroke.unmeasured_cycles == 0) == fits


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 1300), st.integers(0, 700))
def test_the_latest_next_sample_is_where_the_gap_rule_stops_holding(from_ms, length_ms):
    changes = [Change(4, 4, c.goal_steps, c.time_ns + 100 * MS)
               for c in square_train(4, 3, 200 * MS)]
    goals = PinGoals.of(changes)
    from_ns, to_ns, end_ns = from_ms * MS, (from_ms + length_ms) * MS, 1300 * MS
    assert goals.gap_fits(from_ns, to_ns, end_ns) == (to_ns <= goals.reach_ns(from_ns, end_ns))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(1, 10**9), min_size=2, max_size=8), st.integers(0, 5 * 10**9),
       st.integers(1, 10**9))
def test_the_gap_rule_holds_to_the_nanosecond_for_cycles_of_any_length(halves_ns, from_ns,
                                                                        tail_ns):
    """Cycles whose length is no multiple of the rule's eighth: the latest next sample is the
    last nanosecond a gap keeps the rule, and the gap a cycle allows is its eighth rounded
    down (exact integers, as `pinarray.hardware.motion` judges with its Fraction)."""
    times = np.cumsum([0, *halves_ns[:-1]]).tolist()
    changes = [Change(4, 4, UP if k % 2 == 0 else REST, t) for k, t in enumerate(times)]
    end_ns = times[-1] + tail_ns
    goals = PinGoals.of(changes)
    reach = goals.reach_ns(from_ns, end_ns)
    if reach < NEVER_NS:
        assert goals.gap_fits(from_ns, reach, end_ns)
        assert not goals.gap_fits(from_ns, reach + 1, end_ns)
    else:
        assert goals.gap_fits(from_ns, end_ns, end_ns)
    stops = [*goals.cycle_start_ns[1:], end_ns]
    allowed = [int((stop - start) * MAX_GAP_FRACTION)
               for start, stop in zip(goals.cycle_start_ns, stops, strict=True)]
    assert goals.tightest_gap_ns(end_ns) == min(allowed)
    for start, gap in zip(goals.cycle_start_ns, allowed, strict=True):
        assert goals.gap_allowed_ns(start, end_ns) == gap
