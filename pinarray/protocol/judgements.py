"""The ``design`` of the lab's paradigms: identification, two intervals, temporal order.

    design:                              design:                       design:
      paradigm: identification             paradigm: two_interval        paradigm: temporal_order
      patterns: [row, column, L, T]        stimulus: flutter             stimulus: tap
      answers: names     # or counts       compare: frequency_hz         pins: [6, 7]
                                           standard: 10                  soas_ms: [-80, -40, 40, 80]
                                           comparisons: [8, 9, 11, 12]
                                           interval_gap_ms: 500
                                           question: which vibrated faster?

The blocks, repetitions, order, constraints, seed, pauses and practice are every design's
(`pinarray.protocol.design`). A two-interval design presents each comparison in both orders
in every block (the standard first, then the comparison first): the order is balanced by
construction and shuffled with the seed. A two-interval or temporal-order design may adapt its
intensity instead (``adaptive:`` with ``parameter`` the compared one, or ``soa_ms``; its values
the comparisons, above the standard, or the SOAs, each presented with either pin first).
Every condition is checked as it would play (the trains on their pins, no pin driven twice at
once, the servo bus) before anything runs. Pure Python.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from fractions import Fraction
from functools import partial
from typing import NamedTuple

from pinarray.grid import Grid
from pinarray.protocol.device import MS, read_pin
from pinarray.protocol.drives import pulse_slots, stimulus_drives
from pinarray.protocol.model import (
    Condition,
    Device,
    Paradigm,
    PatternStimulus,
    Stimulus,
    Train,
    TrainStimulus,
    WaveStimulus,
)
from pinarray.protocol.paradigms import (
    MAX_PATTERNS,
    AnswerKind,
    Identification,
    IdentificationCondition,
    IntervalOrder,
    Judgement,
    TemporalOrder,
    TemporalOrderCondition,
    TwoInterval,
    TwoIntervalCondition,
)
from pinarray.protocol.procedures import Parameter
from pinarray.protocol.stimuli import check_drives, stimulus_named
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader, shown

# The keys each of the lab's paradigms reads, beside every design's own.
KEYS_OF = {
    Paradigm.IDENTIFICATION: {"patterns", "answers"},
    Paradigm.TWO_INTERVAL: {"stimulus", "compare", "standard", "comparisons", "interval_gap_ms",
                            "question", "adaptive"},
    Paradigm.TEMPORAL_ORDER: {"stimulus", "pins", "soas_ms", "adaptive"},
}
COMMON_KEYS = {"paradigm", "repetitions", "blocks", "order", "constraints", "seed",
               "inter_trial_interval_s", "practice_trials"}
COMPARED = (Parameter.FREQUENCY_HZ, Parameter.DURATION_MS, Parameter.SOA_MS)
QUESTIONS = {Parameter.FREQUENCY_HZ: "which vibrated faster?",
             Parameter.DURATION_MS: "which lasted longer?",
             Parameter.SOA_MS: "which moved more slowly?"}
ANSWER_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,23}")
DEFAULT_GAP_MS = 500
MAX_LEVELS = 200  # comparisons or SOAs of one design
MAX_QUESTION_CHARS = 60


class Adapting(NamedTuple):
    """An adaptive design's parameter and values, where the values are written."""

    parameter: Parameter
    values: tuple[Fraction, ...]
    node: Node


class LabConditions(NamedTuple):
    conditions: tuple[Condition, ...]
    slots: tuple[int, ...]  # pulse slots of each condition
    judgement: Judgement


def read_lab_design(reader: Reader, node: Node, keys: Mapping[str, Node], paradigm: Paradigm,
                    device: Device, by_name: Mapping[str, Stimulus],
                    declared: Mapping[str, Node], adapting: Adapting | None) -> LabConditions:
    """The conditions and judgement of an identification, two-interval or temporal-order
    design, each checked as it would play."""
    allowed = COMMON_KEYS | KEYS_OF[paradigm]
    for key in sorted(keys.keys() - allowed):  # the first stray key, the same every time
        raise reader.error(keys[key], f"expected the keys of {paradigm.value} designs "
                                      f"({', '.join(sorted(KEYS_OF[paradigm]))} beside every "
                                      f"design's), found {key!r}")
    match paradigm:
        case Paradigm.IDENTIFICATION:
            read = _identification(reader, node, keys, device, by_name, declared)
        case Paradigm.TWO_INTERVAL:
            read = _two_interval(reader, node, keys, device, by_name, declared, adapting)
        case _:
            read = _temporal_order(reader, node, keys, device, by_name, declared, adapting)
    return read


def _slots(condition: Condition, stimulus: Stimulus) -> int:
    return sum(pulse_slots(d.train) for d in stimulus_drives(stimulus, condition))


