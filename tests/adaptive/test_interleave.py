"""Interleaved staircases: which one runs a trial depends on the seed, the trial number and the
unfinished staircases only, so a run resumed from its rows continues identically."""

from collections import Counter

import pytest

from pinarray.adaptive.interleave import pick_procedure
from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric
from pinarray.adaptive.staircase import StaircaseRule, StaircaseState, advance, replay, start
from pinarray.errors import PinArrayError

SOAS = tuple(float(v) for v in range(20, 301, 20))
STAIRCASES = {  # name: (rule, start index): one from below, one from above, a 1-up/3-down
    "low": (StaircaseRule(domain=SOAS, down=2, up=1, stop_after_trials=30,
                          stop_after_reversals=6, estimate_reversals=4), 0),
    "high": (StaircaseRule(domain=SOAS, down=2, up=1, stop_after_trials=30,
                           stop_after_reversals=6, estimate_reversals=4), 14),
    "strict": (StaircaseRule(domain=SOAS, down=3, up=1, stop_after_trials=25,
                             estimate_reversals=4), 7),
}
SUBJECT = PsychometricObserver(Psychometric("logistic", 120.0, 0.04, 0.5, 0.02), seed=11)


def continue_run(seed: int, rows: list[tuple[int, str, float, bool]]):
    """The run from its rows so far to its end: each staircase's state rebuilt from its own
    rows, then trials picked and answered until every staircase has finished."""
    rows = list(rows)
    states: dict[str, StaircaseState] = {}
    for name, (rule, start_index) in STAIRCASES.items():
        steps = replay(rule, start_index, [c for _, n, _, c in rows if n == name])
        states[name] = steps[-1].state if steps else start(rule, start_index)
    while unfinished := [n for n in STAIRCASES if not states[n].finished]:
        trial = len(rows) + 1
        name = pick_procedure(seed, trial, unfinished)
        rule = STAIRCASES[name][0]
        intensity = rule.domain[states[name].index]
        step = advance(rule, states[name], SUBJECT.answer(trial, intensity))
        states[name] = step.state
        rows.append((trial, name, step.intensity, step.correct))
    return rows


def test_interleaving_is_identical_when_replayed_from_any_midpoint():
    whole = continue_run(2024, [])
    assert {name for _, name, _, _ in whole} == set(STAIRCASES)
    for midpoint in range(len(whole)):
        assert continue_run(2024, whole[:midpoint]) == whole, midpoint


def test_another_seed_interleaves_in_another_order():
    assert [n for _, n, _, _ in continue_run(1, [])] != [n for _, n, _, _ in continue_run(2, [])]


def test_each_unfinished_procedure_is_picked_about_equally_often():
    picks = Counter(pick_procedure(7, trial, ["a", "b", "c"]) for trial in range(1, 3001))
    # 1000 expected each, binomial sd 26: five sds either way.
    assert all(abs(count - 1000) <= 130 for count in picks.values()), picks


def test_the_picks_of_a_seed_are_the_same_on_every_machine_and_numpy():
    # Integers from numpy's stable PCG64 stream (pinned here so a change of numpy shows).
    picks = "".join(pick_procedure(2024, trial, ["a", "b", "c"]) for trial in range(1, 21))
    assert picks == "acbbcbbcaaacbcbbacbb"


@pytest.mark.parametrize(("seed", "trial", "unfinished", "message"), [
    (-1, 1, ["a"], "seed must be a whole number from 0 to 2\\^63-1, found -1"),
    (0, 0, ["a"], "numbered from 1, found 0"),
    (0, 5, [], "trial 5: every interleaved procedure has finished"),
    (0, 1, ["a", "a"], "named once each, found \\['a', 'a'\\]"),
])
def test_a_bad_pick_is_refused_saying_what_was_found(seed, trial, unfinished, message):
    with pytest.raises(PinArrayError, match=message):
        pick_procedure(seed, trial, unfinished)
