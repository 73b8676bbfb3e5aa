"""Tap counting as a protocol states it: one pin taps N times; how many taps?

    design:
      paradigm: tap_count
      stimulus: taps        # a train without frequency_hz: its duration_s is the window
      pins: [6, 11]
      taps: [2, 3, 4, 5]    # taps within the window (the train's frequency: taps / duration)

The design side of the paradigm seam (`pinarray.protocol.seam.ParadigmDesign`): which keys
it reads, its conditions and where each is written (errors point there), how a condition
plays (`drives`: pinarray checks every one against the servos and the bus at validate), and
the answers it takes. Pure Python, like every paradigm's design: `pinarray validate` loads it
and no more of the package.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import partial
from typing import ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.device import read_pin
from pinarray.protocol.model import (
    Condition,
    Design,
    PinDrive,
    Stimulus,
    TrainShape,
    TrainStimulus,
)
from pinarray.protocol.seam import DesignDefaults, DesignSection, ReadDesign, Written
from pinarray.protocol.stimuli import stimulus_named
from pinarray.units import NS_PER_S

MAX_TAPS = 9  # one answer key each, 1 to 9


# --8<-- [start:condition]
@dataclass(frozen=True)
class TapCountCondition(Condition):
    """One trial: the train ``stimulus`` on ``pin``, tapping ``taps`` times in its window."""

    paradigm: ClassVar[str] = "tap_count"
    pin: int
    taps: int

    @property
    def key(self) -> tuple[object, ...]:
        """What tells the conditions of a design apart (and orders them alike in every plan)."""
        return (self.stimulus, self.pin, self.taps)
# --8<-- [end:condition]


# --8<-- [start:design]
class TapCountDesign(DesignDefaults):
    """Tap counting as the protocol sees it (the package's `PARADIGM` adds rows and analysis)."""

    name = "tap_count"
    keys = frozenset({"stimulus", "pins", "taps"})  # beside every design's (order, blocks...)
    attributes = ("pin", "taps")  # what an order constraint may name
    plan_columns = ("pin", "taps")

    def read(self, section: DesignSection) -> ReadDesign:
        reader, keys = section.reader, section.keys
        section.needs("stimulus", "pins", "taps", paradigm=self.name)
        stimulus = stimulus_named(reader, keys["stimulus"], section.stimuli, section.declared,
                                  TrainStimulus)
        if not isinstance(stimulus.train, TrainShape):
            raise reader.error(keys["stimulus"], f"expected a train without frequency_hz (the "
                                                 f"taps set it), found {stimulus.name!r} at "
                                                 f"{float(stimulus.train.frequency_hz):g} Hz")
        pins = [pin for node in reader.sequence(keys["pins"], "the pins")
                if (pin := reader.attempt(partial(read_pin, reader, node, section.device.grid),
                                          None)) is not None]
        written = []
        for node in reader.sequence(keys["taps"], "the tap counts"):
            taps = reader.attempt(partial(reader.integer, node, "a tap count", 1, MAX_TAPS),
                                  None)
            if taps is None:
                continue
            # Each condition is written where its count is: a problem pinarray finds with it
            # (the servo cannot follow, the bus cannot carry it) is reported there.
            written += [Written(TapCountCondition(stimulus.name, pin, taps), node,
                                f"{taps} taps on pin {pin}: ") for pin in pins]
        return ReadDesign(tuple(written))

    def completes(self, section: DesignSection) -> str | None:
        """The stimulus whose frequency this design gives (its taps per second)."""
        stimulus = section.keys.get("stimulus")
        return None if stimulus is None else str(stimulus.value)

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        if (isinstance(stimulus, TrainStimulus) and isinstance(stimulus.train, TrainShape)
                and isinstance(condition, TapCountCondition)):
            shape = stimulus.train
            frequency = Fraction(condition.taps * NS_PER_S, shape.duration_ns)
            return (PinDrive(condition.pin, shape.with_frequency(frequency), 0),)
        raise PinArrayError(f"stimulus {stimulus.name!r} cannot present {condition!r}")
# --8<-- [end:design]

    # -- answers: the count, on its own digit (DesignDefaults gives the pad and the sheets) -

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        return tuple(str(t) for t in sorted({c.taps for c in design.conditions
                                             if isinstance(c, TapCountCondition)}))

    def instructions(self, design: Design) -> str:
        return "Rest your fingertip on the pins. One pin taps a few times; say how many."

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, TapCountCondition)
        return str(condition.taps)

    def cue(self, condition: Condition, design: Design) -> tuple[object, str] | None:
        return (self.correct_answer(condition, design), f"{self.describe(condition)}")

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, TapCountCondition)
        return f"{condition.taps} taps on pin {condition.pin}"

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, TapCountCondition)
        return str(condition.pin), str(condition.taps)

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, TapCountCondition)
        return {"pin": condition.pin, "taps": condition.taps}
