"""A simulated subject for two-interval designs: ``--observer default`` or overrides of
`TwoIntervalObserverModel`'s fields.

The interval with the higher value is named with a Weibull probability of the difference
``|comparison - standard|`` (guess rate 1/2): threshold ``weber`` x the standard, shape
``slope``, lapse rate ``lapse``; otherwise the other interval. ``weber`` is the Weibull's
threshold over the standard: the difference answered right 1/2 + (1/2 - ``lapse``)(1 - 1/e)
of the time, 81.6 % at a lapse rate of 0 (80.3 % at the default 0.02). Reports of a Weber
fraction at 75 % correct (the usual point) correspond to ``weber`` x (ln 2)^(1/``slope``) at a
lapse rate of 0: 0.885 x ``weber`` at the default slope 3, so the default ``weber`` of 0.2 (an
assumption) is a 75 % Weber fraction of 0.177, and the 0.2-0.3 usually reported near 10 Hz
for vibrotactile frequency discrimination are ``weber`` 0.23-0.34. Subjects differ:
each draws, from its seed, the four normal offsets of SD ``subject_sd`` the lab's paradigms
draw alike; this paradigm's is the second, on the log of ``weber``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pinarray.analysis.observers import draw_offsets, parse_overrides
from pinarray.errors import PinArrayError
from pinarray.paradigms.two_interval.design import FIRST, SECOND, TwoIntervalCondition
from pinarray.protocol.model import Condition, Protocol

OFFSETS = 4  # the lab's paradigms' subjects draw four, whichever paradigm they answer


@dataclass(frozen=True)
class TwoIntervalObserverModel:
    """A population of simulated subjects comparing two intervals (the module says how)."""

    weber: float = 0.2
    slope: float = 3.0
    lapse: float = 0.02
    subject_sd: float = 0.3

    def __post_init__(self) -> None:
        if not 0 <= self.lapse < 0.5:
            raise PinArrayError(f"observer: lapse must be a fraction from 0 to below 0.5 (the "
                                f"guess rate of two intervals), found {self.lapse}")
        for name in ("weber", "slope"):
            if not getattr(self, name) > 0:
                raise PinArrayError(f"observer: {name} must be above 0, found "
                                    f"{getattr(self, name)}")
        if not 0 <= self.subject_sd <= 5:
            raise PinArrayError(f"observer: subject_sd must lie from 0 to 5, found "
                                f"{self.subject_sd}")

    def individual(self, rng: np.random.Generator) -> TwoIntervalObserverModel:
        """One subject of the population, its offsets drawn from ``rng``."""
        if self.subject_sd == 0:
            return self
        u = draw_offsets(rng, self.subject_sd, OFFSETS)
        return replace(self, weber=self.weber * math.exp(u[1]), subject_sd=0.0)

    def p_right(self, standard: float, comparison: float) -> float:
        """The probability of naming the interval with the higher value."""
        difference = abs(comparison - standard)
        threshold = self.weber * abs(standard) if standard else self.weber
        rise = -math.expm1(-((difference / threshold) ** self.slope))
        return 0.5 + (0.5 - self.lapse) * rise


class TwoIntervalObserver:
    """One simulated subject answering a two-interval design; the same ``seed``, model and
    trials give the same subject and the same answers."""

    def __init__(self, model: TwoIntervalObserverModel,
                 seed: int | np.random.Generator | None = None):
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.subject = model.individual(self.rng)

    def __call__(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``."""
        draw = self.rng.random()
        assert isinstance(condition, TwoIntervalCondition)
        right = condition.correct_answer
        p = self.subject.p_right(float(condition.standard), float(condition.comparison))
        return right if draw < p else (SECOND if right == FIRST else FIRST)


def observer(protocol: Protocol, spec: str, seed: int | None) -> TwoIntervalObserver:
    """The simulated subject ``--observer`` names for a two-interval design."""
    return TwoIntervalObserver(parse_overrides(spec, TwoIntervalObserverModel(), "two_interval"),
                               seed)
