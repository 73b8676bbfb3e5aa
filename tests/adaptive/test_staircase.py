"""Transformed and weighted up/down staircases: every step recomputed from the rows by the
rule pinarray/adaptive/staircase.py documents, stopping, refusals and convergence."""

import math
import statistics

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric
from pinarray.adaptive.staircase import (
    Move,
    StaircaseRule,
    StepSizes,
    advance,
    replay,
    reversal_mean,
    start,
)
from pinarray.errors import PinArrayError

DOMAIN = tuple(float(x) for x in range(10, 101, 10))  # 10, 20, ..., 100 (ms of SOA, say)


def rule(**fields) -> StaircaseRule:
    return StaircaseRule(**{"domain": DOMAIN, "down": 2, "up": 1, "stop_after_trials": 200,
                            "estimate_reversals": 4} | fields)


def recomputed(rule: StaircaseRule, start_index: int, rows: list[tuple[float, bool]]):
    """The documented rule written out plainly, from the rows alone (intensity presented,
    answer): what each row's intensity and reversal flag must be, and when the rule stops.

    Counts the consecutive answers by looking back over the rows since the last move."""
    expected_intensities, expected_reversals = [], []
    index, moves, reversal_levels, last_move_row = start_index, [], [], -1
    for n, (_, correct) in enumerate(rows):
        expected_intensities.append(rule.domain[index])
        since = [c for _, c in rows[last_move_row + 1:n + 1]]
        tail_correct = len(since) - len("".join("1" if c else "0" for c in since).rstrip("1"))
        tail_wrong = len(since) - len("".join("1" if c else "0" for c in since).rstrip("0"))
        direction = "down" if correct and tail_correct >= rule.down else (
            "up" if not correct and tail_wrong >= rule.up else None)
        reversal = direction is not None and bool(moves) and moves[-1] != direction
        expected_reversals.append(reversal)
        if reversal:
            reversal_levels.append(rule.domain[index])
        if direction is not None:
            moves.append(direction)
            last_move_row = n
            sizes = max((s for s in rule.steps if s.after_reversals <= len(reversal_levels)),
                        key=lambda s: s.after_reversals)
            index += -sizes.down_steps if direction == "down" else sizes.up_steps
            index = min(max(index, 0), len(rule.domain) - 1)
    return expected_intensities, expected_reversals, reversal_levels


def rows_of(steps) -> list[tuple[float, bool]]:
    return [(s.intensity, s.correct) for s in steps]


def test_every_step_of_a_one_up_two_down_staircase_is_recomputed_from_its_rows_alone():
    outcomes = [True, True, True, True, False, True, True, False, False, True, True, True, True,
                False, True, False, True, True, True, True, True, True, True, True, False]
    steps = replay(rule(), 6, outcomes)
    intensities, reversals, levels = recomputed(rule(), 6, rows_of(steps))
    assert [s.intensity for s in steps] == intensities
    assert [s.reversal for s in steps] == reversals
    assert steps[-1].state.reversal_intensities == tuple(levels)
    # By hand, the start: 70 70 -> down to 60, 60 60 -> 50, a wrong at 50 -> 60 (reversal at 50).
    assert intensities[:5] == [70.0, 70.0, 60.0, 60.0, 50.0]
    assert steps[4].move is Move.UP and steps[4].reversal and steps[5].intensity == 60.0


steps_sizes = st.lists(st.tuples(st.integers(1, 3), st.integers(1, 4), st.integers(1, 4)),
                       min_size=1, max_size=3).map(
    lambda gaps: tuple(StepSizes(sum(g for g, _, _ in gaps[:i]) if i else 0, d, u)
                       for i, (_, d, u) in enumerate(gaps)))


@given(down=st.integers(1, 3), up=st.integers(1, 2), steps=steps_sizes,
       start_index=st.integers(0, len(DOMAIN) - 1),
       outcomes=st.lists(st.booleans(), max_size=80))
def test_any_staircase_is_recomputed_from_its_rows_by_the_documented_rule(
        down, up, steps, start_index, outcomes):
    r = rule(down=down, up=up, steps=steps)
    steps_made = replay(r, start_index, outcomes)
    intensities, reversals, levels = recomputed(r, start_index, rows_of(steps_made))
    assert [s.intensity for s in steps_made] == intensities
    assert [s.reversal for s in steps_made] == reversals
    if steps_made:
        state = steps_made[-1].state
        assert state.reversal_intensities == tuple(levels)
        assert state.index == DOMAIN.index(replay(r, start_index, [*outcomes, True])[-1].intensity)


def test_a_weighted_staircase_steps_up_three_and_down_one():
    weighted = rule(down=1, up=1, steps=(StepSizes(0, down_steps=1, up_steps=3),))
    steps = replay(weighted, 5, [True, True, False, True, False])
    assert [s.intensity for s in steps] == [60.0, 50.0, 40.0, 70.0, 60.0]
    assert [s.reversal for s in steps] == [False, False, True, True, True]


def test_step_sizes_shrink_after_the_stated_reversals():
    shrinking = rule(down=1, up=1, steps=(StepSizes(0, 4, 4), StepSizes(2, 2, 2), StepSizes(4, 1, 1)))
    # Down 4, up 4 (1st reversal), down 2 (2nd reversal: its own move already takes size 2),
    # up 2 (3rd), down 1 (4th), down 1.
    steps = replay(shrinking, 5, [True, False, True, False, True, True, True])
    assert [s.intensity for s in steps] == [60.0, 20.0, 60.0, 40.0, 60.0, 50.0, 40.0]
    assert [s.reversal for s in steps] == [False, True, True, True, True, False, False]


