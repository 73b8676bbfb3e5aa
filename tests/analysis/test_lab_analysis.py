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
from pinarray.analysis.identification import (
    identifications,
    information_transferred,
    it_bias_bits,
)
from pinarray.analysis.judgements import JndStatus, judgements
from pinarray.analysis.lab_observer import LabObserver, LabObserverModel
from pinarray.analysis.lab_report import lab_sections, lab_tables
from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.subjects import IntervalSettings
from pinarray.journal.records import TemporalOrderRecord, TwoIntervalRecord
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol
from pinarray.protocol.paradigms import IntervalOrder, TemporalOrderCondition, TwoIntervalCondition

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"


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
    found = judgements(simulated_rows(model, 1), IntervalSettings())
    (two,) = found.intervals
    (order,) = found.orders
    weber = two.weber
    assert weber.status is ThresholdStatus.ESTIMATED
    assert weber.ci_low < 0.15 < weber.ci_high and 0.11 < weber.value < 0.2
    assert two.threshold.value == pytest.approx(10 * weber.value)
    pss = order.pss
    assert pss.ci_low < -20 < pss.ci_high and -30 < pss.value < -10
    jnd = order.jnd
    assert jnd.status is JndStatus.ESTIMATED
    assert jnd.ci_low < 30 < jnd.ci_high and 22 < jnd.value < 40


@functools.cache
def shipped_plans():
    """protocols/flutter_2ifc.yaml and protocols/toj.yaml with a plan of each."""
    protocols = [load_protocol(PROTOCOLS / f"{name}.yaml") for name in ("flutter_2ifc", "toj")]
    return [(name.replace("_", ""), protocol, make_plan(protocol, 1))
            for name, protocol in zip(("flutter_2ifc", "toj"), protocols, strict=True)]


def shipped_design_rows(model: LabObserverModel, seed: int, subject: str = "01"):
    """A subject of ``model`` running protocols/flutter_2ifc.yaml and protocols/toj.yaml as
    planned, answering as `LabObserver` does."""
    rows = []
    for task, protocol, plan in shipped_plans():
        observer = LabObserver(protocol, model, seed)
        for planned in plan.trials:
            c, said = planned.condition, observer.respond(planned.condition)
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
    # 40 subjects across the range a lab meets (judgements.COVERAGE: 900 of them).
    rng = np.random.default_rng(40)
    held = {"weber": 0, "pss": 0, "jnd": 0}
    for subject in range(40):
        model = LabObserverModel(weber=rng.uniform(0.1, 0.3), slope=rng.uniform(1.5, 5.0),
                                 pss_ms=rng.uniform(-30, 30), jnd_ms=rng.uniform(20, 60),
                                 lapse=rng.uniform(0, 0.04), subject_sd=0.0)
        found = judgements(shipped_design_rows(model, subject), IntervalSettings())
        (two,), (order,) = found.intervals, found.orders
        for name, estimate, truth in (("weber", two.weber, model.weber),
                                      ("pss", order.pss, model.pss_ms),
                                      ("jnd", order.jnd, model.jnd_ms)):
            # A bound in words counts by the bound it states (n/a: no bound that side).
            low = -math.inf if math.isnan(estimate.ci_low) else estimate.ci_low
            high = math.inf if math.isnan(estimate.ci_high) else estimate.ci_high
            held[name] += estimate.status is not None and low <= truth <= high
    # 6 misses or fewer: a 95 % interval has 6 or fewer in 40 with probability 0.99.
    assert min(held.values()) >= 34, held


def test_answers_that_cannot_place_a_value_give_words_and_the_bound_they_state(tmp_path):
    steady = LabObserverModel(weber=0.2, pss_ms=0.0, jnd_ms=40.0, lapse=0.0, subject_sd=0.0)
    keen = LabObserverModel(weber=0.01, pss_ms=0.0, jnd_ms=0.5, lapse=0.0, subject_sd=0.0)
    rows = shipped_design_rows(steady, 1, "01") + shipped_design_rows(keen, 2, "02")
    found = judgements(rows, IntervalSettings())
    two, order = ({f.subject: f for f in fits} for fits in (found.intervals, found.orders))
    # Subject 02 told every comparison apart: the threshold lies below the smallest
    # difference tested (1 Hz), and is no number.
    assert two["02"].threshold.status is ThresholdStatus.BELOW
    assert math.isnan(two["02"].threshold.value) and two["02"].threshold.ci_high < 1.0
    assert math.isnan(two["02"].weber.value) and two["02"].weber.ci_high < 0.1
    # ... and named the right pin at every SOA: the PSS lies between -15 and 15 ms, the JND
    # below what SOAs of 15 ms resolve.
    assert order["02"].pss.status is ThresholdStatus.ESTIMATED
    assert order["02"].jnd.status is JndStatus.BELOW and order["02"].jnd.ci_high < 15
    across = {(m.task, m.measure): m for m in found.across}
    assert [s for s, _ in across["flutter2ifc", "weber_fraction"].per_subject] == ["01"]
    assert [s for s, _ in across["toj", "jnd_ms"].per_subject] == ["01"]
    assert [s for s, _ in across["toj", "pss_ms"].per_subject] == ["01", "02"]

    none = identifications(rows, IntervalSettings())  # no identification rows among them
    lab_tables(none, found, IntervalSettings(), tmp_path)
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
    summary = "\n".join(lab_sections(none, found, IntervalSettings()))
    assert "subject 02, task flutter2ifc: threshold *below the lowest value tested* (<" in summary
    assert "Bayesian Weibull fit" in summary and "credible interval" in summary
