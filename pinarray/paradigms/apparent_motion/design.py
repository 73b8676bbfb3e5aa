"""Apparent motion, as a protocol states it: a wave along pins; did a dot move, and which way?

The seed's second experiment (section 9.7.2)::

    design:
      paradigm: apparent_motion
      configurations: [to_the_right, to_the_left, no_wave]   # wave stimuli

A configuration is a wave stimulus (`pinarray.protocol.model.Wave` along a row, or
`PathWave` up or down a column or along a sequence going the direction it names); the no-wave
control alternates a row's central pin with its two lateral ones. The subject says the
direction felt (one of those the design's waves go), ``none`` (no moving dot) or ``unsure``
(a moving dot, direction not named). An adaptive design may adapt the SOA, the frequency, the
signal's length or the stroke, with catch trials presenting a no-wave control. Pure Python.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.design import MAX_TRIALS
from pinarray.protocol.model import (
    DIRECTION_NAME,
    MAX_DIRECTION_CHARS,
    Condition,
    Design,
    Direction,
    PathWave,
    PinDrive,
    Stimulus,
    Wave,
    WaveKind,
    WaveStimulus,
)
from pinarray.protocol.procedures import DETECTION, Parameter, Task
from pinarray.protocol.seam import (
    AnswerPad,
    Choice,
    DesignDefaults,
    DesignSection,
    ReadDesign,
    Written,
)
from pinarray.protocol.stimuli import stimulus_named

if TYPE_CHECKING:
    from pinarray.grid import Grid


# Its adaptive designs' task (`Task`): which answer counts as correct.
DIRECTION = "direction"  # the wave's direction named


class MotionAnswer(str):
    """The subject's answer to an apparent-motion trial: a direction, none or unsure."""

    NONE: ClassVar[MotionAnswer]
    UNSURE: ClassVar[MotionAnswer]
    LEFT: ClassVar[MotionAnswer]
    RIGHT: ClassVar[MotionAnswer]

    @property
    def value(self) -> str:
        return str(self)


MotionAnswer.NONE = MotionAnswer("none")  # felt no moving dot
MotionAnswer.UNSURE = MotionAnswer("unsure")  # felt a moving dot, could not tell which way
MotionAnswer.LEFT, MotionAnswer.RIGHT = MotionAnswer("left"), MotionAnswer("right")


def is_motion_answer(text: str) -> bool:
    """Whether ``text`` can be a motion answer: none, unsure, or a direction's name."""
    return len(text) <= MAX_DIRECTION_CHARS and DIRECTION_NAME.fullmatch(text) is not None


@dataclass(frozen=True)
class MotionCondition(Condition):
    """What one apparent-motion trial presents: a wave stimulus going ``direction``.

    ``kind`` and ``row`` say how it was written: a row's wave has its row (1 = bottom); a wave
    up or down a column, or along a sequence, has ``row`` None and its ``pins`` in order.
    """

    paradigm: ClassVar[str] = "apparent_motion"
    kind: WaveKind
    direction: Direction
    row: int | None  # 1 = bottom row, as the lab counts; None: not along a row
    pins: tuple[int, ...] = ()  # in the order visited, for a wave not along a row

    @property
    def key(self) -> tuple:
        """(stimulus, pin, frequency, direction): what tells conditions of a design apart."""
        return (self.stimulus, None, None, self.direction)


def wave_condition(stimulus: WaveStimulus) -> MotionCondition:
    """What a trial presenting the wave ``stimulus`` is."""
    wave = stimulus.wave
    match wave:
        case Wave():
            return MotionCondition(stimulus.name, wave.kind, wave.direction, wave.row)
        case PathWave():
            return MotionCondition(stimulus.name, wave.kind, wave.direction, None, wave.pins)
    raise AssertionError(wave)


def answered_directions(presented: Iterable[Direction]) -> tuple[Direction, ...]:
    """The directions a subject may name, of the waves ``presented`` (the no-wave control's
    none left out): left, right, up and down first in that order, then the directions
    sequences name, in the order first met."""
    named = list(presented)
    usual = (Direction.LEFT, Direction.RIGHT, Direction.UP, Direction.DOWN)
    return tuple(dict.fromkeys([*(d for d in usual if d in named),
                                *(d for d in named if d != Direction.NONE)]))


