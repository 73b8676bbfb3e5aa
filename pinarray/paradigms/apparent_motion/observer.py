"""A simulated subject feeling waves, for piloting a protocol and testing the runner without
people.

On a wave trial the subject feels motion with probability ``motion_felt``; having felt it,
names the right direction with ``direction_given_felt``, says "unsure" with
``unsure_given_felt``, and otherwise names the wrong one. On a no-wave trial motion is felt
with ``no_wave_felt`` and the named direction is any of those the subject may name, alike.

Subjects differ. A simulated subject of the seed's experiments draws three independent offsets
from a normal distribution with standard deviation ``subject_sd_logit`` (`OFFSETS`, drawn
alike whichever of the two experiments it answers, so one seed is one subject): this one
takes the second, on the logit of ``motion_felt``, and the third, on the logit of the share
of the way from 0 to ``1 - unsure_given_felt`` of ``direction_given_felt``. The population is
calibrated so the *average subject's* rates are the model's (population means, not the rates
of a subject with offset 0). The defaults reproduce the seed's reported figures in
expectation (section 9.7.2): 77 % motion felt and 65 % of those naming the direction right.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cache

import numpy as np

from pinarray.analysis.observers import (
    centre,
    check_fraction,
    draw_offsets,
    parse_overrides,
    shifted,
)
from pinarray.errors import PinArrayError
from pinarray.paradigms.apparent_motion.design import MotionAnswer, MotionCondition, directions
from pinarray.protocol.model import Condition, Direction, Protocol

# The directions a subject may name when a protocol does not say (the seed's rows).
ROW_DIRECTIONS = (Direction.LEFT, Direction.RIGHT)
_OPPOSITE_WORD = {"left": "right", "right": "left", "up": "down", "down": "up"}
OFFSETS = 3  # a subject of the seed's experiments draws three, whichever it answers


@dataclass(frozen=True)
class MotionObserverModel:
    """A population of simulated subjects feeling waves (the module says how); probabilities
    are fractions in [0, 1], population means."""

    motion_felt: float = 0.77
    direction_given_felt: float = 0.65
    unsure_given_felt: float = 0.10
    no_wave_felt: float = 0.30
    subject_sd_logit: float = 0.5

    def __post_init__(self) -> None:
        for name in ("motion_felt", "direction_given_felt", "unsure_given_felt",
                     "no_wave_felt"):
            check_fraction(name, getattr(self, name))
        if not 0 <= self.subject_sd_logit <= 5:
            raise PinArrayError(f"observer: subject_sd_logit must lie from 0 to 5 (logit "
                                f"units), found {self.subject_sd_logit}")
        if self.direction_given_felt + self.unsure_given_felt > 1:
            raise PinArrayError(
                "observer: direction_given_felt + unsure_given_felt must be at most 1, found "
                f"{self.direction_given_felt} + {self.unsure_given_felt}")

    def individual(self, rng: np.random.Generator) -> MotionObserverModel:
        """One subject of the population, its offsets drawn from ``rng``."""
        _, felt, direction = draw_offsets(rng, self.subject_sd_logit, OFFSETS)
        if self.subject_sd_logit == 0:
            return self
        centres = _centres(self)
        top = 1 - self.unsure_given_felt
        return replace(self, subject_sd_logit=0.0,
                       motion_felt=shifted(self.motion_felt, 1.0, centres[0], felt),
                       direction_given_felt=shifted(self.direction_given_felt, top,
                                                    centres[1], direction))

    def probabilities(self, direction: Direction | str,
                      named: Sequence[Direction] = ROW_DIRECTIONS) -> dict[MotionAnswer, float]:
        """Exact answer probabilities for a wave going ``direction`` (one of ``named``, the
        ones the subject may name, or none), in the order none, ``named``, unsure.

        A felt no-wave is named any of the directions alike; a wave's direction named wrongly
        is named opposite (right for left, down-left for up-right) when that may be answered,
        else any other direction alike, else unsure. For a population these are the averages
        over subjects: felt and direction offsets are independent, so the average of their
        product is the product of the averages.
        """
        if direction != Direction.NONE and direction not in named:
            raise PinArrayError(f"observer: wave direction must be {', '.join(named)} or none, "
                                f"found {direction!r}")
        direction = Direction(direction)
        unsure = self.unsure_given_felt
        answers = dict.fromkeys(
            (MotionAnswer.NONE, *map(MotionAnswer, named), MotionAnswer.UNSURE), 0.0)
        if direction == Direction.NONE:
            felt = self.no_wave_felt
            for each in named:
                answers[MotionAnswer(each)] = felt * ((1 - unsure) / len(named))
            if not named:  # nothing to name but unsure
                answers[MotionAnswer.UNSURE] = felt * (1 - unsure)
        else:
            felt = self.motion_felt
            opposite = "-".join(_OPPOSITE_WORD.get(w, w) for w in direction.split("-"))
            others: list[str] = ([opposite] if opposite in named
                                 else [d for d in named if d != direction]
                                 or [MotionAnswer.UNSURE])
            wrong = felt * (1 - self.direction_given_felt - unsure)
            answers[MotionAnswer(direction)] = felt * self.direction_given_felt
            for other in others:
                answers[MotionAnswer(other)] += wrong / len(others)
        answers[MotionAnswer.NONE] = 1 - felt
        answers[MotionAnswer.UNSURE] += felt * unsure
        return answers


@cache
def _centres(model: MotionObserverModel) -> tuple[float, float]:
    """The logit centres of motion felt and of the direction named, over the population."""
    sd = model.subject_sd_logit
    return (centre(model.motion_felt, sd),
            centre(model.direction_given_felt / (1 - model.unsure_given_felt)
                   if model.unsure_given_felt < 1 else 0.0, sd))


class MotionObserver:
    """One simulated subject: drawn from `MotionObserverModel`'s population, answering waves.

    The same ``seed``, model and trials give the same subject and the same answers;
    ``named`` are the directions the subject may name (the design's waves').
    """

    def __init__(self, model: MotionObserverModel | None = None,
                 seed: int | np.random.Generator | None = None,
                 named: Sequence[Direction] = ROW_DIRECTIONS):
        self.model = model or MotionObserverModel()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.subject = self.model.individual(self.rng)
        self.named = tuple(named)

    def respond(self, direction: Direction | str) -> MotionAnswer:
        """What the subject says of a wave going ``direction`` or not at all (`Direction.NONE`)."""
        probabilities = self.subject.probabilities(direction, self.named)
        draw, total = self.rng.random(), 0.0
        for answer, probability in probabilities.items():
            total += probability
            if draw < total:
                return answer
        return MotionAnswer.UNSURE

    def __call__(self, condition: Condition) -> str:
        assert isinstance(condition, MotionCondition)
        return str(self.respond(condition.direction))


def parse_observer(spec: str) -> MotionObserverModel:
    """A `MotionObserverModel` from ``default`` or ``name=value,...`` overrides."""
    return parse_overrides(spec, MotionObserverModel(), "apparent_motion")


def observer(protocol: Protocol, spec: str, seed: int | None) -> MotionObserver:
    """The simulated subject ``--observer`` names for an apparent-motion design."""
    return MotionObserver(parse_observer(spec), seed, directions(protocol.design))
