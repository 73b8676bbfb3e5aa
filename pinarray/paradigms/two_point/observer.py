"""A simulated subject for two-point designs: ``--observer default`` or overrides of
`TwoPointObserverModel`'s fields.

Two pins ``d`` mm apart are felt as two with probability

    false_alarm + (1 - false_alarm - lapse) * (1 - (1 - intensity_cue) * exp(-(d / threshold_mm) ** slope))

and one pin with probability ``false_alarm`` (said two of one pin). ``intensity_cue`` is the
share of two-pin trials answered "two" from the doubled force alone, whatever the distance
(0: this subject judges space only; REFERENCE.md, two-point discrimination). The defaults, a
threshold of 3 mm (fingertips are classically reported at 2-4 mm), a false-alarm rate of 5 %
and no intensity cue, are assumptions. Subjects differ: each draws, from its seed, the four
normal offsets of SD ``subject_sd`` every paradigm's subject draws alike; this paradigm's are
the first, on the log of ``threshold_mm``, and the second, on the logit of ``false_alarm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pinarray.analysis.observers import draw_offsets, parse_overrides
from pinarray.errors import PinArrayError
from pinarray.paradigms.two_point.design import ONE, TWO, TwoPointCondition
from pinarray.protocol.model import Condition, Protocol

OFFSETS = 4  # every paradigm's subjects draw four, whichever paradigm they answer
MAX_POWER_LOG = 700.0  # exp(700) is finite; exp(-exp(700)) is 0 in any float


@dataclass(frozen=True)
class TwoPointObserverModel:
    """A population of simulated subjects telling one point from two (the module says how)."""

    threshold_mm: float = 3.0
    slope: float = 3.0
    false_alarm: float = 0.05
    lapse: float = 0.02
    intensity_cue: float = 0.0
    subject_sd: float = 0.3

    def __post_init__(self) -> None:
        for name in ("threshold_mm", "slope"):
            if not getattr(self, name) > 0:
                raise PinArrayError(f"observer: {name} must be above 0, found "
                                    f"{getattr(self, name)}")
        for name in ("false_alarm", "intensity_cue"):
            if not 0 <= getattr(self, name) <= 1:
                raise PinArrayError(f"observer: {name} must be a fraction from 0 to 1, found "
                                    f"{getattr(self, name)}")
        if not 0 <= self.lapse < 1 - self.false_alarm:
            raise PinArrayError(f"observer: lapse must be a fraction from 0 to below 1 - "
                                f"false_alarm, found {self.lapse}")
        if not 0 <= self.subject_sd <= 5:
            raise PinArrayError(f"observer: subject_sd must lie from 0 to 5, found "
                                f"{self.subject_sd}")

    def individual(self, rng: np.random.Generator) -> TwoPointObserverModel:
        """One subject of the population, its offsets drawn from ``rng``."""
        if self.subject_sd == 0:
            return self
        u = draw_offsets(rng, self.subject_sd, OFFSETS)
        false_alarm = self.false_alarm
        if 0 < false_alarm < 1:
            logit = math.log(false_alarm / (1 - false_alarm)) + u[1]
            false_alarm = min(1 / (1 + math.exp(-logit)), (1 - self.lapse) * 0.99)
        return replace(self, threshold_mm=self.threshold_mm * math.exp(u[0]),
                       false_alarm=false_alarm, subject_sd=0.0)

    def p_two(self, distance_mm: float) -> float:
        """The probability of saying two when pins ``distance_mm`` apart press (0: one pin)."""
        if distance_mm <= 0:
            return self.false_alarm
        # (d / threshold) ** slope in the log domain: a steep slope or a far threshold would
        # overflow the power itself, where the probability is only ever 0 or 1.
        power_log = self.slope * (math.log(distance_mm) - math.log(self.threshold_mm))
        unfelt = (1 - self.intensity_cue) * (
            0.0 if power_log > MAX_POWER_LOG else math.exp(-math.exp(power_log)))
        return self.false_alarm + (1 - self.false_alarm - self.lapse) * (1 - unfelt)


class TwoPointObserver:
    """One simulated subject answering a two-point design; the same ``seed``, model and
    trials give the same subject and the same answers."""

    def __init__(self, model: TwoPointObserverModel,
                 seed: int | np.random.Generator | None = None):
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.subject = model.individual(self.rng)

    def __call__(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``."""
        assert isinstance(condition, TwoPointCondition)
        distance = condition.distance_mm if condition.count == 2 else 0.0
        return TWO if self.rng.random() < self.subject.p_two(distance) else ONE


def observer(protocol: Protocol, spec: str, seed: int | None) -> TwoPointObserver:
    """The simulated subject ``--observer`` names for a two-point design."""
    return TwoPointObserver(parse_overrides(spec, TwoPointObserverModel(), "two_point"), seed)
