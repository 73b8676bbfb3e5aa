"""Trial plans: reproducible from the seed, numbered 1..N, honouring the order constraints."""

import itertools
from collections import Counter
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.errors import PinArrayError
from pinarray.paradigms.localisation.design import LocalisationCondition
from pinarray.plan import constrained_shuffle, make_plan, williams_square
from pinarray.protocol.load import load_protocol, parse_protocol

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"


def localisation():
    return load_protocol(PROTOCOLS / "localisation.yaml")


def test_the_same_seed_gives_a_byte_identical_plan():
    assert make_plan(localisation(), 7).to_json() == make_plan(localisation(), 7).to_json()
    assert make_plan(localisation(), 7).to_json() != make_plan(localisation(), 8).to_json()


def test_a_plan_without_a_seed_draws_and_records_one():
    plan = make_plan(localisation())
    assert isinstance(plan.seed, int)
    assert make_plan(localisation(), plan.seed).to_json() == plan.to_json()


def test_trials_are_numbered_in_plan_order_with_practice_first():
    plan = make_plan(localisation(), 3)
    assert [t.trial for t in plan.trials] == list(range(1, 27))
    assert [t.practice for t in plan.trials[:3]] == [True, True, False]
    assert {t.block for t in plan.trials if not t.practice} == {1}
    main = Counter(
        (t.condition.pin, t.condition.frequency_hz) for t in plan.trials if not t.practice
    )
    assert len(main) == 24 and set(main.values()) == {1}


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32))
def test_no_pin_is_stimulated_twice_in_a_row(seed):
    trials = [t for t in make_plan(localisation(), seed).trials if not t.practice]
    pins = [t.condition.pin for t in trials]
    assert all(a != b for a, b in itertools.pairwise(pins))


def test_apparent_motion_presents_each_configuration_twice_per_block():
    plan = make_plan(load_protocol(PROTOCOLS / "apparent_motion.yaml"), 11)
    for block in (1, 2):
        kinds = Counter(t.condition.kind.value for t in plan.trials if t.block == block)
        assert kinds == {"rightwards": 2, "leftwards": 2, "none": 2}


def on_pin(pin: int) -> LocalisationCondition:
    return LocalisationCondition("s", pin, Fraction(5))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32), limit=st.integers(1, 3), values=st.integers(2, 5))
def test_runs_never_exceed_the_maximum_run_length(seed, limit, values):
    items = [on_pin(v) for v in range(1, values + 1)] * 4
    order = constrained_shuffle(items, {"pin": limit}, np.random.default_rng(seed))
    assert Counter(order) == Counter(items)
    runs = [len(list(group)) for _, group in itertools.groupby(c.pin for c in order)]
    assert max(runs) <= limit


def test_a_tight_but_possible_constraint_is_met_not_hung():
    # 5 x pin 1 among 9 trials with no repeats: only 1 x 1 x 1 x 1 x 1 interleaved works
    items = [on_pin(1)] * 5 + [on_pin(2)] * 4
    order = constrained_shuffle(items, {"pin": 1}, np.random.default_rng(0))
    assert [c.pin for c in order] == [1, 2, 1, 2, 1, 2, 1, 2, 1]


def test_an_impossible_constraint_is_an_error_not_a_hang():
    items = [on_pin(1)] * 3 + [on_pin(2)]
    with pytest.raises(PinArrayError, match="no order of the trials satisfies"):
        constrained_shuffle(items, {"pin": 1}, np.random.default_rng(0))


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
def test_the_latin_square_is_balanced(n):
    square = williams_square(n)
    for row in square:
        assert sorted(row) == list(range(n))
    for column in zip(*square, strict=True):
        assert Counter(column) == Counter({c: len(square) // n for c in range(n)})
    follows = Counter(pair for row in square for pair in itertools.pairwise(row))
    assert set(follows.values()) == {len(square) // n}
    assert len(follows) == n * (n - 1)


def test_sequential_and_latin_square_orders_are_deterministic_per_block():
    text = (PROTOCOLS / "demo.yaml").read_text()
    demo = parse_protocol(text)
    assert [t.condition.pin for t in make_plan(demo, 1).trials] == list(range(1, 17))
    latin = parse_protocol(
        text.replace("order: sequential", "order: latin_square").replace(
            "frequencies_hz: [5]", "frequencies_hz: [5]\n  blocks: 3"
        )
    )
    plan = make_plan(latin, 5)
    blocks = [[t.condition.pin for t in plan.trials if t.block == b] for b in (1, 2, 3)]
    assert all(sorted(b) == list(range(1, 17)) for b in blocks)
    assert blocks[0] != blocks[1] != blocks[2]


def test_asking_for_a_trial_outside_the_plan_names_the_range():
    with pytest.raises(PinArrayError, match="trial 99 is not in the plan: expected 1 to 26"):
        make_plan(localisation(), 1).trial(99)