def directions(design: Design) -> tuple[Direction, ...]:
    """The wave directions the design's trials present: see `answered_directions`."""
    return answered_directions(c.direction for c in design.conditions
                               if isinstance(c, MotionCondition))


def motion_answers(design: Design) -> tuple[MotionAnswer, ...]:
    """Every answer an apparent-motion trial of ``design`` takes."""
    return (*map(MotionAnswer, directions(design)), MotionAnswer.NONE, MotionAnswer.UNSURE)


# The usual answers' keys (arrows too, since the subject says "left" or "up") and buttons. u
# is unsure and d the run screen's redo, so up and down have their arrows only.
USUAL_ANSWERS = {"left": (("l", "left"), "← left (l)"), "right": (("r", "right"), "right (r) →"),
                 "up": (("up",), "↑ up"), "down": (("down",), "↓ down"),
                 "none": (("n",), "no motion (n)"), "unsure": (("u",), "unsure (u)")}
SEQUENCE_KEYS = "123456789"  # the directions sequence waves name, in the order first listed


def answer_keys(answers: Sequence[str]) -> tuple[Choice, ...]:
    """Each motion answer the design offers with its keys and its button's label."""
    named = iter(SEQUENCE_KEYS)
    out = []
    for answer in answers:
        if answer in USUAL_ANSWERS:
            keys, label = USUAL_ANSWERS[answer]
        else:
            key = next(named, None)  # a design names at most 9 of its own (ten would be keyless)
            keys, label = ((key,), f"{answer} ({key})") if key else ((), answer)
        out.append(Choice(answer, keys, label))
    return tuple(out)


def answer_hint(choices: Sequence[Choice]) -> str:
    """The keys that answer, as the run screen's prompt says them: ``l / r / n (no motion)...``."""
    names = {"left": "l", "right": "r", "up": "↑", "down": "↓"}
    return " / ".join(
        "n (no motion)" if c.answer == "none" else "u (unsure)" if c.answer == "unsure"
        else names.get(c.answer, f"{c.keys[0] if c.keys else '?'} ({c.answer})")
        for c in choices)