def test_at_the_domain_ends_the_staircase_stays_and_still_counts_reversals():
    one_one = rule(down=1, up=1)
    steps = replay(one_one, 0, [True, True, False, False])
    assert [s.intensity for s in steps] == [10.0, 10.0, 10.0, 20.0]
    assert [s.reversal for s in steps] == [False, False, True, False]
    top = replay(one_one, len(DOMAIN) - 1, [False, False, True])
    assert [s.intensity for s in top] == [100.0, 100.0, 100.0]
    assert top[-1].reversal and top[-1].state.index == len(DOMAIN) - 2


def test_a_staircase_stops_after_its_reversals_or_its_trial_limit_whichever_comes_first():
    by_reversals = rule(down=1, up=1, stop_after_reversals=3, estimate_reversals=2)
    steps = replay(by_reversals, 5, [True, False, True, False])
    assert [s.state.finished for s in steps] == [False, False, False, True]
    by_trials = rule(stop_after_trials=3, stop_after_reversals=10)
    steps = replay(by_trials, 5, [True, True, True])
    assert steps[-1].state.finished and steps[-1].state.reversals == 0


def test_a_finished_staircase_takes_no_more_answers():
    steps = replay(rule(stop_after_trials=2), 5, [True, True])
    with pytest.raises(PinArrayError, match="finished after 2 trials"):
        advance(rule(stop_after_trials=2), steps[-1].state, True)


def test_a_staircase_that_could_never_end_is_refused():
    with pytest.raises(PinArrayError, match="needs a trial limit"):
        rule(stop_after_trials=None, stop_after_reversals=12)


@pytest.mark.parametrize(("fields", "message"), [
    ({"domain": (10.0,)}, "2 intensities or more, found 1"),
    ({"domain": (10.0, 30.0, 20.0)}, "strictly ascending, found"),
    ({"down": 0}, "down must be a whole number of 1 or more, found 0"),
    ({"up": 1.5}, "up must be a whole number of 1 or more, found 1.5"),
    ({"stop_after_trials": 0}, "stop_after_trials must be a whole number of 1 or more, found 0"),
    ({"stop_after_reversals": 4, "estimate_reversals": 6}, "stops after 4 reversals cannot estimate from its last 6"),
    ({"steps": (StepSizes(1, 1, 1),)}, "start after 0 reversals, found \\[1\\]"),
    ({"steps": (StepSizes(0, 1, 1), StepSizes(0, 1, 1))}, "strictly more reversals each time, found \\[0, 0\\]"),
    ({"steps": (StepSizes(0, 0, 1),)}, "down_steps must be a whole number of 1 or more, found 0"),
])
def test_a_bad_rule_is_refused_saying_what_was_found(fields, message):
    with pytest.raises(PinArrayError, match=message):
        rule(**fields)


def test_a_start_outside_the_domain_is_refused():
    with pytest.raises(PinArrayError, match="index from 0 to 9 into its domain, found 10"):
        start(rule(), 10)


def test_the_estimate_is_the_arithmetic_mean_of_the_last_reversal_intensities():
    one_one = rule(down=1, up=1, estimate_reversals=3)
    state = replay(one_one, 5, [True, False, True, False, False, True])[-1].state
    assert state.reversal_intensities == (50.0, 60.0, 50.0, 70.0)
    assert reversal_mean(one_one, state) == pytest.approx((60.0 + 50.0 + 70.0) / 3, rel=1e-15)
    early = replay(one_one, 5, [True, False])[-1].state
    assert reversal_mean(one_one, early) == 50.0
    assert reversal_mean(one_one, start(one_one, 5)) is None


def test_a_one_up_two_down_staircase_converges_near_the_70_7_percent_point():
    # A 2AFC subject (guess 0.5) on a fine domain: 1 ms steps from 1 to 60 ms.
    subject = Psychometric("weibull", threshold=20.0, slope=3.0, guess=0.5, lapse=0.0)
    target = subject.intensity_for(1 / math.sqrt(2))  # 16.2 ms; 1-up/3-down's 79.4 %: 19.2 ms
    # Steps of 4, 2, then 1 ms, as labs run it: from a start far above, a fixed 1 ms step is
    # still descending at the first reversals and biases a short run upwards.
    fine = StaircaseRule(domain=tuple(float(x) for x in range(1, 61)), down=2, up=1,
                         steps=(StepSizes(0, 4, 4), StepSizes(2, 2, 2), StepSizes(4, 1, 1)),
                         stop_after_trials=400, stop_after_reversals=20, estimate_reversals=12)
    estimates = []
    for seed in range(200):
        observer = PsychometricObserver(subject, seed)
        state = start(fine, 34)
        while not state.finished:
            state = advance(fine, state, observer.answer(state.trials + 1,
                                                         fine.domain[state.index])).state
        estimates.append(reversal_mean(fine, state))
    mean = statistics.fmean(estimates)
    standard_error = statistics.stdev(estimates) / math.sqrt(len(estimates))
    # One domain step allowed for the bias of fixed-step staircases (García-Pérez 1998: with
    # steps small beside the function's spread, short runs settle a little above 70.7 %), plus
    # four standard errors of the mean; 1-up/3-down's point lies 3 ms above the target.
    assert abs(mean - target) <= 1.0 + 4 * standard_error, (mean, target, standard_error)
