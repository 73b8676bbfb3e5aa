"""Chance levels: what a subject guessing at random would score, stated with its definition.

Localisation: a subject who names one of the ``answer_pins`` uniformly at random on every
trial. Correct by chance is then 1 / K for K nameable pins (1/16 when any pin of the 4x4 grid
may be named); the chance of each error class A-D is the share of nameable pins in that class,
averaged over the stimulated pins (pins stimulated equally often). "Nothing felt" has no
chance level: it is not a guess.

Motion: a subject who names left or right at random is right half the time, so the chance
level of "direction right, of those felt" is 50 %. Whether motion was felt is a yes/no
detection with no chance level; its baseline is the no-wave control (motion felt when no wave
ran), drawn beside it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from pinarray.analysis.stats import ERROR_CLASSES
from pinarray.grid import DEFAULT_GRID, Grid

DIRECTION_CHANCE = 0.5


@dataclass(frozen=True)
class LocalisationChance:
    """Chance levels of the localisation answer categories, as fractions."""

    answer_pins: tuple[int, ...]
    stimulated_pins: tuple[int, ...]
    fractions: Mapping[str, float]  # "correct", "A".."D"

    @property
    def correct(self) -> float:
        return self.fractions["correct"]

    def definition(self) -> str:
        k = len(self.answer_pins)
        return (f"chance = a subject naming any of {k} pins at random "
                f"(correct 1/{k} = {100 * self.correct:.2f} %)")


def localisation_chance(stimulated_pins: Iterable[int], answer_pins: Iterable[int] | None = None,
                        grid: Grid = DEFAULT_GRID) -> LocalisationChance:
    """Chance levels for the given stimulated pins when any of ``answer_pins`` may be named.

    ``answer_pins`` defaults to every pin of ``grid``.
    """
    stimulated = tuple(sorted({grid.check_pin(p) for p in stimulated_pins}))
    answers = tuple(sorted({grid.check_pin(p) for p in (answer_pins or grid.pins)}))
    fractions = dict.fromkeys(("correct", *ERROR_CLASSES), 0.0)
    for s in stimulated:
        for r in answers:
            fractions[grid.classify(s, r).value] += 1 / (len(answers) * len(stimulated))
    return LocalisationChance(answers, stimulated, fractions)
