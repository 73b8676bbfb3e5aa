"""A simulated subject for temporal-order designs: ``--observer default`` or overrides of
`TemporalOrderObserverModel`'s fields.

Pin A (the first the protocol lists) is named first with probability
``lapse / 2 + (1 - lapse) / (1 + exp(-(soa - pss_ms) / s))``, ``s = jnd_ms / ln 3`` (so that
half the distance between the 25 % and 75 % points is ``jnd_ms``). The defaults, a PSS of 0 ms
and a JND of 40 ms, are assumptions. Subjects differ: each draws, from its seed, the four
normal offsets of SD ``subject_sd`` the lab's paradigms draw alike; this paradigm's are the
third, on the log of ``jnd_ms``, and the fourth, on the PSS in units of the JND.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pinarray.analysis.observers import draw_offsets, parse_overrides
from pinarray.errors import PinArrayError
from pinarray.paradigms.temporal_order.design import TemporalOrderCondition
from pinarray.protocol.model import Condition, Protocol

OFFSETS = 4  # the lab's paradigms' subjects draw four, whichever paradigm they answer


@dataclass(frozen=True)
class TemporalOrderObserverModel:
    """A population of simulated subjects judging temporal order (the module says how)."""

    pss_ms: float = 0.0
    jnd_ms: float = 40.0
    lapse: float = 0.02
    subject_sd: float = 0.3

    def __post_init__(self) -> None:
        if not 0 <= self.lapse <= 1:
            raise PinArrayError(f"observer: lapse must be a fraction from 0 to 1, found "
                                f"{self.lapse}")
        if not self.jnd_ms > 0:
            raise PinArrayError(f"observer: jnd_ms must be above 0, found {self.jnd_ms}")
        if not math.isfinite(self.pss_ms):
            raise PinArrayError(f"observer: pss_ms must be a number of ms, found {self.pss_ms}")
        if not 0 <= self.subject_sd <= 5:
            raise PinArrayError(f"observer: subject_sd must lie from 0 to 5, found "
                                f"{self.subject_sd}")

    def individual(self, rng: np.random.Generator) -> TemporalOrderObserverModel:
        """One subject of the population, its offsets drawn from ``rng``."""
        if self.subject_sd == 0:
            return self
        u = draw_offsets(rng, self.subject_sd, OFFSETS)
        jnd = self.jnd_ms * math.exp(u[2])
        return replace(self, jnd_ms=jnd, pss_ms=self.pss_ms + u[3] * jnd, subject_sd=0.0)

    def p_a_first(self, soa_ms: float) -> float:
        """The probability of naming pin A first when B starts ``soa_ms`` after A."""
        scale = self.jnd_ms / math.log(3)
        x = max(-700.0, min(700.0, (soa_ms - self.pss_ms) / scale))
        return self.lapse / 2 + (1 - self.lapse) / (1 + math.exp(-x))


class TemporalOrderObserver:
    """One simulated subject answering a temporal-order design; the same ``seed``, model and
    trials give the same subject and the same answers."""

    def __init__(self, model: TemporalOrderObserverModel,
                 seed: int | np.random.Generator | None = None):
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.subject = model.individual(self.rng)

    def __call__(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``."""
        draw = self.rng.random()
        assert isinstance(condition, TemporalOrderCondition)
        a, b = condition.pins
        return str(a) if draw < self.subject.p_a_first(float(condition.soa_ms)) else str(b)


def observer(protocol: Protocol, spec: str, seed: int | None) -> TemporalOrderObserver:
    """The simulated subject ``--observer`` names for a temporal-order design."""
    return TemporalOrderObserver(
        parse_overrides(spec, TemporalOrderObserverModel(), "temporal_order"), seed)
