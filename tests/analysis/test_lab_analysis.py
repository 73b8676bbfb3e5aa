"""The analysis of the lab's paradigms: information transferred within its bounds, fits that
find the Weber fraction, PSS and JND a simulated subject was given (their credible intervals
holding them about as often as they say on the shipped designs), and words where the answers
cannot place them."""

import csv
import functools
import json
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pinarray.adaptive.posterior import ThresholdStatus
from pinarray.analysis.load import LoadedTrial, RunSelection
from pinarray.analysis.seam import Context, EstimateStatus
from pinarray.analysis.subjects import IntervalSettings
from pinarray.grid import Grid
from pinarray.paradigms.identification.analysis import (
    identifications,
    information_transferred,
    it_bias_bits,
)
from pinarray.paradigms.temporal_order.analysis import JndStatus, temporal_orders
from pinarray.paradigms.temporal_order.design import TemporalOrderCondition
from pinarray.paradigms.temporal_order.observer import (
    TemporalOrderObserver,
    TemporalOrderObserverModel,
)
from pinarray.paradigms.temporal_order.rows import TemporalOrderRecord
from pinarray.paradigms.two_interval.analysis import two_intervals
from pinarray.paradigms.two_interval.design import IntervalOrder, TwoIntervalCondition
from pinarray.paradigms.two_interval.observer import TwoIntervalObserver, TwoIntervalObserverModel
from pinarray.paradigms.two_interval.rows import TwoIntervalRecord
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
CONTEXT = Context(RunSelection((), (), False), IntervalSettings(), Grid())


def model(weber=0.2, slope=3.0, pss_ms=0.0, jnd_ms=40.0, lapse=0.02, subject_sd=0.3):
    """A two-interval and a temporal-order subject, as one lab's subject answers both."""
    return (TwoIntervalObserverModel(weber, slope, lapse, subject_sd),
            TemporalOrderObserverModel(pss_ms, jnd_ms, lapse, subject_sd))


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


def simulated_rows(subject, seed: int):
    """A subject of ``model`` answering 60 two-interval trials at each comparison around
    10 Hz, and 60 temporal-order trials at each SOA."""
    two, temporal = subject
    rng = np.random.default_rng(seed)
    rows, trial = [], 0
    common = {"block": 1, "task": "lab", "onset_ns": 0, "duration_ns": 1}
    for comparison in (8.0, 9.0, 9.5, 10.5, 11.0, 12.0):
        p = two.p_right(10.0, comparison)
        for _ in range(60):
            trial += 1
            right = rng.random() < p
            first = IntervalOrder.COMPARISON_FIRST if trial % 2 else IntervalOrder.STANDARD_FIRST
            higher_first = (first is IntervalOrder.COMPARISON_FIRST) == (comparison > 10)
            said = "first" if higher_first == right else "second"
            rows.append(TwoIntervalRecord(trial=trial, **common, compared="frequency_hz",
                                          standard=10.0, comparison=comparison,
                                          interval_order=first, pins=(6,), response=said))
    for soa_ms in (-90, -60, -30, -10, 10, 30, 60, 90):
        p = temporal.p_a_first(soa_ms)
        for _ in range(60):
            trial += 1
            said = "6" if rng.random() < p else "7"
            rows.append(TemporalOrderRecord(trial=trial, **common, pins=(6, 7),
                                            soa_ns=soa_ms * 1_000_000, response=said))
    return [LoadedTrial("01", "1", 1, None, r) for r in rows]


def test_the_fits_find_the_weber_fraction_pss_and_jnd_a_subject_was_given():
    subject = model(weber=float(Fraction(15, 100)), pss_ms=-20.0, jnd_ms=30.0, lapse=0.0,
                    subject_sd=0.0)
    rows = simulated_rows(subject, 1)
    (two,) = two_intervals(rows, CONTEXT).fits
    (order,) = temporal_orders(rows, CONTEXT).fits
    weber = two.weber
    assert weber.status is EstimateStatus.ESTIMATED
    assert weber.ci_low < 0.15 < weber.ci_high and 0.11 < weber.value < 0.2
    assert two.threshold.value == pytest.approx(10 * weber.value)
    pss = order.pss
    assert pss.ci_low < -20 < pss.ci_high and -30 < pss.value < -10
    jnd = order.jnd
    assert jnd.words == JndStatus.ESTIMATED
    assert jnd.ci_low < 30 < jnd.ci_high and 22 < jnd.value < 40


@functools.cache
def shipped_plans():
    """protocols/flutter_2ifc.yaml and protocols/toj.yaml with a plan of each."""
    protocols = [load_protocol(PROTOCOLS / f"{name}.yaml") for name in ("flutter_2ifc", "toj")]
    return [(name.replace("_", ""), protocol, make_plan(protocol, 1))
            for name, protocol in zip(("flutter_2ifc", "toj"), protocols, strict=True)]


