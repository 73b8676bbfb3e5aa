"""A simulated subject for the lab's paradigms: identification, two intervals, temporal order.

``--observer default`` (or ``name=value`` overrides of `LabObserverModel`'s fields):

- **identification**: the pattern is named right with probability ``identify_correct``;
  otherwise another pattern, those sharing more pins with the one presented more likely
  (weight 1 + shared pins); a count answer is right with the same probability, else one pin
  more or fewer.
- **two intervals**: the interval with the higher value is named with a Weibull probability of
  the difference ``|comparison - standard|`` (guess rate 1/2): threshold ``weber`` x the
  standard, shape ``slope``, lapse rate ``lapse``; otherwise the other interval.
- **temporal order**: pin A (the first the protocol lists) is named first with probability
  ``lapse / 2 + (1 - lapse) / (1 + exp(-(soa - pss_ms) / s))``, ``s = jnd_ms / ln 3`` (so
  that half the distance between the 25 % and 75 % points is ``jnd_ms``).

The defaults are assumptions, not measurements: 80 % of patterns named right, a Weber
fraction of 0.2 (vibrotactile frequency discrimination near 10 Hz is usually reported at
0.2-0.3), a PSS of 0 ms and a JND of 40 ms. Subjects differ: each draws, from its seed, normal
offsets of SD ``subject_sd``: on the logit of ``identify_correct``, on the log of ``weber``
and of ``jnd_ms``, and on the PSS in units of the JND (0: every subject the same).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from pinarray.analysis.observer import observer_number
from pinarray.errors import PinArrayError
from pinarray.protocol import Condition, Protocol
from pinarray.protocol.paradigms import (
    FIRST,
    SECOND,
    AnswerKind,
    Identification,
    IdentificationCondition,
    Judgement,
    TemporalOrderCondition,
    TwoIntervalCondition,
)


@dataclass(frozen=True)
class LabObserverModel:
    """A population of simulated subjects for the lab's paradigms (the module says how each
    answers); probabilities are fractions, ``pss_ms`` and ``jnd_ms`` milliseconds."""

    identify_correct: float = 0.8
    weber: float = 0.2
    slope: float = 3.0
    pss_ms: float = 0.0
    jnd_ms: float = 40.0
    lapse: float = 0.02
    subject_sd: float = 0.3

    def __post_init__(self) -> None:
        for name in ("identify_correct", "lapse"):
            value = getattr(self, name)
            if not 0 <= value <= 1:
                raise PinArrayError(f"observer: {name} must be a fraction from 0 to 1, found "
                                    f"{value}")
        for name in ("weber", "slope", "jnd_ms"):
            if not getattr(self, name) > 0:
                raise PinArrayError(f"observer: {name} must be above 0, found "
                                    f"{getattr(self, name)}")
        if not 0 <= self.subject_sd <= 5:
            raise PinArrayError(f"observer: subject_sd must lie from 0 to 5, found "
                                f"{self.subject_sd}")
        if self.lapse >= 0.5:
            raise PinArrayError(f"observer: lapse must be below 0.5 (the guess rate of two "
                                f"intervals), found {self.lapse}")

    def individual(self, rng: np.random.Generator) -> LabObserverModel:
        """One subject of the population, its offsets drawn from ``rng``."""
        if self.subject_sd == 0:
            return self
        u = [float(x) for x in rng.normal(0.0, self.subject_sd, 4)]
        right = self.identify_correct
        if 0 < right < 1:
            right = 1 / (1 + math.exp(-(math.log(right / (1 - right)) + u[0])))
        jnd = self.jnd_ms * math.exp(u[2])
        return replace(self, identify_correct=right, weber=self.weber * math.exp(u[1]),
                       jnd_ms=jnd, pss_ms=self.pss_ms + u[3] * jnd, subject_sd=0.0)

    def p_interval_right(self, standard: float, comparison: float) -> float:
        """The probability of naming the interval with the higher value."""
        difference = abs(comparison - standard)
        threshold = self.weber * abs(standard) if standard else self.weber
        rise = -math.expm1(-((difference / threshold) ** self.slope))
        return 0.5 + (0.5 - self.lapse) * rise

    def p_a_first(self, soa_ms: float) -> float:
        """The probability of naming pin A first when B starts ``soa_ms`` after A."""
        scale = self.jnd_ms / math.log(3)
        x = max(-700.0, min(700.0, (soa_ms - self.pss_ms) / scale))
        return self.lapse / 2 + (1 - self.lapse) / (1 + math.exp(-x))


def parse_lab_observer(spec: str) -> LabObserverModel:
    """A `LabObserverModel` from ``default`` or ``name=value,...`` overrides of its fields."""
    model = LabObserverModel()
    if spec.strip() in ("", "default"):
        return model
    names = {f.name for f in fields(LabObserverModel)}
    changes: dict[str, float] = {}
    for item in spec.split(","):
        name, _, text = (part.strip() for part in item.partition("="))
        if name not in names:
            raise PinArrayError(f"observer: unknown parameter {name!r} for this paradigm; "
                                f"expected one of {', '.join(sorted(names))}")
        changes[name] = observer_number(item, text)
    return replace(model, **changes)


class LabObserver:
    """One simulated subject answering a fixed design of the lab's paradigms.

    The same ``seed``, model and trials give the same subject and the same answers.
    """

    def __init__(self, protocol: Protocol, model: LabObserverModel,
                 seed: int | np.random.Generator | None = None):
        judgement = protocol.design.judgement
        if judgement is None:
            raise PinArrayError(f"{protocol.source}: this observer answers identification, "
                                "two-interval and temporal-order designs")
        self.judgement: Judgement = judgement
        self.pin_count = protocol.device.grid.pin_count
        self.patterns = {c.pattern: c.pins for c in protocol.design.conditions
                         if isinstance(c, IdentificationCondition)}
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.subject = model.individual(self.rng)

    def respond(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``."""
        subject, draw = self.subject, self.rng.random()
        match condition:
            case IdentificationCondition():
                return self._identify(condition, draw < subject.identify_correct)
            case TwoIntervalCondition():
                right = condition.correct_answer
                p = subject.p_interval_right(float(condition.standard),
                                             float(condition.comparison))
                return right if draw < p else (SECOND if right == FIRST else FIRST)
            case TemporalOrderCondition(pins=(a, b)):
                return str(a) if draw < subject.p_a_first(float(condition.soa_ms)) else str(b)
        raise PinArrayError(f"this observer answers the lab's paradigms, not a "
                            f"{type(condition).__name__}")

    def _identify(self, condition: IdentificationCondition, right: bool) -> str:
        judgement = self.judgement
        assert isinstance(judgement, Identification)
        if judgement.answers is AnswerKind.COUNTS:
            if right:
                return str(condition.count)
            near = [n for n in (condition.count - 1, condition.count + 1)
                    if 1 <= n <= self.pin_count]
            return str(near[int(self.rng.integers(len(near)))])
        if right:
            return condition.pattern
        others: Sequence[str] = [p for p in judgement.patterns if p != condition.pattern]
        shown = set(condition.pins)
        weights = np.array([1 + len(shown & set(self.patterns[p])) for p in others], float)
        return others[int(self.rng.choice(len(others), p=weights / weights.sum()))]
