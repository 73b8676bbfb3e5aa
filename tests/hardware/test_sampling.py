"""Which samples the measured motion needs: every period while a pin moves, only as often as
the cycle rule asks while every moving pin holds its goal."""

from pinarray.hardware.delivery import Change
from pinarray.hardware.sampling import Holds

MS = 1_000_000
PERIOD_NS = 4 * MS
UP, REST = 2113, 2048


def square_train(servo_id: int, cycles: int, half_ns: int) -> list[Change]:
    """Up at 0, down at half a cycle, and so on."""
    return [Change(servo_id, servo_id, UP if k % 2 == 0 else REST, k * half_ns)
            for k in range(2 * cycles)]


def test_a_pin_holding_its_goal_is_next_sampled_a_period_before_the_cycle_rule_demands():
    holds = Holds(square_train(4, 3, 200 * MS), (4,), 1200 * MS, PERIOD_NS)
    holds.sampled(4, 100 * MS, UP - 1)
    assert holds.next_sample_ns(100 * MS) == 104 * MS  # one sample at the goal: not yet
    holds.sampled(4, 104 * MS, UP - 1)
    # a 400 ms cycle allows gaps of 50 ms; the first sample after the next change comes up to
    # a period late, so the one before it is a period early
    assert holds.next_sample_ns(104 * MS) == (104 + 50 - 4) * MS


def test_a_pin_still_far_from_its_goal_or_another_still_moving_keeps_every_period():
    changes = square_train(4, 3, 200 * MS) + square_train(9, 3, 200 * MS)
    holds = Holds(sorted(changes, key=lambda c: c.time_ns), (4, 9), 1200 * MS, PERIOD_NS)
    for at_ms in (100, 104):
        holds.sampled(4, at_ms * MS, UP)
        holds.sampled(9, at_ms * MS, UP - 20)  # stopped short: not within 3 steps
    assert holds.next_sample_ns(104 * MS) == 108 * MS


def test_a_goal_change_or_an_unanswered_sample_sends_sampling_back_to_every_period():
    holds = Holds(square_train(4, 3, 200 * MS), (4,), 1200 * MS, PERIOD_NS)
    for at_ms in (100, 104):
        holds.sampled(4, at_ms * MS, UP)
    assert holds.next_sample_ns(104 * MS) > 108 * MS
    holds.moved(4)
    assert holds.next_sample_ns(104 * MS) == 108 * MS
    holds.sampled(4, 108 * MS, UP)
    assert holds.next_sample_ns(108 * MS) == 112 * MS  # it must be seen holding again first


def test_before_its_first_cycle_begins_a_pin_is_sampled_every_period():
    changes = [Change(4, 4, UP, 300 * MS), Change(4, 4, REST, 500 * MS)]
    holds = Holds(changes, (4,), 800 * MS, PERIOD_NS)
    for at_ms in (100, 104):
        holds.sampled(4, at_ms * MS, REST)  # no goal in force yet: nothing held
    assert holds.next_sample_ns(104 * MS) == 108 * MS
