"""A simulated subject for tap counting: ``--observer default`` or ``name=value`` overrides.

It counts right with probability ``correct_2`` at 2 taps, ``drop`` less for each tap more
(counting gets harder as taps come faster), else says a neighbouring count of the design's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pinarray.analysis.observers import parse_overrides
from pinarray.errors import PinArrayError
from pinarray.protocol.model import Condition, Protocol
from pinarray_tap_count.design import TapCountCondition


@dataclass(frozen=True)
class TapCountObserverModel:
    """How well a simulated subject counts (the module says how)."""

    correct_2: float = 0.95
    drop: float = 0.12

    def __post_init__(self) -> None:
        if not 0 <= self.correct_2 <= 1 or not 0 <= self.drop <= 1:
            raise PinArrayError("observer: correct_2 and drop are fractions from 0 to 1")

    def p_correct(self, taps: int) -> float:
        return max(0.0, self.correct_2 - self.drop * (taps - 2))


class TapCountObserver:
    """One simulated subject; pinarray sets ``rng`` before each trial (so the answer to a trial
    depends on the seed and the trial alone: a resumed run answers as an unbroken one)."""

    def __init__(self, model: TapCountObserverModel, answers: tuple[str, ...],
                 seed: int | None) -> None:
        self.model, self.answers = model, answers
        self.rng = np.random.default_rng(seed)

    def __call__(self, condition: Condition) -> str:
        assert isinstance(condition, TapCountCondition)
        right = str(condition.taps)
        if self.rng.random() < self.model.p_correct(condition.taps):
            return right
        at = self.answers.index(right)
        near = [self.answers[i] for i in (at - 1, at + 1) if 0 <= i < len(self.answers)]
        return near[int(self.rng.integers(len(near)))]


def observer(protocol: Protocol, spec: str, seed: int | None) -> TapCountObserver:
    """The simulated subject ``--observer`` names (pinarray finds this function by name)."""
    answers = protocol.design.answers(protocol.device.grid.pin_count)
    return TapCountObserver(parse_overrides(spec, TapCountObserverModel(), "tap_count"),
                            answers, seed)
