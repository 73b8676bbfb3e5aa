"""Psychometric functions: the probability of a correct answer at each intensity.

Two shapes, both with a guess rate ``guess`` (the floor: 0.5 in a two-alternative task, the
false-alarm rate in detection) and a lapse rate ``lapse`` (the ceiling is ``1 - lapse``)::

    weibull:   p(x) = guess + (1 - guess - lapse) * (1 - exp(-(x / threshold) ** slope))  for x > 0
               p(x) = guess                                                                for x <= 0
    logistic:  p(x) = guess + (1 - guess - lapse) / (1 + exp(-slope * (x - threshold)))

``x``, ``threshold`` are in the unit of the adapted parameter. The Weibull's ``slope`` is its
shape (no unit) and its ``threshold`` the intensity where the function has risen 1 - 1/e
(63.2 %) of the way from ``guess`` to ``1 - lapse``; the logistic's ``slope`` is per unit of
intensity and its ``threshold`` the intensity half way (50 %) from ``guess`` to ``1 - lapse``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pinarray.errors import PinArrayError

PsychometricKind = Literal["weibull", "logistic"]
KINDS: tuple[PsychometricKind, ...] = ("weibull", "logistic")


def rise(kind: PsychometricKind, intensity: ArrayLike, threshold: ArrayLike,
         slope: ArrayLike) -> NDArray[np.float64]:
    """The function's rise from 0 to 1 (without guess and lapse), broadcast over its arguments."""
    x = np.asarray(intensity, dtype=np.float64)
    t = np.asarray(threshold, dtype=np.float64)
    s = np.asarray(slope, dtype=np.float64)
    if kind == "weibull":
        positive = x > 0
        # An overflow is a power of +inf, a rise of exactly 1: nothing to warn anyone about.
        with np.errstate(over="ignore"):
            ratio = np.where(positive, x, 1.0) / t
            # -expm1(-z) keeps the small rises near x = 0 exact where 1 - exp(-z) would
            # round to 0.
            return np.where(positive, -np.expm1(-(ratio**s)), 0.0)
    if kind == "logistic":
        # 1 / (1 + exp(-u)) written through tanh: no overflow warning for large |u|.
        return 0.5 * (1.0 + np.tanh(0.5 * s * (x - t)))
    raise PinArrayError(f"a psychometric function is weibull or logistic, found {kind!r}")


def probability_correct(kind: PsychometricKind, intensity: ArrayLike, threshold: ArrayLike,
                        slope: ArrayLike, guess: ArrayLike, lapse: ArrayLike) -> NDArray[np.float64]:
    """``guess + (1 - guess - lapse) * rise``, broadcast over every argument (the module's rule)."""
    g = np.asarray(guess, dtype=np.float64)
    lam = np.asarray(lapse, dtype=np.float64)
    return g + (1.0 - g - lam) * rise(kind, intensity, threshold, slope)


@dataclass(frozen=True)
class Psychometric:
    """One psychometric function (the module docstring gives both shapes and their parameters).

    ``threshold`` is in the unit of the adapted parameter; ``guess`` and ``lapse`` are
    probabilities with ``guess + lapse < 1``.
    """

    kind: PsychometricKind
    threshold: float
    slope: float
    guess: float
    lapse: float

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise PinArrayError(f"a psychometric function is weibull or logistic, found {self.kind!r}")
        values = (self.threshold, self.slope, self.guess, self.lapse)
        if not all(np.isfinite(v) for v in values):
            raise PinArrayError(f"a psychometric function's parameters must be finite numbers, found {values}")
        if self.kind == "weibull" and self.threshold <= 0:
            raise PinArrayError(f"a Weibull threshold must be above 0, found {self.threshold}")
        if self.slope <= 0:
            raise PinArrayError(f"a psychometric slope must be above 0, found {self.slope}")
        if not (0 <= self.guess and 0 <= self.lapse and self.guess + self.lapse < 1):
            raise PinArrayError("guess and lapse rates must be 0 or more with guess + lapse below 1, "
                                f"found guess {self.guess}, lapse {self.lapse}")

    def probability(self, intensity: ArrayLike) -> NDArray[np.float64]:
        """The probability of a correct answer at each intensity (any shape, float64)."""
        return probability_correct(self.kind, intensity, self.threshold, self.slope,
                                   self.guess, self.lapse)

    def intensity_for(self, probability: float) -> float:
        """The intensity at which the probability of a correct answer is ``probability``
        (strictly between ``guess`` and ``1 - lapse``): the inverse of `probability`."""
        low, high = self.guess, 1.0 - self.lapse
        if not low < probability < high:
            raise PinArrayError(f"the function reaches only probabilities between {low} and {high} "
                                f"(exclusive), asked for {probability}")
        share = (probability - low) / (high - low)
        if self.kind == "weibull":
            return float(self.threshold * (-np.log1p(-share)) ** (1.0 / self.slope))
        return float(self.threshold + np.log(share / (1.0 - share)) / self.slope)
