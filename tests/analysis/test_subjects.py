"""Subjects as the unit: each subject counts once, however many trials they answered."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy import stats as scipy_stats

from pinarray.analysis.load import RunSelection, load_results, load_runs, select_runs
from pinarray.analysis.seam import Context
from pinarray.analysis.stats import Proportion
from pinarray.analysis.study import study
from pinarray.analysis.subjects import (
    DEFAULT_SETTINGS,
    IntervalMethod,
    IntervalSettings,
    across_subjects,
    bootstrap_interval,
    t_interval,
)
from pinarray.errors import PinArrayError
from pinarray.grid import Grid
from pinarray.paradigms.apparent_motion.analysis import motions
from pinarray.paradigms.localisation.stats import subject_level, summarise_subjects
from tests.analysis.conftest import localisation_row

CONTEXT = Context(RunSelection((), (), False), IntervalSettings(), Grid())

def level_of(root):
    _, *per_subject = summarise_subjects((t.subject, t.record)
                                         for t in select_runs(load_runs([root])).trials)
    return subject_level(per_subject)


def test_a_subject_who_answered_16_trials_counts_once_in_the_across_subject_mean(tmp_path,
                                                                                 write_run):
    root = tmp_path / "results"
    write_run(root, "many", "localisation", [localisation_row(n, 4, "4") for n in range(1, 17)])
    write_run(root, "few", "localisation",
              [localisation_row(n, 4, "4" if n == 1 else "3") for n in range(1, 5)])
    correct = level_of(root).localisation[0].share("correct")
    assert correct.subjects == 2 and correct.trials == 20
    # == on floats, here and below: 100 k / n is a correctly rounded quotient, exact when the
    # percentage is a whole number or a half, and sums of such are exact in any order
    assert correct.mean_pct == (100 + 25) / 2  # each subject once
    assert correct.pooled.pct == 100 * 17 / 20  # every trial once: 85 %, not the mean


def test_the_hand_built_set_gives_subject_means_beside_the_trial_pooled_numbers(results_root):
    three, ten = level_of(results_root).localisation
    # 3 Hz: subject A 1 of 4 correct, B 1 of 2; 10 Hz: A 2 of 4, B 0 of 1.
    assert three.share("correct").values_pct == [25.0, 50.0]
    assert three.share("correct").mean_pct == 37.5
    assert_allclose(three.share("correct").pooled.pct, 100 / 3)
    assert ten.share("correct").mean_pct == 25.0 and ten.share("correct").pooled.pct == 40.0
    assert three.share("none").values_pct == [25.0, 0.0]  # nothing felt, per subject
    assert ten.share("A").values_pct == [25.0, 100.0]


def test_two_subjects_at_25_and_50_percent_give_a_bootstrap_interval_from_25_to_50(results_root):
    # Resampling two subjects gives means 25, 37.5 or 50 with odds 1:2:1: the 2.5 and 97.5
    # percentiles are the two ends (exact values: a quarter of 2000 resamples, whatever the
    # generator's stream in this numpy, sit at each end).
    correct = level_of(results_root).localisation[0].share("correct")
    assert correct.bootstrap_interval_pct == (25.0, 50.0)
    t_low, t_high = correct.t_interval_pct
    half = 12.706204736174707 * np.std([25, 50], ddof=1) / math.sqrt(2)  # t(0.975, 1 df)
    assert_allclose((t_low, t_high), (37.5 - half, 37.5 + half))


def test_motion_direction_is_judged_per_subject_among_the_trials_they_felt(results_root):
    motion = motions(load_results([results_root]), CONTEXT)
    assert_allclose(motion.felt.values_pct, [75.0, 100.0])
    assert_allclose(motion.direction_right.values_pct, [100 / 3, 100.0])
    # Subject B had no no-wave trial: left out of that mean, which then has no interval.
    assert motion.no_wave_felt.per_subject == (("A", Proportion(1, 2)),)
    assert math.isnan(motion.no_wave_felt.t_interval_pct[0])


def test_one_subject_gives_a_mean_but_no_across_subject_interval():
    alone = across_subjects([("A", Proportion(3, 8))])
    assert alone.mean_pct == 37.5
    assert all(math.isnan(v) for v in (*alone.t_interval_pct, *alone.bootstrap_interval_pct))


def test_subjects_without_trials_for_a_measure_are_left_out_of_it():
    measure = across_subjects([("A", Proportion(1, 2)), ("B", Proportion(0, 0))])
    assert measure.subjects == 1 and measure.trials == 2


def test_the_interval_method_and_the_bootstrap_seed_are_named():
    chosen = IntervalSettings(IntervalMethod.BOOTSTRAP, bootstrap_seed=7, bootstrap_resamples=500)
    assert chosen.describe() == ("95 % subject bootstrap (percentile; 500 resamples of "
                                 "subjects, seed 7; stays within 0-100 %)")
    assert chosen.describe(IntervalMethod.T).startswith("95 % t interval across subjects")
    with pytest.raises(PinArrayError, match="at least 100"):
        IntervalSettings(bootstrap_resamples=10)


def test_the_study_draws_the_chosen_interval_and_keeps_both(results_root):
    chosen = IntervalSettings(IntervalMethod.BOOTSTRAP, bootstrap_seed=3)
    result = study(select_runs(load_runs([results_root])), chosen)
    correct = result.of("localisation").level.localisation[0].share("correct")
    assert correct.interval_pct(IntervalMethod.BOOTSTRAP) == correct.bootstrap_interval_pct
    assert correct.interval_pct(IntervalMethod.T) == correct.t_interval_pct


percentages = st.lists(st.floats(0, 100, allow_nan=False), min_size=2, max_size=30)


@given(percentages)
def test_a_t_interval_holds_the_mean_and_matches_scipy(values):
    low, high = t_interval(values)
    mean = float(np.mean(values))
    assert low <= mean + 1e-9 and mean - 1e-9 <= high
    if np.std(values) > 0:
        reference = scipy_stats.t.interval(0.95, len(values) - 1, loc=mean,
                                           scale=scipy_stats.sem(values))
        assert_allclose((low, high), reference, rtol=1e-9, atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(percentages, st.integers(0, 2**32 - 1))
def test_a_bootstrap_interval_holds_the_mean_stays_in_range_and_repeats_with_its_seed(values,
                                                                                   seed):
    low, high = bootstrap_interval(values, seed, 2000)
    mean = float(np.mean(values))
    assert min(values) - 1e-9 <= low <= mean + 1e-9 <= high + 2e-9 <= max(values) + 3e-9
    assert bootstrap_interval(values, seed, 2000) == (low, high)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 12).flatmap(lambda n: st.tuples(st.integers(0, n),
                                                               st.just(n))),
                min_size=2, max_size=12))
def test_the_interval_figures_draw_by_default_never_leaves_0_to_100_percent(counts):
    measure = across_subjects([(f"s{i}", Proportion(k, n)) for i, (k, n) in enumerate(counts)])
    low, high = measure.interval_pct(DEFAULT_SETTINGS.method)
    if measure.subjects >= 2:  # an interval needs two subjects with trials
        assert 0 <= low <= high <= 100
