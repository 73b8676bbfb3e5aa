"""A simulated subject for identification designs: ``--observer default`` or overrides of
`IdentificationObserverModel`'s fields.

The pattern is named right with probability ``identify_correct``; otherwise another pattern,
those sharing more pins with the one presented more likely (weight 1 + shared pins); a count
answer is right with the same probability, else one pin more or fewer. The default, 80 % of
patterns named right, is an assumption, not a measurement. Subjects differ: each draws, from
its seed, normal offsets of SD ``subject_sd`` (0: every subject the same); this paradigm's is
the first of the four the lab's paradigms draw alike (identification, two intervals, temporal
order twice), on the logit of ``identify_correct``, so that one seed is one subject in each.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from pinarray.analysis.observers import draw_offsets, parse_overrides
from pinarray.errors import PinArrayError
from pinarray.paradigms.identification.design import (
    AnswerKind,
    Identification,
    IdentificationCondition,
)
from pinarray.protocol.model import Condition, Protocol

OFFSETS = 4  # the lab's paradigms' subjects draw four, whichever paradigm they answer


@dataclass(frozen=True)
class IdentificationObserverModel:
    """A population of simulated subjects naming patterns (the module says how)."""

    identify_correct: float = 0.8
    subject_sd: float = 0.3

    def __post_init__(self) -> None:
        if not 0 <= self.identify_correct <= 1:
            raise PinArrayError(f"observer: identify_correct must be a fraction from 0 to 1, "
                                f"found {self.identify_correct}")
        if not 0 <= self.subject_sd <= 5:
            raise PinArrayError(f"observer: subject_sd must lie from 0 to 5, found "
                                f"{self.subject_sd}")

    def individual(self, rng: np.random.Generator) -> IdentificationObserverModel:
        """One subject of the population, its offsets drawn from ``rng``."""
        if self.subject_sd == 0:
            return self
        u = draw_offsets(rng, self.subject_sd, OFFSETS)
        right = self.identify_correct
        if 0 < right < 1:
            right = 1 / (1 + math.exp(-(math.log(right / (1 - right)) + u[0])))
        return replace(self, identify_correct=right, subject_sd=0.0)


class IdentificationObserver:
    """One simulated subject answering an identification design; the same ``seed``, model
    and trials give the same subject and the same answers."""

    def __init__(self, protocol: Protocol, model: IdentificationObserverModel,
                 seed: int | np.random.Generator | None = None):
        judgement = protocol.design.judgement
        assert isinstance(judgement, Identification)
        self.judgement = judgement
        self.pin_count = protocol.device.grid.pin_count
        self.patterns = {c.pattern: c.pins for c in protocol.design.conditions
                         if isinstance(c, IdentificationCondition)}
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.subject = model.individual(self.rng)

    def __call__(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``."""
        draw = self.rng.random()
        assert isinstance(condition, IdentificationCondition)
        right = draw < self.subject.identify_correct
        if self.judgement.answers is AnswerKind.COUNTS:
            if right:
                return str(condition.count)
            near = [n for n in (condition.count - 1, condition.count + 1)
                    if 1 <= n <= self.pin_count]
            return str(near[int(self.rng.integers(len(near)))])
        if right:
            return condition.pattern
        others: Sequence[str] = [p for p in self.judgement.patterns if p != condition.pattern]
        shown = set(condition.pins)
        weights = np.array([1 + len(shown & set(self.patterns[p])) for p in others], float)
        return others[int(self.rng.choice(len(others), p=weights / weights.sum()))]


def observer(protocol: Protocol, spec: str, seed: int | None) -> IdentificationObserver:
    """The simulated subject ``--observer`` names for an identification design."""
    model = parse_overrides(spec, IdentificationObserverModel(), "identification")
    return IdentificationObserver(protocol, model, seed)
