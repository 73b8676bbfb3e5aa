"""Temporal-order judgement, as a protocol states it: two pins tap; which came first?

    design:
      paradigm: temporal_order
      stimulus: tap                   # a train, played on both pins
      pins: [6, 7]                    # pin A, pin B
      soas_ms: [-80, -40, 40, 80]     # B's onset minus A's: negative, B first

The subject names the pin that came first (on a row by its place, left or right; on a
column lower or upper). An adaptive design adapts the SOA instead (``adaptive:`` with
``parameter: soa_ms``), each value presented with either pin first. Pure Python.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction
from typing import TYPE_CHECKING, ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.device import MS, read_pin, whole_ns
from pinarray.protocol.model import (
    Condition,
    Design,
    PinDrive,
    Stimulus,
    Train,
    TrainStimulus,
)
from pinarray.protocol.procedures import Parameter, Task
from pinarray.protocol.seam import (
    KEY_NAMES,
    AnswerPad,
    Choice,
    DesignDefaults,
    DesignSection,
    ReadDesign,
    Written,
    read_levels,
)
from pinarray.protocol.stimuli import stimulus_named
from pinarray.units import NS_PER_MS

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pinarray.grid import Grid

# Keys and labels of the pin-first answers, by the pins' places (`places`): short enough for
# two buttons in 80 columns.
PLACE_KEYS = {"left": (("l", "left"), "← left (l)"), "right": (("r", "right"), "right (r) →"),
              "lower": (("down",), "↓ lower"), "upper": (("up",), "↑ upper")}


# Its adaptive designs' task (`Task`): which answer counts as correct.
ORDER = "order"  # the pin that came first named


@dataclass(frozen=True)
class TemporalOrderCondition(Condition):
    """One temporal-order trial: the train ``stimulus`` on ``pins`` (A, B as the design lists
    them), B starting ``soa_ns`` after A (negative: B first)."""

    paradigm: ClassVar[str] = "temporal_order"
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
class TemporalOrder:
    """A temporal-order design: the train both pins play, the pins (A, B), and each pin's
    place as the subject would say it (left/right on a row, lower/upper on a column)."""

    stimulus: str
    pins: tuple[int, int]
    places: tuple[str, str]


def _judgement(design: Design) -> TemporalOrder:
    judgement = design.judgement
    assert isinstance(judgement, TemporalOrder)
    return judgement


def places(grid: Grid, a: int, b: int) -> tuple[str, str]:
    """How a subject tells pins ``a`` and ``b`` apart: left and right on a row, lower and
    upper on a column, else by their numbers."""
    (row_a, column_a), (row_b, column_b) = grid.cell(a), grid.cell(b)
    if row_a == row_b:
        return ("left", "right") if column_a < column_b else ("right", "left")
    if column_a == column_b:
        return ("lower", "upper") if row_a < row_b else ("upper", "lower")
    return (f"pin {a}", f"pin {b}")


class TemporalOrderDesign(DesignDefaults):
    """Temporal order as the protocol sees it (the room adds its rows and analysis)."""

    name = "temporal_order"
    keys = frozenset({"stimulus", "pins", "soas_ms"})
    attributes = ("soa_ms", "first_pin")
    parameters = (Parameter.SOA_MS,)
    tasks = (ORDER,)
    balanced_draws = True  # which pin goes first: as often one as the other
    plan_columns = ("pins", "soa_ms")

    def read(self, section: DesignSection) -> ReadDesign:
        reader, keys, adapting = section.reader, section.keys, section.adapting
        section.needs("stimulus", "pins", paradigm=self.name)
        stimulus = stimulus_named(reader, keys["stimulus"], section.stimuli, section.declared,
                                  TrainStimulus)
        if not isinstance(stimulus.train, Train):
            raise reader.error(keys["stimulus"], f"expected a train with a frequency_hz for "
                                                 f"both pins, found train {stimulus.name!r} "
                                                 "without one")
        pin_nodes = reader.sequence(keys["pins"], "the two pins", 2)
        pins = tuple(read_pin(reader, n, section.device.grid) for n in pin_nodes)
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
            section.needs("soas_ms", paradigm=self.name)
            soas = read_levels(reader, keys["soas_ms"], "the SOAs", "ms", signed=True)
        written = tuple(Written(TemporalOrderCondition(
            stimulus.name, (a, b), whole_ns(reader, item, soa, MS, "an SOA", "ms")),
            item, f"at an SOA of {float(soa):g} ms: ") for item, soa in soas)
        return ReadDesign(written, TemporalOrder(stimulus.name, (a, b),
                                                 places(section.device.grid, a, b)))

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        match stimulus, condition:
            case TrainStimulus(train=Train() as train), TemporalOrderCondition(pins=(a, b)):
                first, second = condition.delays_ns
                return (PinDrive(a, train, first), PinDrive(b, train, second))
        raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a "
                            f"{type(condition).__name__}")

    # -- adaptive designs ------------------------------------------------------------------

    def adapt(self, condition: Condition, parameter: Parameter, value: Fraction) -> Condition:
        assert isinstance(condition, TemporalOrderCondition)
        return replace(condition,
                       soa_ns=round(value * NS_PER_MS) * (-1 if condition.soa_ns < 0 else 1))

    def adapts_condition(self, condition: Condition) -> bool:
        return True

    def default_guess(self, task: Task, conditions: Sequence[Condition]) -> Fraction:
        return Fraction(1, 2)  # one of two pins

    def counts_as_correct(self, task: Task, condition: Condition, catch: bool,
                          response: str) -> bool:
        if catch:
            return response == "none"
        return (isinstance(condition, TemporalOrderCondition)
                and response == str(condition.first_pin))

    # -- answers ---------------------------------------------------------------------------

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        return tuple(str(pin) for pin in _judgement(design).pins)

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        judgement = _judgement(design)
        return tuple((str(pin), f"pin {pin} ({place}) came first")
                     for pin, place in zip(judgement.pins, judgement.places, strict=True))

    def instructions(self, design: Design) -> str:
        places_ = _judgement(design).places
        return ("Rest your fingertip on the pins. Two pins tap one after the other; say which "
                f"came first: the {places_[0]} or the {places_[1]} one.")

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        judgement = _judgement(design)
        written = {str(pin): str(pin) for pin in judgement.pins} | {
            place: str(pin) for pin, place in zip(judgement.pins, judgement.places, strict=True)}
        return written.get(text)

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        judgement = _judgement(design)
        choices = tuple(_pin_first(pin, place, n) for n, (pin, place)
                        in enumerate(zip(judgement.pins, judgement.places, strict=True), start=1))
        hint = " / ".join(f"{KEY_NAMES.get(c.keys[0], c.keys[0])} ({place} pin {c.answer})"
                          for c, place in zip(choices, judgement.places, strict=True))
        return AnswerPad(False, choices, "", f"which came first? {hint}")

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, TemporalOrderCondition)
        first = condition.first_pin
        return None if first is None else str(first)

    def cue(self, condition: Condition, design: Design) -> tuple[object, str] | None:
        return None  # both pins play in every trial: the answer is in neither

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, TemporalOrderCondition)
        a, b = condition.pins
        if not condition.soa_ns:
            return f"pins {a} and {b} together"
        leading, trailing = (a, b) if condition.soa_ns > 0 else (b, a)
        return f"pin {leading}, then pin {trailing} {float(abs(condition.soa_ms)):g} ms later"

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, TemporalOrderCondition)
        return " ".join(map(str, condition.pins)), f"{float(condition.soa_ms):g}"

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, TemporalOrderCondition)
        return {"pins": list(condition.pins), "soa_ns": condition.soa_ns}


def _pin_first(pin: int, place: str, number: int) -> Choice:
    if place in PLACE_KEYS:
        keys, label = PLACE_KEYS[place]
        return Choice(str(pin), keys, label)
    return Choice(str(pin), (str(number),), f"pin {pin} ({number})")
