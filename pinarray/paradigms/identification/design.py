"""Identification, as a protocol states it: one pattern of pins; which was it (or how many)?

    design:
      paradigm: identification
      patterns: [row, column, L, T]   # pattern stimuli, the answers in this order
      answers: names                  # or counts: how many pins were raised

A pattern raises several pins at once, or is a sequence of patterns in time (``frames``). The
subject names the pattern (its stimulus's name, one answer key each, 1 to 9) or counts its
pins. Patterns a subject could not tell apart (playing exactly the same) are refused. Pure
Python.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import StrEnum
from functools import partial
from typing import TYPE_CHECKING, ClassVar

from pinarray.errors import PinArrayError
from pinarray.protocol.model import Condition, Design, PatternStimulus, PinDrive, Stimulus
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
from pinarray.protocol.yaml_nodes import shown

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pinarray.grid import Grid

MAX_PATTERNS = 9  # an identification design's alternatives: one key each, 1 to 9
ANSWER_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,23}")
# What the pad's entry says it takes when the subject counts (digits, then Enter).
COUNT_ENTRY = "type how many pins were raised, Enter to confirm"


class AnswerKind(StrEnum):
    """What an identification subject names: the pattern, or how many pins it raised."""

    NAMES = "names"
    COUNTS = "counts"


@dataclass(frozen=True)
class IdentificationCondition(Condition):
    """One identification trial: the pattern stimulus called ``stimulus``, raising ``pins``
    (every frame's, ascending)."""

    paradigm: ClassVar[str] = "identification"
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
class Identification:
    """An identification design: its alternatives (pattern stimuli, in the order the answer
    pad offers them) and what the subject names."""

    patterns: tuple[str, ...]
    answers: AnswerKind


def _judgement(design: Design) -> Identification:
    judgement = design.judgement
    assert isinstance(judgement, Identification)
    return judgement


class IdentificationDesign(DesignDefaults):
    """Identification as the protocol sees it (the room adds its rows and analysis)."""

    name = "identification"
    keys = frozenset({"patterns", "answers"})
    attributes = ("pattern", "count")
    plan_columns = ("pattern", "pins")

    def read(self, section: DesignSection) -> ReadDesign:
        reader, keys = section.reader, section.keys
        if "patterns" not in keys:
            raise reader.error(section.node, "expected a 'patterns' key (the pattern stimuli a "
                                             "subject tells apart) in an identification design, "
                                             "found none")
        answers = AnswerKind(reader.optional(
            keys, "answers", lambda n: reader.string(n, "the answers", tuple(AnswerKind)),
            AnswerKind.NAMES.value))
        items = reader.sequence(keys["patterns"], "the patterns", 2)
        if len(items) > MAX_PATTERNS:
            raise reader.error(keys["patterns"], f"expected at most {MAX_PATTERNS} patterns "
                                                 f"(one answer key each, 1 to 9), found "
                                                 f"{len(items)}")
        written: list[Written] = []
        seen: dict[tuple, str] = {}
        with reader.section():
            for item in items:
                stimulus = reader.attempt(partial(stimulus_named, reader, item, section.stimuli,
                                                  section.declared, PatternStimulus), None)
                if stimulus is None:
                    continue
                name = stimulus.name
                if answers is AnswerKind.NAMES and not ANSWER_NAME.fullmatch(name):
                    reader.error(item, f"expected a pattern name a subject can answer (a "
                                       f"letter, then letters, digits, _ or -, at most 24), "
                                       f"found {shown(name)}")
                    continue
                condition = IdentificationCondition(name, stimulus.pins)
                if any(w.condition == condition for w in written):
                    reader.error(item, f"expected each pattern once, found {name!r} again")
                    continue
                played = tuple(sorted(stimulus.shape.drives(), key=lambda d: (d.pin, d.delay_ns)))
                if played in seen:
                    reader.error(item, f"expected patterns a subject can tell apart, found "
                                       f"{name!r} playing exactly what {seen[played]!r} plays")
                    continue
                seen[played] = name
                written.append(Written(condition, item))
        patterns = tuple(w.condition.stimulus for w in written)
        return ReadDesign(tuple(written), Identification(patterns, answers))

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        match stimulus, condition:
            case PatternStimulus(shape=shape), IdentificationCondition():
                return shape.drives()
        raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a "
                            f"{type(condition).__name__}")

    # -- answers ---------------------------------------------------------------------------

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        judgement = _judgement(design)
        if judgement.answers is AnswerKind.NAMES:
            return judgement.patterns
        return tuple(str(n) for n in range(1, pin_count + 1))

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        judgement = _judgement(design)
        if judgement.answers is AnswerKind.NAMES:
            return tuple((name, f"named pattern {name}") for name in judgement.patterns)
        return tuple((str(n), f"counted {n} pin{'s' if n > 1 else ''} raised")
                     for n in range(1, pin_count + 1))

    def instructions(self, design: Design) -> str:
        judgement = _judgement(design)
        if judgement.answers is AnswerKind.NAMES:
            return ("Rest your fingertip on the pins. After each stimulus, name the shape the "
                    f"raised pins made: {', '.join(judgement.patterns)}.")
        return ("Rest your fingertip on the pins. After each stimulus, say how many pins were "
                "raised.")

    def take_answer(self, response: object, design: Design, grid: Grid) -> str:
        answers = design.answers(grid.pin_count)
        text = str(response).strip()
        if text not in answers:
            shown_ = (f"a count from 1 to {grid.pin_count}"
                      if _judgement(design).answers is AnswerKind.COUNTS
                      else f"one of {', '.join(answers)}")
            raise PinArrayError(f"expected {shown_}, found {response!r}")
        return text

    def sheet_expected(self, design: Design, grid: Grid) -> str:
        if _judgement(design).answers is AnswerKind.COUNTS:
            return f"a count from 1 to {grid.pin_count}"
        return f"one of {', '.join(design.answers(grid.pin_count))}"

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        judgement = _judgement(design)
        if judgement.answers is AnswerKind.COUNTS:
            return AnswerPad(True, (), COUNT_ENTRY, "how many pins + Enter")
        pins = {c.pattern: c.pins for c in design.conditions
                if isinstance(c, IdentificationCondition)}
        choices = tuple(pattern_choice(grid, n, name, pins[name])
                        for n, name in enumerate(judgement.patterns, start=1))
        return AnswerPad(False, choices, "", choices_hint(choices))

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        assert isinstance(condition, IdentificationCondition)
        if _judgement(design).answers is AnswerKind.COUNTS:
            return str(condition.count)
        return condition.pattern

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        assert isinstance(condition, IdentificationCondition)
        return f"pattern {condition.pattern} on pins {' '.join(map(str, condition.pins))}"

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        assert isinstance(condition, IdentificationCondition)
        return condition.pattern, " ".join(map(str, condition.pins))

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        assert isinstance(condition, IdentificationCondition)
        return {"pattern": condition.pattern, "pins": list(condition.pins)}


def pattern_choice(grid: Grid, number: int, name: str, pins: Sequence[int]) -> Choice:
    """A pattern as a card: a small drawing of the grid (two rows of pins to a line), its key
    beside the drawing's first line and its name beside the second."""
    lines = mini_grid(grid, pins).split("\n")
    lines[0] += f" [b]{number}[/b]"
    lines[min(1, len(lines) - 1)] += f" {name}"
    return Choice(name, (str(number),), f"{number} {name}", "\n".join(lines))


def mini_grid(grid: Grid, pins: Sequence[int]) -> str:
    """The grid as the subject feels it (top row first), a raised pin a filled half block,
    two rows of pins to a line of text, on a dim ground that shows the grid's extent (console
    markup, as the run screen draws it)."""
    raised = set(pins)
    lines = []
    for top in range(grid.rows - 1, -1, -2):
        cells = []
        for column in range(grid.columns):
            up = grid.pin_at(top, column) in raised
            down = top > 0 and grid.pin_at(top - 1, column) in raised
            cells.append("█" if up and down else "▀" if up else "▄" if down else " ")
        lines.append(f"[on $panel]{''.join(cells)}[/]")
    return "\n".join(lines)