def shipped_design_rows(models, seed: int, subject: str = "01"):
    """A subject of ``models`` running protocols/flutter_2ifc.yaml and protocols/toj.yaml as
    planned, answering as each paradigm's simulated subject does."""
    rows = []
    for (task, _, plan), observer in zip(shipped_plans(),
                                        (TwoIntervalObserver(models[0], seed),
                                         TemporalOrderObserver(models[1], seed)), strict=True):
        for planned in plan.trials:
            c, said = planned.condition, observer(planned.condition)
            common = {"trial": planned.trial, "block": planned.block, "task": task,
                      "onset_ns": 0, "duration_ns": 1, "practice": planned.practice}
            match c:
                case TwoIntervalCondition():
                    rows.append(TwoIntervalRecord(
                        **common, compared=c.parameter.value, standard=float(c.standard),
                        comparison=float(c.comparison), interval_order=c.order, pins=(6,),
                        response=said))
                case TemporalOrderCondition():
                    rows.append(TemporalOrderRecord(**common, pins=c.pins, soa_ns=c.soa_ns,
                                                    response=said))
    return [LoadedTrial(subject, "1", 1, None, r) for r in rows]


def test_the_intervals_hold_the_truth_about_95_percent_of_the_time_on_the_shipped_designs():
    # 40 subjects across the range a lab meets (each room's COVERAGE: 900 of them).
    rng = np.random.default_rng(40)
    held = {"weber": 0, "pss": 0, "jnd": 0}
    for subject in range(40):
        two_model, order_model = models = model(
            weber=rng.uniform(0.1, 0.3), slope=rng.uniform(1.5, 5.0),
            pss_ms=rng.uniform(-30, 30), jnd_ms=rng.uniform(20, 60), lapse=rng.uniform(0, 0.04),
            subject_sd=0.0)
        rows = shipped_design_rows(models, subject)
        (two,), (order,) = two_intervals(rows, CONTEXT).fits, temporal_orders(rows, CONTEXT).fits
        for name, estimate, truth in (("weber", two.weber, two_model.weber),
                                      ("pss", order.pss, order_model.pss_ms),
                                      ("jnd", order.jnd, order_model.jnd_ms)):
            # A bound in words counts by the bound it states (n/a: no bound that side).
            low = -math.inf if math.isnan(estimate.ci_low) else estimate.ci_low
            high = math.inf if math.isnan(estimate.ci_high) else estimate.ci_high
            held[name] += estimate.words != "not fitted" and low <= truth <= high
    # 6 misses or fewer: a 95 % interval has 6 or fewer in 40 with probability 0.99.
    assert min(held.values()) >= 34, held


def test_answers_that_cannot_place_a_value_give_words_and_the_bound_they_state(tmp_path):
    steady = model(weber=0.2, pss_ms=0.0, jnd_ms=40.0, lapse=0.0, subject_sd=0.0)
    keen = model(weber=0.01, pss_ms=0.0, jnd_ms=0.5, lapse=0.0, subject_sd=0.0)
    rows = shipped_design_rows(steady, 1, "01") + shipped_design_rows(keen, 2, "02")
    intervals, orders = two_intervals(rows, CONTEXT), temporal_orders(rows, CONTEXT)
    two, order = ({f.subject: f for f in fits} for fits in (intervals.fits, orders.fits))
    # Subject 02 told every comparison apart: the threshold lies below the smallest
    # difference tested (1 Hz), and is no number.
    assert two["02"].threshold.status is EstimateStatus.BOUNDED
    assert two["02"].threshold.words == ThresholdStatus.BELOW
    assert math.isnan(two["02"].threshold.value) and two["02"].threshold.ci_high < 1.0
    assert math.isnan(two["02"].weber.value) and two["02"].weber.ci_high < 0.1
    # ... and named the right pin at every SOA: the PSS lies between -15 and 15 ms, the JND
    # below what SOAs of 15 ms resolve.
    assert order["02"].pss.status is EstimateStatus.ESTIMATED
    assert order["02"].jnd.words == JndStatus.BELOW and order["02"].jnd.ci_high < 15
    across = {(m.task, m.measure): m for m in (*intervals.across, *orders.across)}
    assert [s for s, _ in across["flutter2ifc", "weber_fraction"].per_subject] == ["01"]
    assert [s for s, _ in across["toj", "jnd_ms"].per_subject] == ["01"]
    assert [s for s, _ in across["toj", "pss_ms"].per_subject] == ["01", "02"]

    assert not identifications(rows, CONTEXT).per_subject  # no identification rows among them
    intervals.tables(tmp_path)
    orders.tables(tmp_path)
    table = {r["subject"]: r for r in csv.DictReader((tmp_path / "two_interval.csv").open())}
    assert (table["02"]["threshold"], table["02"]["status"]) == ("n/a", "below the lowest "
                                                                 "value tested")
    assert table["01"]["status"] == "estimated" and table["all"]["status"] == "n/a"
    toj = {r["subject"]: r for r in csv.DictReader((tmp_path / "temporal_order.csv").open())}
    assert (toj["02"]["jnd_ms"], toj["02"]["jnd_status"]) == ("n/a", "below what the answers "
                                                              "resolve")
    sidecar = json.loads((tmp_path / "temporal_order.json").read_text())
    assert "Bayesian logistic fit" in sidecar["pss_ms"]["Description"]
    assert "below what the answers resolve" in sidecar["jnd_status"]["Levels"]
    summary = "\n".join([*intervals.sections(), *orders.sections()])
    assert "subject 02, task flutter2ifc: threshold *below the lowest value tested* (<" in summary
    assert "Bayesian Weibull fit" in summary and "credible interval" in summary
