"""Localisation, as a protocol states it: one pin moves at one frequency; which pin was it?

The seed's first experiment (section 9.7.1)::

    design:
      paradigm: localisation
      stimulus: seed_train          # a train; without frequency_hz, the design gives it
      pins: [1, 4, 6, 7, 10, 11, 13, 16]
      frequencies_hz: [3, 5, 10]    # every pin at every frequency, one condition each

The subject names the pin that moved by its number, or says nothing was felt (``none``).
An adaptive design may adapt the frequency (its values are then the frequencies), the
signal's length or the stroke. Pure Python, read by `pinarray validate`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction
from functools import partial
from typing import TYPE_CHECKING, ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.design import MAX_TRIALS
from pinarray.protocol.device import read_pin
from pinarray.protocol.model import (
    Condition,
    Design,
    PinDrive,
    Stimulus,
    TrainShape,
    TrainStimulus,
)
from pinarray.protocol.procedures import DETECTION, Parameter, Task
from pinarray.protocol.seam import (
    AnswerPad,
    DesignDefaults,
    DesignSection,
    ReadDesign,
    Written,
)
from pinarray.protocol.stimuli import MAX_FREQUENCY_HZ, check_period, stimulus_named
from pinarray.protocol.yaml_nodes import Invalid

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pinarray.grid import Grid

# Its adaptive designs' task (`Task`): which answer counts as correct.
LOCALISATION = "localisation"  # the moved pin named


NOTHING_FELT = "none"  # the answer when no pin was felt
# What the pad's entry says it takes (digits, then Enter).
PIN_ENTRY = "type the pin number, Enter to confirm · 0 or n: nothing felt · or click a pin"


@dataclass(frozen=True)
class LocalisationCondition(Condition):
    """What one localisation trial presents: the ``stimulus``'s train on one ``pin``, at one
    frequency (``frequency_hz``, exact)."""

    paradigm: ClassVar[str] = "localisation"
    pin: int
    frequency_hz: Fraction

    @property
    def key(self) -> tuple:
        """(stimulus, pin, frequency, direction): what tells conditions of a design apart."""
        return (self.stimulus, self.pin, self.frequency_hz, None)


def _value(value: Fraction) -> str:
    return f"{float(value):g}"


class LocalisationDesign(DesignDefaults):
    """Localisation as the protocol sees it (the room adds its rows and analysis)."""

    name = "localisation"
    keys = frozenset({"stimulus", "pins", "frequencies_hz"})
    attributes = ("pin", "frequency_hz", "stimulus")
    parameters = tuple(p for p in Parameter if p is not Parameter.SOA_MS)
    tasks = (LOCALISATION, DETECTION)
    plan_columns = ("pin", "frequency_hz")
    warns_of_cut_lifts = False  # one train a trial: no later change measures its last lift

    def read(self, section: DesignSection) -> ReadDesign:
        reader, node, keys, device = section.reader, section.node, section.keys, section.device
        adapted = section.adapting if (section.adapting is not None and section.adapting.parameter
                                       is Parameter.FREQUENCY_HZ) else None
        section.needs("stimulus", "pins", *(() if adapted else ("frequencies_hz",)),
                      paradigm=self.name)
        pin_nodes = reader.sequence(keys["pins"], "the pins")
        pins = [pin for n in pin_nodes
                if (pin := reader.attempt(partial(read_pin, reader, n, device.grid), None))
                is not None]
        if len(set(pins)) != len(pins):
            raise reader.error(keys["pins"], f"expected each pin once, found {pins}")
        stimulus = stimulus_named(reader, keys["stimulus"], section.stimuli, section.declared,
                                  TrainStimulus)
        if adapted is None:
            frequency_nodes = reader.sequence(keys["frequencies_hz"], "the frequencies")
            frequencies = [(n, reader.number(n, "a frequency", "Hz", maximum=MAX_FREQUENCY_HZ))
                           for n in frequency_nodes]
        else:
            # An adaptive design's values are its frequencies: its conditions are the pins at
            # the first (every value is checked on every pin as the design's reader checks
            # an adaptive design's values).
            if adapted.values[-1] > MAX_FREQUENCY_HZ:
                raise reader.error(adapted.node, f"expected frequencies of at most "
                                                 f"{MAX_FREQUENCY_HZ} Hz, found "
                                                 f"{float(adapted.values[-1]):g}")
            frequencies = [(adapted.node, adapted.values[0])]
        if len(pin_nodes) * len(frequencies) > MAX_TRIALS:
            raise reader.error(keys.get("frequencies_hz", node),
                               f"expected at most {MAX_TRIALS:,} conditions (pins x "
                               f"frequencies), found {len(pin_nodes)} x {len(frequencies)}")
        written: list[Written] = []
        for frequency_node, frequency in frequencies:
            if isinstance(stimulus.train, TrainShape):  # a train with one was checked alone
                train = stimulus.train.with_frequency(frequency)
                try:
                    check_period(reader, frequency_node, frequency_node, train)
                except Invalid:
                    continue
            written.extend(Written(LocalisationCondition(stimulus.name, pin, frequency),
                                   frequency_node) for pin in pins)
        return ReadDesign(tuple(written))

    def completes(self, section: DesignSection) -> str | None:
        stimulus = section.keys.get("stimulus")
        return None if stimulus is None else stimulus.value

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        match stimulus, condition:
            case TrainStimulus(train=train), LocalisationCondition(pin=pin, frequency_hz=frequency):
                return (PinDrive(pin, train.with_frequency(frequency), 0),)
        raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a "
                            f"{type(condition).__name__}")

    # -- adaptive designs ------------------------------------------------------------------

    def adapt(self, condition: Condition, parameter: Parameter, value: Fraction) -> Condition:
        if isinstance(condition, LocalisationCondition) and parameter is Parameter.FREQUENCY_HZ:
            return replace(condition, frequency_hz=value)
        return condition

    def default_guess(self, task: Task, conditions: Sequence[Condition]) -> Fraction:
        if task == LOCALISATION:
            return Fraction(1, len({c.pin for c in conditions
                                    if isinstance(c, LocalisationCondition)}))
        return Fraction(0)

    def counts_as_correct(self, task: Task, condition: Condition, catch: bool,
                          response: str) -> bool:
        felt = response != NOTHING_FELT
        if catch:
            return not felt
        if task == LOCALISATION:
            return isinstance(condition, LocalisationCondition) and response == str(condition.pin)
        return felt

    def felt_answer(self, condition: Condition, design: Design, trial: int) -> str:
        assert isinstance(condition, LocalisationCondition)
        return str(condition.pin)

    def wrong_answer(self, task: Task, condition: Condition, design: Design, pin_count: int,
                     trial: int) -> str:
        assert isinstance(condition, LocalisationCondition)
        if task == DETECTION:
            return NOTHING_FELT
        pins = sorted({c.pin for c in design.conditions
                       if isinstance(c, LocalisationCondition) and c.pin != condition.pin})
        return str(pins[trial % len(pins)]) if pins else NOTHING_FELT

    # -- answers ---------------------------------------------------------------------------

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        return ()  # its manifests have never listed them: its rows read them from the plan

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        return (*map(str, range(1, pin_count + 1)), NOTHING_FELT)

    def instructions(self, design: Design) -> str:
        return ("Rest your fingertip on the pins. After each stimulus, name the pin that moved "
                "by its number (1 = bottom-left as you feel it), or say 'none' if you felt "
                "nothing.")

    def take_answer(self, response: object, design: Design, grid: Grid) -> str:
        if response is None or response == NOTHING_FELT:
            return NOTHING_FELT
        expected = f"expected a pin number from 1 to {grid.pin_count} or 'none'"
        try:
            pin = int(response)  # type: ignore[call-overload]
        except (TypeError, ValueError):
            raise PinArrayError(f"{expected}, found {response!r}") from None
        if not 1 <= pin <= grid.pin_count:
            raise PinArrayError(f"{expected}, found {pin}")
        return str(pin)

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        if text == NOTHING_FELT:
            return text
        if text.isascii() and text.isdigit() and len(text) <= 9 and 1 <= int(text) <= grid.pin_count:
            return str(int(text))
        return None

    def sheet_expected(self, design: Design, grid: Grid) -> str:
        return f"a pin number from 1 to {grid.pin_count} or 'none'"

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        return AnswerPad(True, (), PIN_ENTRY, "pin number + Enter, or click a pin", pins=True,
                         nothing=NOTHING_FELT)

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, LocalisationCondition)
        return str(condition.pin)

    def cue(self, condition: Condition, design: Design) -> tuple[object, str] | None:
        assert isinstance(condition, LocalisationCondition)
        return condition.pin, f"pin {condition.pin}"

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, LocalisationCondition)
        return f"pin {condition.pin} at {_value(condition.frequency_hz)} Hz"

    def title(self, condition: Condition) -> str:
        assert isinstance(condition, LocalisationCondition)
        return (f"{condition.stimulus} on pin {condition.pin} at "
                f"{float(condition.frequency_hz):g} Hz")

    def grouped(self, condition: Condition) -> tuple[str, int | None]:
        assert isinstance(condition, LocalisationCondition)
        return f"{condition.stimulus} at {float(condition.frequency_hz):g} Hz", condition.pin

    def screen_line(self, condition: Condition, pins: tuple[int, ...]) -> str:
        assert isinstance(condition, LocalisationCondition)
        return f"stimulus: pin {condition.pin} at {condition.frequency_hz} Hz"

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, LocalisationCondition)
        return str(condition.pin), _value(condition.frequency_hz)

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, LocalisationCondition)
        return {"pin": condition.pin, "frequency_hz": str(condition.frequency_hz)}

    def marker_fields(self, condition: Condition, stimulus: Stimulus) -> dict[str, object]:
        assert isinstance(condition, LocalisationCondition)
        return {"pin": condition.pin, "frequency_hz": _number(condition.frequency_hz)}


def _number(value: Fraction) -> int | float:
    number = float(value)
    return int(number) if number.is_integer() else number
