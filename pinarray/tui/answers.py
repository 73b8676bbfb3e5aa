"""The answers a run's paradigm offers on the pad, each with its keys and its label.

Localisation and counts are typed (digits, then Enter); the other paradigms' answers are
chosen with one key each: a wave's direction (`pinarray.tui.response_pad`), a pattern (keys 1
to 9, in the design's order, each shown as a small grid), an interval (1 or ←: first; 2 or
→: second), the pin that came first (← and → for pins on a row, ↓ and ↑ on a column, 1 and 2
otherwise). Pure: the run screen and its tests read them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

from pinarray.grid import Grid
from pinarray.protocol import Paradigm, Protocol
from pinarray.protocol.paradigms import (
    FIRST,
    SECOND,
    AnswerKind,
    Identification,
    IdentificationCondition,
    TemporalOrder,
    TwoInterval,
)
from pinarray.tui.response_pad import COUNT_ENTRY, PIN_ENTRY, Choice, motion_hint

# Keys and labels of the pin-first answers, by the pins' places
# (`pinarray.protocol.judgements.places`): short enough for two buttons in 80 columns.
PLACE_KEYS = {"left": (("l", "left"), "← left (l)"), "right": (("r", "right"), "right (r) →"),
              "lower": (("down",), "↓ lower"), "upper": (("up",), "↑ upper")}


class PadAnswers(NamedTuple):
    """What the pad takes: typed digits (``typed``, with what its hint says) or choices."""

    typed: bool
    choices: tuple[str | Choice, ...]
    entry_hint: str
    hint: str  # the run screen's prompt: which keys answer


def pad_answers(protocol: Protocol) -> PadAnswers:
    """The pad's answers for ``protocol``'s paradigm."""
    design = protocol.design
    judgement = design.judgement
    match judgement:
        case None if design.paradigm is Paradigm.LOCALISATION:
            return PadAnswers(True, (), PIN_ENTRY, "pin number + Enter, or click a pin")
        case None:
            answers = design.motion_answers
            return PadAnswers(False, tuple(answers), PIN_ENTRY, motion_hint(answers))
        case Identification(answers=AnswerKind.COUNTS):
            return PadAnswers(True, (), COUNT_ENTRY, "how many pins + Enter")
        case Identification(patterns=patterns):
            pins = {c.pattern: c.pins for c in design.conditions
                    if isinstance(c, IdentificationCondition)}
            choices = tuple(pattern_choice(protocol.device.grid, n, name, pins[name])
                            for n, name in enumerate(patterns, start=1))
        case TwoInterval(question=question):
            choices = (Choice(FIRST, ("1", "left"), "← first (1)"),
                       Choice(SECOND, ("2", "right"), "second (2) →"))
            return PadAnswers(False, choices, PIN_ENTRY, f"{question} 1 (first) / 2 (second)")
        case TemporalOrder(pins=pins, places=places):
            choices = tuple(_pin_first(pin, place, n)
                            for n, (pin, place) in enumerate(zip(pins, places, strict=True),
                                                             start=1))
            hint = " / ".join(f"{_key_name(c.keys[0])} ({place} pin {c.answer})"
                              for c, place in zip(choices, places, strict=True))
            return PadAnswers(False, choices, PIN_ENTRY, f"which came first? {hint}")
    return PadAnswers(False, choices, PIN_ENTRY, choices_hint(choices))


def _pin_first(pin: int, place: str, number: int) -> Choice:
    if place in PLACE_KEYS:
        keys, label = PLACE_KEYS[place]
        return Choice(str(pin), keys, label)
    return Choice(str(pin), (str(number),), f"pin {pin} ({number})")


def pattern_choice(grid: Grid, number: int, name: str, pins: Sequence[int]) -> Choice:
    """A pattern as a card: a small drawing of the grid (two rows of pins to a line), its key
    beside the drawing's first line and its name beside the second."""
    lines = mini_grid(grid, pins).split("\n")
    lines[0] += f" [b]{number}[/b]"
    lines[min(1, len(lines) - 1)] += f" {name}"
    return Choice(name, (str(number),), f"{number} {name}", "\n".join(lines))


def mini_grid(grid: Grid, pins: Sequence[int]) -> str:
    """The grid as the subject feels it (top row first), a raised pin a filled half block,
    two rows of pins to a line of text, on a dim ground that shows the grid's extent."""
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


def choices_hint(choices: Sequence[Choice]) -> str:
    """``1 across / 2 upright ...``: each choice's first key and its answer."""
    return " / ".join(f"{_key_name(c.keys[0])} ({c.answer})" for c in choices)


def _key_name(key: str) -> str:
    return {"left": "←", "right": "→", "up": "↑", "down": "↓"}.get(key, key)
