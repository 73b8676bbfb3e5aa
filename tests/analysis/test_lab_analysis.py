"""The analysis of the lab's paradigms: information transferred within its bounds, fits that
find the Weber fraction, PSS and JND a simulated subject was given, and `pinarray analyse`
turning results into the tables, figures and summary."""

import math
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pinarray.analysis.identification import information_transferred, it_bias_bits
from pinarray.analysis.judgements import judgements
from pinarray.analysis.lab_observer import LabObserverModel
from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.subjects import IntervalSettings
from pinarray.journal.records import TemporalOrderRecord, TwoIntervalRecord
from pinarray.protocol.paradigms import IntervalOrder


@settings(max_examples=200, deadline=None)
@given(arrays(np.int64, st.tuples(st.integers(1, 8), st.integers(1, 8)),
              elements=st.integers(0, 50)))
def test_information_transferred_lies_between_0_and_log2_of_the_fewer_categories(counts):
    bits = information_transferred(counts)
    rows, columns = counts.shape
    assert 0 <= bits <= math.log2(min(rows, columns)) + 1e-9
    assert it_bias_bits(counts) >= 0


@given(k=st.integers(2, 9), n=st.integers(1, 20))
def test_a_subject_who_names_every_pattern_right_transfers_log2_of_the_patterns(k, n):
    assert math.isclose(information_transferred(np.eye(k, dtype=np.int64) * n), math.log2(k))
    # ... and one who answers the same whatever was presented transfers nothing.
    assert information_transferred(np.ones((k, 1), dtype=np.int64) * n) == 0


def test_few_trials_per_cell_make_a_guessing_subject_look_informed_by_about_the_bias():
    rng = np.random.default_rng(0)
    answers = rng.integers(0, 7, size=(7, 4))  # 4 random answers to each of 7 patterns
    counts = np.zeros((7, 7), dtype=np.int64)
    for presented, row in enumerate(answers):
        for answered in row:
            counts[presented, answered] += 1
    bits, bias = information_transferred(counts), it_bias_bits(counts)
    assert bits > 0.5  # nothing was transferred, yet
    assert math.isclose(bias, 6 * 6 / (2 * 28 * math.log(2)), rel_tol=0.2)
    assert bits - bias < 0.6


def simulated_rows(model: LabObserverModel, seed: int):
    """A subject of ``model`` answering 60 two-interval trials at each comparison around
    10 Hz, and 60 temporal-order trials at each SOA."""
    rng = np.random.default_rng(seed)
    rows, trial = [], 0
    common = {"block": 1, "task": "lab", "onset_ns": 0, "duration_ns": 1}
    for comparison in (8.0, 9.0, 9.5, 10.5, 11.0, 12.0):
        p = model.p_interval_right(10.0, comparison)
        for _ in range(60):
            trial += 1
            right = rng.random() < p
            order = IntervalOrder.COMPARISON_FIRST if trial % 2 else IntervalOrder.STANDARD_FIRST
            higher_first = (order is IntervalOrder.COMPARISON_FIRST) == (comparison > 10)
            said = "first" if higher_first == right else "second"
            rows.append(TwoIntervalRecord(trial=trial, **common, compared="frequency_hz",
                                          standard=10.0, comparison=comparison,
                                          interval_order=order, pins=(6,), response=said))
    for soa_ms in (-90, -60, -30, -10, 10, 30, 60, 90):
        p = model.p_a_first(soa_ms)
        for _ in range(60):
            trial += 1
            said = "6" if rng.random() < p else "7"
            rows.append(TemporalOrderRecord(trial=trial, **common, pins=(6, 7),
                                            soa_ns=soa_ms * 1_000_000, response=said))
    return [LoadedTrial("01", "1", 1, None, r) for r in rows]


def test_the_fits_find_the_weber_fraction_pss_and_jnd_a_subject_was_given():
    model = LabObserverModel(weber=Fraction(15, 100), pss_ms=-20.0, jnd_ms=30.0, lapse=0.0,
                             subject_sd=0.0)
    found = judgements(simulated_rows(model, 1), IntervalSettings(), resamples=100)
    (two,) = found.intervals
    (order,) = found.orders
    weber, low, high = two.weber
    assert low <= weber <= high and 0.11 < weber < 0.2
    pss, pss_low, pss_high = order.pss
    assert pss_low <= pss <= pss_high and -30 < pss < -10
    assert 22 < order.jnd_ms < 40
