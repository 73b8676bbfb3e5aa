"""Proportions of trials, the *trial-pooled* numbers: every trial weighs the same, so their
intervals (Wilson) treat trials as independent. Subject-level statistics, with subjects as the
unit, are built from per-subject proportions in `pinarray.analysis.subjects`; each paradigm's
room counts its own answers into them. Pure functions, no files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pinarray.analysis.seam import Estimate

Z_95 = 1.959963984540054  # two-sided 95 % normal quantile
POOLED = "all"  # the group of every subject's trials together


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion, as fractions; (0, 1) when ``trials == 0``.

    Chosen over the normal approximation because it stays inside [0, 1] and behaves at the
    small counts one subject gives (8 trials per frequency in the seed).
    """
    if not 0 <= successes <= trials:
        raise ValueError(f"successes must lie in 0..trials, found {successes} of {trials}")
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class Proportion:
    """``successes`` of ``trials``, with its percentage and 95 % Wilson interval in percent."""

    successes: int
    trials: int

    @property
    def pct(self) -> float:
        return 100 * self.successes / self.trials if self.trials else math.nan

    @property
    def interval_pct(self) -> tuple[float, float]:
        if not self.trials:
            return math.nan, math.nan
        low, high = wilson_interval(self.successes, self.trials)
        return 100 * low, 100 * high

    @property
    def estimate(self) -> Estimate:
        """The share of trials (0-1) as an estimate: estimated with its Wilson interval, or
        not resolved without trials."""
        if not self.trials:
            return Estimate.of(math.nan, words="no trials")
        low, high = wilson_interval(self.successes, self.trials)
        return Estimate.of(self.successes / self.trials, low, high)
