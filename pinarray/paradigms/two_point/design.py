"""Two-point discrimination, as a protocol states it: one pin or two at once; one point or two?

    design:
      paradigm: two_point
      stimulus: press                  # a train, played on one pin or on two at once
      pairs: [[6, 7], [6, 8], [1, 11]] # two pins; how far apart follows from the grid's pitch
      single_pins: [6, 7, 8]           # one-pin trials (default: every pin of the pairs)
      single_stimuli: [press, press_deep]  # the one-pin trials rove over these trains

Each pair is a two-pin trial, its distance (centre to centre, mm) from the device's grid
pitch (2 mm: 2, 2.83, 4, 4.47 ... mm); each single pin with each single stimulus is a one-pin
trial. The subject says ``one`` or ``two``.

Two pins press with about twice the force of one, so a subject may answer by intensity alone.
``single_stimuli`` lets the one-pin trials rove over trains of several strokes (pulse widths)
so that force does not tell one from two; a design without it is warned of at validate
(`TwoPointDesign.warnings`). Pure Python.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.device import read_pin
from pinarray.protocol.model import (
    Condition,
    Design,
    PinDrive,
    Protocol,
    Stimulus,
    Train,
    TrainStimulus,
)
from pinarray.protocol.seam import (
    AnswerPad,
    Choice,
    DesignDefaults,
    DesignSection,
    ReadDesign,
    Written,
    choices_hint,
)
from pinarray.protocol.stimuli import stimulus_named

if TYPE_CHECKING:
    from pinarray.grid import Grid
    from pinarray.protocol.yaml_nodes import Node, Reader

ONE, TWO = "one", "two"
MAX_PAIRS = 120  # every pair of a 4 x 4 grid
DISTANCE_DIGITS = 4  # a distance in mm, to 0.1 um: exact in a plan, a row and a table
# The distances a design may tell apart: a row's trial_type names its distance to 0.01 mm,
# so two distances that round alike there (or a pair at 0 mm) would be one level.
LABEL_DIGITS = 2


@dataclass(frozen=True)
class TwoPointCondition(Condition):
    """One two-point trial: the train ``stimulus`` on ``pins`` at once, one pin or two
    ``distance_mm`` apart (centre to centre; 0 for one pin)."""

    paradigm: ClassVar[str] = "two_point"
    pins: tuple[int, ...]
    distance_mm: float

    @property
    def count(self) -> int:
        """How many pins press: 1 or 2 (what the subject judges)."""
        return len(self.pins)

    @property
    def key(self) -> tuple:
        """What tells the conditions of a design apart (and orders them alike in every plan)."""
        return (self.stimulus, self.pins)


def distance_mm(grid: Grid, a: int, b: int) -> float:
    """How far apart pins ``a`` and ``b`` are, centre to centre, in mm (the grid's pitch)."""
    (xa, ya), (xb, yb) = grid.position_mm(a), grid.position_mm(b)
    return round(math.hypot(xa - xb, ya - yb), DISTANCE_DIGITS)


def _train(reader: Reader, node: Node, section: DesignSection) -> TrainStimulus:
    stimulus = stimulus_named(reader, node, section.stimuli, section.declared, TrainStimulus)
    if not isinstance(stimulus.train, Train):
        raise reader.error(node, f"expected a train with a frequency_hz, found train "
                                 f"{stimulus.name!r} without one")
    return stimulus


class TwoPointDesign(DesignDefaults):
    """Two-point discrimination as the protocol sees it (the room adds its rows and analysis)."""

    name = "two_point"
    keys = frozenset({"stimulus", "pairs", "single_pins", "single_stimuli"})
    attributes = ("pins", "count", "distance_mm")
    plan_columns = ("pins", "distance_mm")

    def read(self, section: DesignSection) -> ReadDesign:
        reader, keys, grid = section.reader, section.keys, section.device.grid
        section.needs("stimulus", "pairs", paradigm=self.name)
        stimulus = _train(reader, keys["stimulus"], section)
        pair_nodes = reader.sequence(keys["pairs"], "the pairs of pins")
        if len(pair_nodes) > MAX_PAIRS:
            raise reader.error(keys["pairs"], f"expected at most {MAX_PAIRS} pairs, found "
                                              f"{len(pair_nodes)}")
        written: list[Written] = []
        seen: set[tuple[int, ...]] = set()
        labels: dict[float, tuple[float, tuple[int, ...]]] = {}
        for item in pair_nodes:
            pins = reader.attempt(partial(self._pair, reader, item, grid), None)
            if pins is None:
                continue
            if pins in seen:
                reader.error(item, f"expected each pair once, found pins {pins[0]} and "
                                   f"{pins[1]} again")
                continue
            seen.add(pins)
            d = distance_mm(grid, *pins)
            if reader.attempt(partial(self._apart, reader, item, pins, d, grid.pitch_mm, labels), None) is None:
                continue
            written.append(Written(TwoPointCondition(stimulus.name, pins, d), item,
                                   f"pins {pins[0]} and {pins[1]} ({d:g} mm apart): "))
        if "single_pins" in keys:
            single_nodes = reader.sequence(keys["single_pins"], "the single pins")
            singles = [(n, pin) for n in single_nodes
                       if (pin := reader.attempt(partial(read_pin, reader, n, grid), None))
                       is not None]
        else:
            singles = [(keys["pairs"], pin) for pin in sorted({p for pair in seen for p in pair})]
        if len({pin for _, pin in singles}) != len(singles):
            raise reader.error(keys["single_pins"], "expected each single pin once, found "
                                                    f"{[pin for _, pin in singles]}")
        trains = [stimulus]
        if "single_stimuli" in keys:
            names = reader.sequence(keys["single_stimuli"], "the single stimuli")
            trains = [train for n in names
                      if (train := reader.attempt(partial(_train, reader, n, section), None))
                      is not None]
            if len({t.name for t in trains}) != len(trains):
                raise reader.error(keys["single_stimuli"], "expected each single stimulus "
                                                           "once, found "
                                                           f"{[t.name for t in trains]}")
        for train in trains:
            for node, pin in singles:
                written.append(Written(TwoPointCondition(train.name, (pin,), 0.0), node,
                                       f"pin {pin} alone ({train.name}): "))
        return ReadDesign(tuple(written))

    @staticmethod
    def _pair(reader: Reader, node: Node, grid: Grid) -> tuple[int, ...]:
        items = reader.sequence(node, "a pair of pins", 2)
        pins = tuple(sorted(read_pin(reader, n, grid) for n in items))
        if len(pins) != 2 or pins[0] == pins[1]:
            raise reader.error(node, f"expected two different pins, found {list(pins)}")
        return pins

    @staticmethod
    def _apart(reader: Reader, node: Node, pins: tuple[int, ...], d: float, pitch_mm: float,
               labels: dict[float, tuple[float, tuple[int, ...]]]) -> float:
        """``d``, a pair's distance, checked to be one its rows can name (`LABEL_DIGITS`)
        apart from every other distance of the design (``labels``: those seen, by label)."""
        label = round(d, LABEL_DIGITS)
        if label <= 0:
            raise reader.error(node, f"expected pins at least {10 ** -LABEL_DIGITS:g} mm apart "
                                     f"(the grid's pitch_mm), found pins {pins[0]} and "
                                     f"{pins[1]} {d:g} mm apart at a pitch of {pitch_mm:g} mm")
        other_d, other = labels.setdefault(label, (d, pins))
        if other_d != d:
            raise reader.error(node, f"expected distances {10 ** -LABEL_DIGITS:g} mm apart or "
                                     f"more (the grid's pitch_mm), found pins {pins[0]} and "
                                     f"{pins[1]} {d:g} mm apart beside pins {other[0]} and "
                                     f"{other[1]} {other_d:g} mm apart")
        return d

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        match stimulus, condition:
            case TrainStimulus(train=Train() as train), TwoPointCondition(pins=pins):
                return tuple(PinDrive(pin, train, 0) for pin in pins)
        raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a "
                            f"{type(condition).__name__}")

    def warnings(self, protocol: Protocol) -> list[str]:
        conditions = [c for c in protocol.design.conditions if isinstance(c, TwoPointCondition)]
        singles = {c.stimulus for c in conditions if c.count == 1}
        pairs = {c.stimulus for c in conditions if c.count == 2}
        if not singles or singles - pairs:
            return []  # the one-pin trials play other trains than the pairs (or there are none)
        return ["two pins press with about twice the force of one: a subject may tell one from "
                "two by intensity alone; let the one-pin trials rove over trains of several "
                "strokes (single_stimuli) or use a same-force control"]

    # -- answers ---------------------------------------------------------------------------

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        return ONE, TWO

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        return (ONE, "felt one point"), (TWO, "felt two points")

    def instructions(self, design: Design) -> str:
        return ("Rest your fingertip on the pins. One pin or two press at once; say whether you "
                "felt one point or two.")

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        return {ONE: ONE, TWO: TWO, "1": ONE, "2": TWO}.get(text)

    def sheet_expected(self, design: Design, grid: Grid) -> str:
        return "one or two (or 1, 2)"

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        choices = (Choice(ONE, ("1", "o"), "one (1)"), Choice(TWO, ("2", "t"), "two (2)"))
        return AnswerPad(False, choices, "", f"one point or two? {choices_hint(choices)}")

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, TwoPointCondition)
        return TWO if condition.count == 2 else ONE

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, TwoPointCondition)
        if condition.count == 1:
            return f"pin {condition.pins[0]} alone"
        a, b = condition.pins
        return f"pins {a} and {b}, {condition.distance_mm:g} mm apart"

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, TwoPointCondition)
        return " ".join(map(str, condition.pins)), f"{condition.distance_mm:g}"

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, TwoPointCondition)
        return {"pins": list(condition.pins), "distance_mm": condition.distance_mm}
