"""Two-interval forced choice, as a protocol states it: which of two intervals had more?

    design:
      paradigm: two_interval
      stimulus: flutter               # a pattern or a wave, played in both intervals
      compare: frequency_hz           # or duration_ms, soa_ms
      standard: 10
      comparisons: [8, 9, 11, 12]
      interval_gap_ms: 500
      question: which vibrated faster?

The same stimulus twice, a standard and a comparison that differ in one parameter, in an
order balanced by construction (each comparison in both orders in every block) and shuffled
with the seed; the subject names the interval that had more of it (``first`` or ``second``).
An adaptive design adapts the comparison instead (``adaptive:`` with ``parameter`` the
compared one; its values above the standard), each value checked in both orders. Pure Python.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum
from fractions import Fraction
from typing import TYPE_CHECKING, ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.adapted import adapted_stimulus, drives_of
from pinarray.protocol.device import MS, whole_ns
from pinarray.protocol.model import (
    Condition,
    Design,
    PatternStimulus,
    PinDrive,
    Stimulus,
    WaveStimulus,
)
from pinarray.protocol.procedures import Parameter, Task
from pinarray.protocol.seam import (
    AnswerPad,
    Choice,
    DesignDefaults,
    DesignSection,
    ReadDesign,
    Written,
    read_levels,
)
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader, shown

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pinarray.grid import Grid

FIRST, SECOND = "first", "second"  # an answer: the interval that had more
COMPARED = (Parameter.FREQUENCY_HZ, Parameter.DURATION_MS, Parameter.SOA_MS)
QUESTIONS = {Parameter.FREQUENCY_HZ: "which vibrated faster?",
             Parameter.DURATION_MS: "which lasted longer?",
             Parameter.SOA_MS: "which moved more slowly?"}
DEFAULT_GAP_MS = 500
MAX_QUESTION_CHARS = 60


# Its adaptive designs' task (`Task`): which answer counts as correct.
DISCRIMINATION = "discrimination"  # the interval with the higher value named


class IntervalOrder(StrEnum):
    """Which interval of a two-interval trial holds the standard."""

    STANDARD_FIRST = "standard_first"
    COMPARISON_FIRST = "comparison_first"


@dataclass(frozen=True)
class TwoIntervalCondition(Condition):
    """One two-interval trial: ``stimulus`` at ``standard`` and at ``comparison`` of
    ``parameter`` (frequency_hz, duration_ms or soa_ms), in ``order``, the second interval
    starting ``gap_ns`` after the first ends."""

    paradigm: ClassVar[str] = "two_interval"
    parameter: Parameter
    standard: Fraction
    comparison: Fraction
    order: IntervalOrder
    gap_ns: int

    @property
    def interval_order(self) -> IntervalOrder:
        """Which interval holds the standard: what an order constraint names."""
        return self.order

    @property
    def values_in_order(self) -> tuple[Fraction, Fraction]:
        """The parameter's value in the first and in the second interval."""
        if self.order is IntervalOrder.STANDARD_FIRST:
            return self.standard, self.comparison
        return self.comparison, self.standard

    @property
    def correct_answer(self) -> str:
        """The interval with the higher value: what "which had more?" asks for."""
        first, second = self.values_in_order
        return FIRST if first > second else SECOND

    @property
    def key(self) -> tuple:
        """What tells the conditions of a design apart (and orders them alike in every plan)."""
        return (self.stimulus, self.order.value, self.comparison, None)


@dataclass(frozen=True)
class TwoInterval:
    """A two-interval design: the stimulus both intervals play, the parameter they differ in,
    the standard's value, and the ``question`` the subject answers (``faster``...)."""

    stimulus: str
    parameter: Parameter
    standard: Fraction
    gap_ns: int
    question: str


def _judgement(design: Design) -> TwoInterval:
    judgement = design.judgement
    assert isinstance(judgement, TwoInterval)
    return judgement


def _value(value: Fraction) -> str:
    return f"{float(value):g}"


