"""The statistics on a results set small enough to count by hand (see conftest.py)."""

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.analysis import summary_lines
from pinarray.analysis.load import load_results
from pinarray.analysis.stats import wilson_interval
from pinarray.paradigms.apparent_motion.analysis import motion_summary
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.paradigms.localisation.stats import (
    confusion_matrix,
    localisation_by_frequency,
    summarise_subjects,
)


def summaries_of(root):
    return {s.group: s for s in summarise_subjects((t.subject, t.record)
                                                  for t in load_results([root]))}


def test_correct_percent_per_frequency_counts_only_main_trials_with_status_ok(results_root):
    pooled = summaries_of(results_root)["all"]
    three, ten = pooled.localisation
    assert (three.frequency_hz, three.trials, three.correct.successes) == (3.0, 6, 2)
    assert (ten.frequency_hz, ten.trials, ten.correct.successes) == (10.0, 5, 2)
    assert_allclose(three.correct.pct, 100 / 3)
    assert_allclose(ten.correct.pct, 40.0)


def test_the_wilson_interval_of_2_of_6_is_9_7_to_70_percent(results_root):
    three = summaries_of(results_root)["all"].localisation[0]
    assert_allclose(three.correct.interval_pct, (9.68, 70.0), atol=0.01)


def test_error_types_are_percent_of_all_trials_at_that_frequency(results_root):
    three, ten = summaries_of(results_root)["all"].localisation
    assert three.error_counts == (1, 1, 1, 0) and three.none_felt == 1
    assert ten.error_counts == (2, 0, 0, 1) and ten.none_felt == 0
    assert_allclose([three.error_pct(c) for c in "ABCD"], [100 / 6, 100 / 6, 100 / 6, 0])
    assert_allclose([ten.error_pct(c) for c in "ABCD"], [40, 0, 0, 20])


def test_the_confusion_matrix_holds_every_trial_once_nothing_felt_included(results_root):
    confusion = summaries_of(results_root)["all"].confusion
    expected = np.zeros((16, 17), dtype=int)
    for stimulated, reported in [(10, 10), (10, 9), (10, 5), (4, 4), (4, 4), (4, 8), (10, 16),
                                 (1, 3), (1, 1), (4, 3)]:
        expected[stimulated - 1, reported - 1] += 1
    expected[10 - 1, 16] = 1  # subject A felt nothing once on pin 10: the last column
    assert (confusion == expected).all()


def test_a_confusion_row_divides_by_every_trial_of_its_pin_as_the_pin_map_does(results_root):
    pooled = summaries_of(results_root)["all"]
    row = pooled.confusion[10 - 1]
    assert row.sum() == pooled.pin_trials[2, 1] == 5  # pin 10: nothing felt counted too
    assert_allclose(100 * row[10 - 1] / row.sum(), pooled.pin_accuracy_pct[2, 1])


def test_pin_accuracy_is_laid_out_as_the_subject_feels_the_grid(results_root):
    pooled = summaries_of(results_root)["all"]
    accuracy = pooled.pin_accuracy_pct
    # exact: 100 k / n is a correctly rounded quotient, and these are whole numbers
    assert accuracy[0, 3] == 50.0  # pin 4, bottom right: 2 of 4
    assert accuracy[2, 1] == 20.0  # pin 10, third row up, second column: 1 of 5
    assert accuracy[0, 0] == 50.0  # pin 1: 1 of 2 (practice and redone rows left out)
    assert np.isnan(accuracy).sum() == 13
    assert pooled.pin_trials.sum() == 11


def test_motion_felt_and_direction_right_per_subject_and_pooled(results_root):
    trials = load_results([results_root])
    pooled, a, b = (motion_summary(t.record for t in trials if t.subject in subjects)
                    for subjects in ("AB", "A", "B"))
    assert (pooled.felt.successes, pooled.felt.trials) == (5, 6)
    assert (pooled.direction_right.successes, pooled.direction_right.trials) == (3, 5)
    assert (pooled.no_wave_felt.successes, pooled.no_wave_felt.trials) == (1, 2)
    assert (a.felt.successes, a.felt.trials, a.direction_right.successes) == (3, 4, 1)
    assert (b.felt.successes, b.felt.trials, b.direction_right.successes) == (2, 2, 2)


def test_each_subject_is_summarised_on_its_own(results_root):
    groups = summaries_of(results_root)
    assert list(groups) == ["all", "sub-A", "sub-B"]
    assert groups["all"].subjects == ("A", "B")
    b_three = groups["sub-B"].localisation[0]
    assert (b_three.trials, b_three.correct.successes, b_three.error_counts) == (2, 1, (0, 0, 1, 0))


def test_the_end_of_session_lines_give_the_numbers_a_ui_shows(results_root):
    records = [t.record for t in load_results([results_root]) if t.subject == "B"]
    lines = summary_lines(records)
    assert lines[0].startswith("3 Hz: 50.0 % correct (1/2")
    assert lines[-1] == "direction right on 100 % of those (2/2)"
    assert summary_lines([]) == ["no counted trials"]


@given(st.integers(0, 500), st.integers(0, 500))
def test_a_wilson_interval_holds_the_observed_share_and_mirrors(k, extra):
    n = k + extra
    low, high = wilson_interval(k, n)
    assert 0 <= low <= high <= 1
    if n:
        assert low - 1e-12 <= k / n <= high + 1e-12
        mirrored = wilson_interval(n - k, n)
        assert_allclose((low, high), (1 - mirrored[1], 1 - mirrored[0]), atol=1e-12)


localisation_rows = st.lists(
    st.builds(
        lambda n, pin, f, answer: LocalisationRecord(
            trial=n, block=1, task="localisation", onset_ns=0, duration_ns=10**9,
            response="none" if answer == 0 else str(answer), pin=pin, frequency_hz=f),
        st.integers(1, 999), st.integers(1, 16), st.sampled_from([3.0, 5.0, 10.0]),
        st.integers(0, 16)),
    max_size=60,
)


@given(localisation_rows)
def test_correct_errors_and_nothing_felt_add_up_to_every_trial(records):
    rows = localisation_by_frequency(records)
    assert sum(row.trials for row in rows) == len(records)
    confusion = confusion_matrix(records)
    assert confusion.sum() == len(records)
    assert confusion[:, 16].sum() == sum(row.count("none") for row in rows)
    for row in rows:
        assert row.correct.successes + sum(row.error_counts) + row.none_felt == row.trials
        shares = [row.share(c).pct for c in ("correct", "A", "B", "C", "D", "none")]
        assert math.isclose(sum(shares), 100.0)