class ApparentMotionDesign(DesignDefaults):
    """Apparent motion as the protocol sees it (the room adds its rows and analysis)."""

    name = "apparent_motion"
    keys = frozenset({"configurations"})
    attributes = ("direction", "stimulus")
    parameters = tuple(Parameter)
    tasks = (DIRECTION, DETECTION)
    plan_columns = ("row", "direction")
    warns_of_cut_lifts = False  # a wave's pins each play once: no later change measures them

    def read(self, section: DesignSection) -> ReadDesign:
        reader, keys = section.reader, section.keys
        if "configurations" not in keys:
            raise reader.error(section.node, "expected a 'configurations' key (wave stimuli) "
                                             "in an apparent_motion design, found none")
        items = reader.sequence(keys["configurations"], "the configurations")
        if len(items) > MAX_TRIALS:
            raise reader.error(keys["configurations"], f"expected at most {MAX_TRIALS:,} "
                                                       f"configurations, found {len(items):,}")
        written = []
        for item in items:
            stimulus = stimulus_named(reader, item, section.stimuli, section.declared,
                                      WaveStimulus)
            written.append(Written(wave_condition(stimulus), item))
        return ReadDesign(tuple(written))

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        match stimulus, condition:
            case WaveStimulus(wave=wave), MotionCondition():
                return wave.drives()
        raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a "
                            f"{type(condition).__name__}")

    # -- adaptive designs ------------------------------------------------------------------

    def default_guess(self, task: Task, conditions: Sequence[Condition]) -> Fraction:
        if task == DIRECTION:
            named = answered_directions(c.direction for c in conditions
                                        if isinstance(c, MotionCondition))
            return Fraction(1, max(len(named), 1))
        return Fraction(0)

    def catch_condition(self, stimulus: Stimulus) -> Condition:
        if not isinstance(stimulus, WaveStimulus):
            raise PinArrayError(f"expected a wave stimulus of an apparent_motion design for "
                                f"catch trials, found {stimulus.name!r}")
        if stimulus.wave.direction != Direction.NONE:
            # A catch trial's right answer is that nothing moved: a moving wave has a direction.
            raise PinArrayError(f"expected a no-wave control (wave: none) for catch trials, "
                                f"whose right answer is no motion; found {stimulus.name!r}, a "
                                f"wave going {stimulus.wave.direction}")
        return wave_condition(stimulus)

    def counts_as_correct(self, task: Task, condition: Condition, catch: bool,
                          response: str) -> bool:
        felt = response != MotionAnswer.NONE
        if catch:
            return not felt
        if task == DIRECTION:
            return isinstance(condition, MotionCondition) and response == condition.direction
        return felt

    def felt_answer(self, condition: Condition, design: Design, trial: int) -> str:
        assert isinstance(condition, MotionCondition)
        named = directions(design)
        if condition.direction in named or not named:
            return condition.direction if named else "unsure"
        return named[trial % len(named)]  # a no-wave control, felt as moving

    def wrong_answer(self, task: Task, condition: Condition, design: Design, pin_count: int,
                     trial: int) -> str:
        assert isinstance(condition, MotionCondition)
        if task == DETECTION:
            return MotionAnswer.NONE
        others = [d for d in directions(design) if d != condition.direction]
        return others[trial % len(others)] if others else MotionAnswer.NONE

    # -- answers ---------------------------------------------------------------------------

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        return ()  # its manifests have never listed them: its rows read them from the plan

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        return tuple(motion_answers(design))

    def instructions(self, design: Design) -> str:
        return ("Rest your fingertip on the pins. After each stimulus, say whether you felt a "
                "dot moving and, if so, which way it went (left, right, up, down: the "
                "directions the experimenter named), or unsure; say 'none' if you felt no "
                "movement.")

    def take_answer(self, response: object, design: Design, grid: Grid) -> str:
        offered = ("none", *directions(design), "unsure")
        if response not in offered:
            raise PinArrayError(f"expected one of {', '.join(offered)}, found {response!r}")
        return str(response)

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        return text if text in ("none", *directions(design), "unsure") else None

    def sheet_expected(self, design: Design, grid: Grid) -> str:
        return f"one of {', '.join(('none', *directions(design), 'unsure'))}"

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        choices = answer_keys(motion_answers(design))
        return AnswerPad(False, choices, "", answer_hint(choices))

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, MotionCondition)
        return condition.direction

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, MotionCondition)
        where = (f"row {condition.row}" if condition.row is not None
                 else "pins " + " ".join(map(str, condition.pins)))
        return f"{condition.direction.value} wave on {where}"

    def screen_line(self, condition: Condition, pins: tuple[int, ...]) -> str:
        assert isinstance(condition, MotionCondition)
        shown = " ".join(map(str, pins))
        if condition.direction == Direction.NONE:
            return f"stimulus: no wave (centre alternates with sides) on pins {shown}"
        if condition.kind is WaveKind.SEQUENCE:
            return f"stimulus: wave going {condition.direction} on pins {shown}"
        return f"stimulus: {condition.kind} wave on pins {shown}"

    def grouped(self, condition: Condition) -> tuple[str, int | None]:
        assert isinstance(condition, MotionCondition)
        return f"{condition.stimulus} going {condition.direction}", None

    def title(self, condition: Condition) -> str:
        assert isinstance(condition, MotionCondition)
        return f"{condition.stimulus} ({condition.direction})"

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, MotionCondition)
        return ("-" if condition.row is None else str(condition.row),
                condition.direction.value)

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, MotionCondition)
        # "direction" holds the wave's kind (rightwards...), as it always has; a wave not
        # along a row adds its pins and the direction a subject names.
        return {"direction": condition.kind.value, "row": condition.row} | (
            {} if condition.row is not None else {"pins": list(condition.pins),
                                                  "towards": condition.direction.value})

    def marker_fields(self, condition: Condition, stimulus: Stimulus) -> dict[str, object]:
        assert isinstance(condition, MotionCondition) and isinstance(stimulus, WaveStimulus)
        frequency = float(stimulus.wave.train.frequency_hz)
        return {"row": condition.row, "direction": condition.direction.value,
                "frequency_hz": int(frequency) if frequency.is_integer() else frequency}
