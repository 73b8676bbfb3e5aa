"""Statistics with subjects as the unit: per-subject percentages and their across-subject mean.

Each subject contributes one number per measure, their own percentage, however many trials
they answered; the across-subject mean is the plain mean of those numbers. Its interval is

- a **subject bootstrap** (the default): subjects resampled with replacement ``resamples``
  times from a generator seeded with ``seed``, the percentile interval of the resampled means.
  Each resampled mean lies between the lowest and highest subject's percentage, so the
  interval never leaves 0-100 %; or
- a **t interval**, on request: mean +/- t(level, N - 1) * SD / sqrt(N), SD the sample
  standard deviation of the per-subject percentages. It is not bounded: with few subjects
  far apart it passes 0 or 100 % (two subjects at 25 and 50 % give [-121, 196] %).

Both need at least two subjects. A subject with no trial for a measure (e.g. "direction right
of those felt" for a subject who never felt motion) is left out of that measure's mean, and
the number of subjects is reported beside it. The trial-pooled proportion (every trial
weighing the same, Wilson interval) is kept beside the subject-level numbers and labelled so.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from pinarray.analysis.stats import Proportion
from pinarray.errors import PinArrayError

DEFAULT_BOOTSTRAP_SEED = 20240501
DEFAULT_BOOTSTRAP_RESAMPLES = 10_000


class IntervalMethod(StrEnum):
    """How the across-subject interval is computed."""

    T = "t"
    BOOTSTRAP = "bootstrap"


@dataclass(frozen=True)
class IntervalSettings:
    """Which across-subject interval figures show, its level, and the bootstrap's recipe.

    Parameters
    ----------
    method : IntervalMethod
        The interval drawn in figures and given in the tables and the summary: the subject
        bootstrap by default (it stays within 0-100 %); the t interval only when asked for.
    level : float
        Coverage, a fraction in (0, 1); 0.95 by default.
    bootstrap_seed : int
        Seed of the generator the bootstrap resamples subjects with; recorded in every output.
    bootstrap_resamples : int
        Number of bootstrap resamples.
    """

    method: IntervalMethod = IntervalMethod.BOOTSTRAP
    level: float = 0.95
    bootstrap_seed: int = DEFAULT_BOOTSTRAP_SEED
    bootstrap_resamples: int = DEFAULT_BOOTSTRAP_RESAMPLES

    def __post_init__(self) -> None:
        if not 0 < self.level < 1:
            raise PinArrayError(f"interval level must lie between 0 and 1, found {self.level}")
        if self.bootstrap_resamples < 100:
            raise PinArrayError("bootstrap resamples must be at least 100, found "
                                f"{self.bootstrap_resamples}")
        if self.bootstrap_seed < 0:
            raise PinArrayError(f"bootstrap seed must be >= 0, found {self.bootstrap_seed}")

    @property
    def level_pct(self) -> str:
        return f"{100 * self.level:g} %"

    def describe(self, method: IntervalMethod | None = None) -> str:
        """One phrase naming the interval, for captions and table notes."""
        match method or self.method:
            case IntervalMethod.T:
                return (f"{self.level_pct} t interval across subjects "
                        "(mean ± t(N-1) · SD/√N; not bounded: may pass 0 or 100 %)")
            case IntervalMethod.BOOTSTRAP:
                return (f"{self.level_pct} subject bootstrap (percentile; "
                        f"{self.bootstrap_resamples} resamples of subjects, "
                        f"seed {self.bootstrap_seed}; stays within 0-100 %)")
        raise AssertionError(method)


DEFAULT_SETTINGS = IntervalSettings()


def t_interval(values: Sequence[float], level: float = 0.95) -> tuple[float, float]:
    """The t interval of the mean of ``values``; (nan, nan) for fewer than two values."""
    from scipy.special import stdtrit  # the t quantile; scipy loads only when asked

    data = np.asarray(values, dtype=float)
    n = len(data)
    if n < 2:
        return math.nan, math.nan
    half = float(stdtrit(n - 1, 0.5 + level / 2)) * float(data.std(ddof=1)) / math.sqrt(n)
    mean = float(data.mean())
    return mean - half, mean + half


def bootstrap_interval(values: Sequence[float], seed: int = DEFAULT_BOOTSTRAP_SEED,
                       resamples: int = DEFAULT_BOOTSTRAP_RESAMPLES,
                       level: float = 0.95) -> tuple[float, float]:
    """Percentile interval of the mean of ``values`` resampled with replacement.

    The same values, seed and resamples always give the same interval; (nan, nan) for fewer
    than two values.
    """
    data = np.asarray(values, dtype=float)
    n = len(data)
    if n < 2:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = data[rng.integers(0, n, size=(resamples, n))].mean(axis=1)
    low, high = np.quantile(means, [0.5 - level / 2, 0.5 + level / 2])
    return float(low), float(high)


def interval_of(values: Sequence[float], settings: IntervalSettings) -> tuple[float, float]:
    """The across-subject interval of the mean of ``values`` that ``settings`` name."""
    if settings.method is IntervalMethod.T:
        return t_interval(values, settings.level)
    return bootstrap_interval(values, settings.bootstrap_seed, settings.bootstrap_resamples,
                              settings.level)


@dataclass(frozen=True)
class AcrossSubjects:
    """One measure with subjects as the unit: each subject's proportion and their mean.

    ``per_subject`` holds only subjects with at least one trial for the measure.
    Percentages are in percent; intervals are (low, high), NaN when there are fewer than
    two subjects.
    """

    per_subject: tuple[tuple[str, Proportion], ...]
    t_interval_pct: tuple[float, float]
    bootstrap_interval_pct: tuple[float, float]

    @property
    def subjects(self) -> int:
        return len(self.per_subject)

    @property
    def trials(self) -> int:
        return sum(p.trials for _, p in self.per_subject)

    @property
    def values_pct(self) -> list[float]:
        return [p.pct for _, p in self.per_subject]

    @property
    def mean_pct(self) -> float:
        return float(np.mean(self.values_pct)) if self.per_subject else math.nan

    @property
    def sd_pct(self) -> float:
        return float(np.std(self.values_pct, ddof=1)) if self.subjects > 1 else math.nan

    @property
    def pooled(self) -> Proportion:
        """The trial-pooled proportion (every trial weighing the same)."""
        return Proportion(sum(p.successes for _, p in self.per_subject), self.trials)

    def interval_pct(self, method: IntervalMethod) -> tuple[float, float]:
        match method:
            case IntervalMethod.T:
                return self.t_interval_pct
            case IntervalMethod.BOOTSTRAP:
                return self.bootstrap_interval_pct
        raise AssertionError(method)


def across_subjects(per_subject: Iterable[tuple[str, Proportion]],
                    settings: IntervalSettings = DEFAULT_SETTINGS) -> AcrossSubjects:
    """The across-subject mean and both intervals of the given per-subject proportions."""
    kept = tuple((subject, p) for subject, p in per_subject if p.trials)
    values = [p.pct for _, p in kept]
    return AcrossSubjects(
        kept, t_interval(values, settings.level),
        bootstrap_interval(values, settings.bootstrap_seed, settings.bootstrap_resamples,
                           settings.level),
    )