class TwoIntervalDesign(DesignDefaults):
    """Two intervals as the protocol sees them (the room adds its rows and analysis)."""

    name = "two_interval"
    keys = frozenset({"stimulus", "compare", "standard", "comparisons", "interval_gap_ms",
                      "question"})
    attributes = ("comparison", "interval_order")
    # The comparison of two intervals: the design's compare.
    parameters = COMPARED
    tasks = (DISCRIMINATION,)
    balanced_draws = True  # which interval holds the comparison: as often one way as the other
    plan_columns = ("first", "second", "interval_order")

    def read(self, section: DesignSection) -> ReadDesign:
        reader, keys, adapting = section.reader, section.keys, section.adapting
        section.needs("stimulus", "compare", "standard", paradigm=self.name)
        name = reader.string(keys["stimulus"], "the stimulus both intervals play")
        stimulus = section.stimuli.get(name)
        if stimulus is None and name in section.declared:
            raise Invalid(name)  # declared but broken: its own problem is already reported
        if not isinstance(stimulus, PatternStimulus | WaveStimulus):
            raise reader.error(keys["stimulus"], f"expected the name of a pattern or a wave for "
                                                 f"both intervals to play, found {shown(name)}")
        parameter = Parameter(reader.string(keys["compare"], "the compared parameter",
                                            tuple(p.value for p in COMPARED)))
        standard = reader.number(keys["standard"], "the standard", parameter.unit)
        gap_ns = reader.optional(
            keys, "interval_gap_ms",
            lambda n: whole_ns(reader, n, reader.number(n, "the gap between the intervals", "ms",
                                                        allow_zero=True, maximum=60_000),
                               MS, "the gap between the intervals", "ms"),
            round(DEFAULT_GAP_MS * MS))
        question = reader.optional(keys, "question", lambda n: _question(reader, n),
                                   QUESTIONS[parameter])
        if adapting is not None:
            if "comparisons" in keys:
                raise reader.error(keys["comparisons"], "expected no 'comparisons' in an "
                                                        "adaptive design (its values are the "
                                                        "comparisons), found some")
            if adapting.parameter is not parameter:
                raise reader.error(adapting.node, f"expected the values of the compared "
                                                  f"{parameter.value}, found values of "
                                                  f"{adapting.parameter.value}")
            if adapting.values[0] <= standard:
                raise reader.error(adapting.node, f"expected comparisons above the standard "
                                                  f"{float(standard):g} {parameter.unit} (a "
                                                  f"higher value is easier), found "
                                                  f"{float(adapting.values[0]):g}")
            comparisons = [(adapting.node, adapting.values[-1])]  # each value checked apart
        else:
            section.needs("comparisons", paradigm=self.name)
            comparisons = read_levels(reader, keys["comparisons"], "the comparisons",
                                      parameter.unit, signed=False)
        written: list[Written] = []
        with reader.section():
            for item, comparison in comparisons:
                if comparison == standard:
                    reader.error(item, f"expected comparisons other than the standard "
                                       f"{float(standard):g} {parameter.unit} (no interval "
                                       "would have more), found it")
                    continue
                what = f"at {parameter.value} {float(comparison):g}: "
                written.extend(Written(TwoIntervalCondition(name, parameter, standard,
                                                            comparison, order, gap_ns),
                                       item, what) for order in IntervalOrder)
        return ReadDesign(tuple(written),
                          TwoInterval(name, parameter, standard, gap_ns, question))

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        """The stimulus at the first interval's value, then, ``gap_ns`` after it ends, at the
        second's."""
        if not isinstance(condition, TwoIntervalCondition) or not isinstance(
                stimulus, PatternStimulus | WaveStimulus):
            raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a "
                                f"{type(condition).__name__}")
        first_value, second_value = condition.values_in_order
        first = drives_of(adapted_stimulus(stimulus, condition.parameter, first_value))
        second = drives_of(adapted_stimulus(stimulus, condition.parameter, second_value))
        start_ns = max(d.delay_ns + d.train.duration_ns for d in first) + condition.gap_ns
        return (*first, *(PinDrive(d.pin, d.train, start_ns + d.delay_ns) for d in second))

    # -- adaptive designs ------------------------------------------------------------------

    def adapt(self, condition: Condition, parameter: Parameter, value: Fraction) -> Condition:
        assert isinstance(condition, TwoIntervalCondition)
        return replace(condition, comparison=value)

    def adapts_condition(self, condition: Condition) -> bool:
        return True

    def default_guess(self, task: Task, conditions: Sequence[Condition]) -> Fraction:
        return Fraction(1, 2)  # one of two intervals

    def counts_as_correct(self, task: Task, condition: Condition, catch: bool,
                          response: str) -> bool:
        if catch:
            return response == "none"
        return isinstance(condition, TwoIntervalCondition) and response == condition.correct_answer

    # -- answers ---------------------------------------------------------------------------

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        return (FIRST, SECOND)

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        question = _judgement(design).question
        return ((FIRST, f"the first interval, asked {question!r}"),
                (SECOND, f"the second interval, asked {question!r}"))

    def instructions(self, design: Design) -> str:
        return ("Rest your fingertip on the pins. Each trial plays two intervals one after "
                f"the other; say which one, first or second: {_judgement(design).question}")

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        return {FIRST: FIRST, SECOND: SECOND, "1": FIRST, "2": SECOND}.get(text)

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        choices = (Choice(FIRST, ("1", "left"), "← first (1)"),
                   Choice(SECOND, ("2", "right"), "second (2) →"))
        return AnswerPad(False, choices, "",
                         f"{_judgement(design).question} 1 (first) / 2 (second)")

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, TwoIntervalCondition)
        return condition.correct_answer

    def cue(self, condition: Condition, design: Design) -> tuple[object, str] | None:
        return None  # both intervals play in every trial: the answer is in neither

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, TwoIntervalCondition)
        first, second = condition.values_in_order
        unit = condition.parameter.unit
        where = "second" if condition.order is IntervalOrder.STANDARD_FIRST else "first"
        return (f"{condition.parameter.quantity} {_value(first)} {unit}, then "
                f"{_value(second)} {unit} (comparison {where})")

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, TwoIntervalCondition)
        first, second = condition.values_in_order
        return _value(first), _value(second), condition.order.value

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, TwoIntervalCondition)
        return {"compare": condition.parameter.value, "standard": str(condition.standard),
                "comparison": str(condition.comparison),
                "interval_order": condition.order.value}


def _question(reader: Reader, node: Node) -> str:
    text = " ".join(reader.string(node, "the question").split())
    if len(text) > MAX_QUESTION_CHARS:
        raise reader.error(node, f"expected a question of at most {MAX_QUESTION_CHARS} "
                                 f"characters, found {len(text)}")
    return text