def _checked(reader: Reader, node: Node, condition: Condition, stimulus: Stimulus,
             device: Device, what: str) -> int:
    """``condition`` checked as it would play; its pulse slots (the design's reader checks
    them against its limits)."""
    check_drives(reader, node, stimulus_drives(stimulus, condition), device, what)
    return _slots(condition, stimulus)


def _identification(reader: Reader, node: Node, keys: Mapping[str, Node], device: Device,
                    by_name: Mapping[str, Stimulus],
                    declared: Mapping[str, Node]) -> LabConditions:
    if "patterns" not in keys:
        raise reader.error(node, "an identification design needs a 'patterns' key (the pattern "
                                 "stimuli a subject tells apart), found none")
    answers = AnswerKind(reader.optional(
        keys, "answers", lambda n: reader.string(n, "the answers", tuple(AnswerKind)),
        AnswerKind.NAMES.value))
    items = reader.sequence(keys["patterns"], "the patterns", 2)
    if len(items) > MAX_PATTERNS:
        raise reader.error(keys["patterns"], f"expected at most {MAX_PATTERNS} patterns (one "
                                             f"answer key each, 1 to 9), found {len(items)}")
    conditions: list[Condition] = []
    slots: list[int] = []
    seen: dict[tuple, str] = {}
    with reader.section():
        for item in items:
            stimulus = reader.attempt(partial(stimulus_named, reader, item, by_name, declared,
                                              PatternStimulus), None)
            if stimulus is None:
                continue
            name = stimulus.name
            if answers is AnswerKind.NAMES and not ANSWER_NAME.fullmatch(name):
                reader.error(item, f"expected a pattern name a subject can answer (a letter, "
                                   f"then letters, digits, _ or -, at most 24), found {shown(name)}")
                continue
            condition = IdentificationCondition(name, stimulus.pins)
            if condition in conditions:
                reader.error(item, f"expected each pattern once, found {name!r} again")
                continue
            played = tuple(sorted(stimulus.shape.drives(), key=lambda d: (d.pin, d.delay_ns)))
            if played in seen:
                reader.error(item, f"expected patterns a subject can tell apart, found {name!r} "
                                   f"playing exactly what {seen[played]!r} plays")
                continue
            seen[played] = name
            slot = reader.attempt(partial(_checked, reader, item, condition, stimulus, device, ""),
                                  None)
            if slot is not None:
                conditions.append(condition)
                slots.append(slot)
    patterns = tuple(c.stimulus for c in conditions if isinstance(c, IdentificationCondition))
    return LabConditions(tuple(conditions), tuple(slots), Identification(patterns, answers))


def _needs(reader: Reader, node: Node, keys: Mapping[str, Node], paradigm: Paradigm,
           *names: str) -> None:
    for key in names:
        if key not in keys:
            raise reader.error(node, f"a {paradigm.value} design needs a {key!r} key, found none")


def _levels(reader: Reader, node: Node, what: str, unit: str, signed: bool) -> list[tuple[Node, Fraction]]:
    items = reader.sequence(node, what)
    if len(items) > MAX_LEVELS:
        raise reader.error(node, f"expected at most {MAX_LEVELS} of {what}, found {len(items)}")
    read = [(item, reader.number(item, f"each of {what}", unit,
                                 minimum=-60_000 if signed else 0, maximum=60_000))
            for item in items]
    values = [value for _, value in read]
    for item, value in read:
        if values.count(value) > 1:
            raise reader.error(item, f"expected each of {what} once, found {float(value):g} "
                                     "more than once")
    return read


