"""The lab's own paradigms beside the seed's two: what one trial presents and what it asks.

- **identification**: one pattern of several pins (or a sequence of patterns in time); the
  subject names which of the design's patterns it was, or how many pins were raised.
- **two-interval forced choice**: the same stimulus twice, a standard and a comparison that
  differ in one parameter (frequency, signal length, SOA), in an order balanced and seeded
  over the run; the subject says which interval had more of it (``first`` or ``second``).
- **temporal-order judgement**: a train on two pins, one starting an SOA before the other;
  the subject names the pin that came first.

Each condition is self-contained: with its stimulus it says every drive of the trial
(`pinarray.protocol.drives`). Plain values only: the model builds on this module, not the
other way round. Times are integer nanoseconds; values of a compared parameter are exact.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from fractions import Fraction

from pinarray.protocol.procedures import Parameter
from pinarray.units import NS_PER_MS

FIRST, SECOND = "first", "second"  # a two-interval answer: the interval that had more
MAX_PATTERNS = 9  # an identification design's alternatives: one key each, 1 to 9


class AnswerKind(StrEnum):
    """What an identification subject names: the pattern, or how many pins it raised."""

    NAMES = "names"
    COUNTS = "counts"


class IntervalOrder(StrEnum):
    """Which interval of a two-interval trial holds the standard."""

    STANDARD_FIRST = "standard_first"
    COMPARISON_FIRST = "comparison_first"


@dataclass(frozen=True)
class IdentificationCondition:
    """One identification trial: the pattern stimulus called ``stimulus``, raising ``pins``
    (every frame's, ascending)."""

    stimulus: str
    pins: tuple[int, ...]

    @property
    def pattern(self) -> str:
        """The pattern's name (its stimulus's): what a subject naming it answers."""
        return self.stimulus

    @property
    def count(self) -> int:
        """How many pins the pattern raises (a numerosity answer)."""
        return len(self.pins)

    @property
    def key(self) -> tuple:
        """What tells the conditions of a design apart (and orders them alike in every plan)."""
        return (self.stimulus, None, None, None)


@dataclass(frozen=True)
class TwoIntervalCondition:
    """One two-interval trial: ``stimulus`` at ``standard`` and at ``comparison`` of
    ``parameter`` (frequency_hz, duration_ms or soa_ms), in ``order``, the second interval
    starting ``gap_ns`` after the first ends."""

    stimulus: str
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
class TemporalOrderCondition:
    """One temporal-order trial: the train ``stimulus`` on ``pins`` (A, B as the design lists
    them), B starting ``soa_ns`` after A (negative: B first)."""

    stimulus: str
    pins: tuple[int, int]
    soa_ns: int

    @property
    def soa_ms(self) -> Fraction:
        """The SOA in exact milliseconds (what an order constraint and the protocol name)."""
        return Fraction(self.soa_ns, NS_PER_MS)

    @property
    def first_pin(self) -> int | None:
        """The pin whose train starts first; None when both start together."""
        if self.soa_ns == 0:
            return None
        return self.pins[0] if self.soa_ns > 0 else self.pins[1]

    @property
    def delays_ns(self) -> tuple[int, int]:
        """When A's and B's trains start after the stimulus onset."""
        return max(0, -self.soa_ns), max(0, self.soa_ns)

    @property
    def key(self) -> tuple:
        """What tells the conditions of a design apart (and orders them alike in every plan)."""
        return (self.stimulus, self.pins, self.soa_ns, None)


@dataclass(frozen=True)
class Identification:
    """An identification design: its alternatives (pattern stimuli, in the order the answer
    pad offers them) and what the subject names."""

    patterns: tuple[str, ...]
    answers: AnswerKind


@dataclass(frozen=True)
class TwoInterval:
    """A two-interval design: the stimulus both intervals play, the parameter they differ in,
    the standard's value, and the ``question`` the subject answers (``faster``...)."""

    stimulus: str
    parameter: Parameter
    standard: Fraction
    gap_ns: int
    question: str


@dataclass(frozen=True)
class TemporalOrder:
    """A temporal-order design: the train both pins play, the pins (A, B), and each pin's
    place as the subject would say it (left/right on a row, lower/upper on a column)."""

    stimulus: str
    pins: tuple[int, int]
    places: tuple[str, str]


# What the subject judges in the lab's paradigms; None in the seed's two, whose conditions
# say it all.
Judgement = Identification | TwoInterval | TemporalOrder
LabCondition = IdentificationCondition | TwoIntervalCondition | TemporalOrderCondition


def correct_answer(condition: LabCondition, judgement: Judgement) -> str | None:
    """The answer that names what ``condition`` presented (None: a temporal order with both
    pins at once, which has no right answer)."""
    match condition, judgement:
        case IdentificationCondition(), Identification(answers=AnswerKind.COUNTS):
            return str(condition.count)
        case IdentificationCondition(), _:
            return condition.pattern
        case TwoIntervalCondition(), _:
            return condition.correct_answer
        case TemporalOrderCondition(), _:
            first = condition.first_pin
            return None if first is None else str(first)
    raise AssertionError(condition)


def offered_answers(judgement: Judgement, pin_count: int) -> tuple[str, ...]:
    """Every answer a trial of the design takes, as the results write it."""
    match judgement:
        case Identification(answers=AnswerKind.NAMES, patterns=patterns):
            return patterns
        case Identification():
            return tuple(str(n) for n in range(1, pin_count + 1))
        case TwoInterval():
            return (FIRST, SECOND)
        case TemporalOrder(pins=pins):
            return tuple(str(pin) for pin in pins)
    raise AssertionError(judgement)


def answer_meanings(judgement: Judgement, pin_count: int) -> tuple[tuple[str, str], ...]:
    """Each answer the design offers with what it means, as a results sidecar says it."""
    match judgement:
        case Identification(answers=AnswerKind.NAMES, patterns=patterns):
            return tuple((name, f"named pattern {name}") for name in patterns)
        case Identification():
            return tuple((str(n), f"counted {n} pin{'s' if n > 1 else ''} raised")
                         for n in range(1, pin_count + 1))
        case TwoInterval(question=question):
            return ((FIRST, f"the first interval, asked {question!r}"),
                    (SECOND, f"the second interval, asked {question!r}"))
        case TemporalOrder(pins=pins, places=places):
            return tuple((str(pin), f"pin {pin} ({place}) came first")
                         for pin, place in zip(pins, places, strict=True))
    raise AssertionError(judgement)


def instructions(judgement: Judgement) -> str:
    """What the subject is told, for the results' sidecars."""
    match judgement:
        case Identification(answers=AnswerKind.NAMES, patterns=patterns):
            return ("Rest your fingertip on the pins. After each stimulus, name the shape the "
                    f"raised pins made: {', '.join(patterns)}.")
        case Identification():
            return ("Rest your fingertip on the pins. After each stimulus, say how many pins "
                    "were raised.")
        case TwoInterval(question=question):
            return ("Rest your fingertip on the pins. Each trial plays two intervals one after "
                    f"the other; say which one, first or second: {question}")
        case TemporalOrder(places=places):
            return ("Rest your fingertip on the pins. Two pins tap one after the other; say "
                    f"which came first: the {places[0]} or the {places[1]} one.")
    raise AssertionError(judgement)
