"""The lab's own designs as a lab writes them: which pattern, which interval, which pin first;
their conditions, answers, plans, and every mistake located."""

import functools
from collections import Counter
from fractions import Fraction
from itertools import groupby

from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.paradigms.identification.design import AnswerKind
from pinarray.paradigms.temporal_order.design import TemporalOrderCondition
from pinarray.paradigms.two_interval.design import IntervalOrder, TwoIntervalCondition
from pinarray.plan import make_plan
from pinarray.protocol.drives import trial_drives
from pinarray.protocol.load import load_protocol, parse_protocol, protocol_warnings, validate_file
from pinarray.protocol.procedures import Parameter
from tests.lab_protocols import PROTOCOLS
from tests.test_protocol_load import problems

SHAPES, FLUTTER, TOJ = (PROTOCOLS / f"{n}.yaml" for n in ("shapes", "flutter_2ifc", "toj"))

LAB = """\
protocol: lab
stimuli:
  tap: {{frequency_hz: 10, duration_s: 0.2}}
  row: {{pattern: [5, 6, 7, 8], train: tap}}
  column: {{pattern: [2, 6, 10, 14], train: tap}}
  corner: {{pattern: [1, 2, 5], train: tap}}
design:
{design}
"""


def lab(design: str) -> str:
    return LAB.format(design="\n".join("  " + line for line in design.strip().splitlines()))


def test_the_three_ready_protocols_validate():
    for path in (SHAPES, FLUTTER, TOJ):
        protocol, found = validate_file(path)
        assert found == [] and protocol is not None


def test_shapes_offer_the_seven_patterns_as_answers_in_the_order_listed():
    protocol = load_protocol(SHAPES)
    answers = protocol.design.answers(16)
    assert answers == ("across", "upright", "rising", "falling", "L", "T", "square")
    square = next(c for c in protocol.design.conditions if c.pattern == "square")
    assert square.pins == (5, 6, 7, 9, 11, 13, 14, 15)
    assert protocol.design.paradigm.correct_answer(square, protocol.design) == "square"


def test_a_numerosity_design_is_answered_by_counting_the_raised_pins():
    protocol = parse_protocol(lab("paradigm: identification\npatterns: [row, corner]\n"
                                  "answers: counts"))
    judgement = protocol.design.judgement
    assert judgement.answers is AnswerKind.COUNTS
    assert [protocol.design.paradigm.correct_answer(c, protocol.design)
            for c in protocol.design.conditions] == ["4", "3"]
    assert protocol.design.answers(16)[-1] == "16"


def test_identification_mistakes_are_located():
    assert problems(lab("paradigm: identification\npatterns: [row, tap]")) == [
        "p.yaml:9:19: expected the name of a pattern, found 'tap'; the stimuli section has "
        "column, corner, row"]
    assert problems(lab("paradigm: identification\npatterns: [row, row]")) == [
        "p.yaml:9:19: expected each pattern once, found 'row' again"]
    assert problems(lab("paradigm: identification\npatterns: [row, column]\n"
                        "frequencies_hz: [5]")) == [
        "p.yaml:10:19: expected the keys of identification designs (answers, patterns beside "
        "every design's), found 'frequencies_hz'"]
    assert problems(lab("paradigm: identification\npatterns: [row, column]\n"
                        "adaptive: {parameter: soa_ms}"))[0].startswith(
        "p.yaml:10:13: expected no 'adaptive' in an identification design")


def test_patterns_a_subject_cannot_tell_apart_are_refused():
    text = LAB.replace("corner: {{pattern: [1, 2, 5], train: tap}}",
                       "corner: {{pattern: [8, 7, 6, 5], train: tap}}")
    text = text.format(design="  paradigm: identification\n  patterns: [row, corner]")
    assert problems(text) == ["p.yaml:9:19: expected patterns a subject can tell apart, found "
                              "'corner' playing exactly what 'row' plays"]


def test_a_two_interval_trial_is_the_standard_and_a_comparison_in_either_order():
    protocol = load_protocol(FLUTTER)
    conditions = protocol.design.conditions
    assert {(c.comparison, c.order) for c in conditions} == {
        (Fraction(c), order) for c in (7, 8, 9, 11, 12, 13) for order in IntervalOrder}
    twelve_first = TwoIntervalCondition("flutter", Parameter.FREQUENCY_HZ, Fraction(10),
                                        Fraction(12), IntervalOrder.COMPARISON_FIRST,
                                        500_000_000)
    assert twelve_first in conditions and twelve_first.correct_answer == "first"
    drives = trial_drives(protocol, twelve_first)
    # 1 s at 12 Hz on the four central pins, 0.5 s of nothing, 1 s at 10 Hz
    assert {(d.pin, d.delay_ns, d.train.frequency_hz) for d in drives} == {
        *((p, 0, 12) for p in (6, 7, 10, 11)), *((p, 1_500_000_000, 10) for p in (6, 7, 10, 11))}