def _two_interval(reader: Reader, node: Node, keys: Mapping[str, Node], device: Device,
                  by_name: Mapping[str, Stimulus], declared: Mapping[str, Node],
                  adapting: Adapting | None) -> LabConditions:
    paradigm = Paradigm.TWO_INTERVAL
    _needs(reader, node, keys, paradigm, "stimulus", "compare", "standard")
    name = reader.string(keys["stimulus"], "the stimulus both intervals play")
    stimulus = by_name.get(name)
    if stimulus is None and name in declared:
        raise Invalid(name)  # declared but broken: its own problem is already reported
    if not isinstance(stimulus, PatternStimulus | WaveStimulus):
        raise reader.error(keys["stimulus"], f"expected the name of a pattern or a wave for "
                                             f"both intervals to play, found {shown(name)}")
    parameter = Parameter(reader.string(keys["compare"], "the compared parameter",
                                        tuple(p.value for p in COMPARED)))
    standard = reader.number(keys["standard"], "the standard", parameter.unit)
    gap = reader.optional(keys, "interval_gap_ms",
                          lambda n: reader.number(n, "the gap between the intervals", "ms",
                                                  allow_zero=True, maximum=60_000),
                          Fraction(DEFAULT_GAP_MS))
    question = reader.optional(keys, "question", lambda n: _question(reader, n),
                               QUESTIONS[parameter])
    gap_ns = round(gap * MS)
    if adapting is not None:
        if "comparisons" in keys:
            raise reader.error(keys["comparisons"], "expected no 'comparisons' in an adaptive "
                                                    "design (its values are the comparisons), "
                                                    "found some")
        if adapting.parameter is not parameter:
            raise reader.error(adapting.node, f"expected the values of the compared "
                                              f"{parameter.value}, found values of "
                                              f"{adapting.parameter.value}")
        if adapting.values[0] <= standard:
            raise reader.error(adapting.node, f"expected comparisons above the standard "
                                              f"{float(standard):g} {parameter.unit} (a higher "
                                              f"value is easier), found {float(adapting.values[0]):g}")
        comparisons = [(adapting.node, adapting.values[-1])]  # each value is checked apart
    else:
        _needs(reader, node, keys, paradigm, "comparisons")
        comparisons = _levels(reader, keys["comparisons"], "the comparisons", parameter.unit,
                              signed=False)
    conditions: list[Condition] = []
    slots: list[int] = []
    with reader.section():
        for item, comparison in comparisons:
            if comparison == standard:
                reader.error(item, f"expected comparisons other than the standard "
                                   f"{float(standard):g} {parameter.unit} (no interval would "
                                   "have more), found it")
                continue
            for order in IntervalOrder:
                condition = TwoIntervalCondition(name, parameter, standard, comparison, order,
                                                 gap_ns)
                what = f"at {parameter.value} {float(comparison):g}: "
                slot = reader.attempt(partial(_checked, reader, item, condition, stimulus,
                                              device, what), None)
                if slot is None:
                    break
                conditions.append(condition)
                slots.append(slot)
    return LabConditions(tuple(conditions), tuple(slots),
                         TwoInterval(name, parameter, standard, gap_ns, question))


def _question(reader: Reader, node: Node) -> str:
    text = " ".join(reader.string(node, "the question").split())
    if len(text) > MAX_QUESTION_CHARS:
        raise reader.error(node, f"expected a question of at most {MAX_QUESTION_CHARS} "
                                 f"characters, found {len(text)}")
    return text


def _temporal_order(reader: Reader, node: Node, keys: Mapping[str, Node], device: Device,
                    by_name: Mapping[str, Stimulus], declared: Mapping[str, Node],
                    adapting: Adapting | None) -> LabConditions:
    paradigm = Paradigm.TEMPORAL_ORDER
    _needs(reader, node, keys, paradigm, "stimulus", "pins")
    stimulus = stimulus_named(reader, keys["stimulus"], by_name, declared, TrainStimulus)
    if not isinstance(stimulus.train, Train):
        raise reader.error(keys["stimulus"], f"expected a train with a frequency_hz for both "
                                             f"pins, found train {stimulus.name!r} without one")
    pin_nodes = reader.sequence(keys["pins"], "the two pins", 2)
    pins = tuple(read_pin(reader, n, device.grid) for n in pin_nodes)
    if len(pins) != 2 or pins[0] == pins[1]:
        raise reader.error(keys["pins"], f"expected two different pins, found {list(pins)}")
    a, b = pins
    if adapting is not None:
        if "soas_ms" in keys:
            raise reader.error(keys["soas_ms"], "expected no 'soas_ms' in an adaptive design "
                                                "(its values are the SOAs), found some")
        # Each value is checked apart; a trial draws which pin goes first.
        soas = [(adapting.node, adapting.values[-1]), (adapting.node, -adapting.values[-1])]
    else:
        _needs(reader, node, keys, paradigm, "soas_ms")
        soas = _levels(reader, keys["soas_ms"], "the SOAs", "ms", signed=True)
    conditions: list[Condition] = []
    slots: list[int] = []
    with reader.section():
        for item, soa in soas:
            condition = TemporalOrderCondition(stimulus.name, (a, b), round(soa * MS))
            slot = reader.attempt(partial(_checked, reader, item, condition, stimulus, device,
                                          f"at an SOA of {float(soa):g} ms: "), None)
            if slot is not None:
                conditions.append(condition)
                slots.append(slot)
    return LabConditions(tuple(conditions), tuple(slots),
                         TemporalOrder(stimulus.name, (a, b), places(device.grid, a, b)))


def places(grid: Grid, a: int, b: int) -> tuple[str, str]:
    """How a subject tells pins ``a`` and ``b`` apart: left and right on a row, lower and
    upper on a column, else by their numbers."""
    (row_a, column_a), (row_b, column_b) = grid.cell(a), grid.cell(b)
    if row_a == row_b:
        return ("left", "right") if column_a < column_b else ("right", "left")
    if column_a == column_b:
        return ("lower", "upper") if row_a < row_b else ("upper", "lower")
    return (f"pin {a}", f"pin {b}")