def test_a_comparison_equal_to_the_standard_has_no_right_answer_and_is_refused():
    text = FLUTTER.read_text().replace("comparisons: [7, 8, 9, 11, 12, 13]",
                                       "comparisons: [9, 10, 11]")
    assert problems(text) == ["p.yaml:32:20: expected comparisons other than the standard 10 "
                              "Hz (no interval would have more), found it"]


@functools.cache
def flutter_protocol():
    """protocols/flutter_2ifc.yaml, read once by the first test that asks (not as every test
    process collects this file)."""
    return load_protocol(FLUTTER)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_every_block_of_a_two_interval_plan_holds_each_comparison_in_both_orders_alike(seed):
    protocol = flutter_protocol()
    plan = make_plan(protocol, seed)
    for block in (1, 2):
        counted = Counter((t.condition.comparison, t.condition.order) for t in plan.trials
                          if t.block == block)
        assert set(counted.values()) == {4}  # each comparison 4 times in each order
        runs = [t.condition.order for t in plan.trials if t.block == block]
        longest = max(len(list(g)) for _, g in groupby(runs))
        assert longest <= 4  # the protocol's max_run on interval_order
    assert make_plan(protocol, seed) == plan


ADAPTIVE_2IFC = """\
protocol: flutter_up
stimuli:
  vibration: {frequency_hz: 10, duration_s: 1}
  flutter: {pattern: [6, 7], train: vibration}
design:
  paradigm: two_interval
  stimulus: flutter
  compare: frequency_hz
  standard: 10
  adaptive:
    parameter: frequency_hz
    values: {from: 10.5, to: 13, step: 0.5}
    task: discrimination
    procedures:
      down: {method: staircase, start: 13, down: 2, up: 1, stop_after_trials: 21,
             estimate_reversals: 4}
  practice_trials: 1
"""


@functools.cache
def adaptive_protocol():
    return parse_protocol(ADAPTIVE_2IFC)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_an_adaptive_two_interval_plan_puts_the_comparison_first_half_the_time(seed):
    protocol = adaptive_protocol()
    adaptive = protocol.design.adaptive
    assert (adaptive.task, adaptive.guess_rate) == ("discrimination", Fraction(1, 2))
    first = [t.condition.order is IntervalOrder.COMPARISON_FIRST
             for t in make_plan(protocol, seed).trials if not t.practice]
    assert abs(2 * sum(first) - len(first)) <= 1


def test_adaptive_comparisons_must_lie_above_the_standard():
    text = ADAPTIVE_2IFC.replace("from: 10.5", "from: 9.5")
    assert problems(text) == ["p.yaml:12:13: expected comparisons above the standard 10 Hz (a "
                              "higher value is easier), found 9.5"]


def test_a_temporal_order_trial_starts_pin_b_an_soa_after_pin_a():
    protocol = load_protocol(TOJ)
    judgement = protocol.design.judgement
    assert judgement.pins == (6, 7) and judgement.places == ("left", "right")
    assert [c.soa_ns // 1_000_000 for c in protocol.design.conditions] == [
        -120, -60, -30, -15, 15, 30, 60, 120]
    right_first = TemporalOrderCondition("tap", (6, 7), -30_000_000)
    assert right_first.first_pin == 7
    assert protocol.design.paradigm.correct_answer(right_first, protocol.design) == "7"
    assert {(d.pin, d.delay_ns) for d in trial_drives(protocol, right_first)} == {
        (6, 30_000_000), (7, 0)}
    assert protocol.design.answers(16) == ("6", "7")


def test_temporal_order_needs_two_different_pins():
    text = TOJ.read_text().replace("pins: [6, 7] ", "pins: [6, 6] ")
    assert problems(text) == ["p.yaml:25:9: expected two different pins, found [6, 6]"]


def test_patterns_that_last_different_times_are_warned_of_as_a_cue():
    text = LAB.replace("design:", "  sweep: {{frames: [row, column], soa_ms: 300}}\ndesign:")
    protocol = parse_protocol(lab_text(text, "paradigm: identification\npatterns: [row, sweep]"))
    (warning,) = protocol_warnings(protocol)
    assert warning.startswith("the stimuli a subject must tell apart last different times "
                              "(sweep 0.500 s; row 0.200 s)")
    # Two intervals play both values in every trial: their lengths tell nothing.
    assert protocol_warnings(flutter_protocol()) == []


def lab_text(template: str, design: str) -> str:
    return template.format(design="\n".join("  " + line for line in design.splitlines()))


def test_a_train_cut_inside_a_lift_is_warned_of():
    assert protocol_warnings(flutter_protocol()) == []  # 1 s: a whole number of half cycles
    cut = parse_protocol(FLUTTER.read_text().replace("duration_s: 1\n", "duration_s: 0.3\n"))
    assert protocol_warnings(cut)[0] == (
        "flutter at 7 Hz ends 14.3 ms into a lift of 71.4 ms: the pin is lowered before it may "
        "finish its stroke; give the signal a whole number of half cycles")
