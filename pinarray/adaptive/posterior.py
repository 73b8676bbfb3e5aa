"""A subject's threshold from their answers: the Bayesian posterior over a grid of threshold x
slope x lapse, its median and 95 % credible interval, or words where the data cannot place it.

Data: at each intensity, ``n_correct`` correct answers out of ``n_trials``. The model is a
`Psychometric` of the stated kind with the guess rate stated; the threshold, the slope and the
lapse rate are unknown (the lapse rate may instead be stated, ``lapse``: then it is that rate
alone), and the posterior over them is computed on a grid, exhaustively (no optimiser:
nothing to stop short of an optimum):

- **grid**: `THRESHOLDS` thresholds evenly spaced in log intensity (a Weibull; a logistic: in
  intensity) from the tested range (the lowest to the highest intensity answered) widened by
  `REACH` tested ranges on each side (at least a factor 2 for a Weibull); `SLOPES` slopes
  evenly spaced in log from `SLOPE_RANGE`; lapse rates 0 to `MAX_LAPSE` in steps of 0.01.
  A logistic's slope is measured in units of four per tested range (a logistic of slope 3 so
  measured rises from 18 to 82 % of its way over the middle third of the range, much as a
  Weibull of shape 3 does over the middle of its own);
- **prior**, one factor per parameter: the threshold's flat (in log intensity for a Weibull)
  across the tested range and falling off beyond it as a normal of sd `TAIL_SD` tested ranges
  (at least log 2 for a Weibull), so a threshold outside the range is allowed but must be
  asked for by the data; the slope's log-normal around `SLOPE_MEDIAN` with sd `SLOPE_LOG_SD`
  of its logarithm (weakly informative: 95 % of it between 1.0 and 8.7); the lapse rate's the
  shape of a Beta(1, 10) (highest at 0, a third lower at 0.1);
- **likelihood**: binomial, ``k log p + (n - k) log(1 - p)`` summed over the intensities;
- **threshold**: the median of the threshold's marginal posterior, and its 95 % equal-tailed
  credible interval (the 2.5 % and 97.5 % points), read from the cumulative mass by linear
  interpolation within each grid cell (in log intensity for a Weibull);
- **slope**: likewise the median and 95 % credible interval of its marginal posterior (in log
  slope); the lapse rate is its marginal's median on the grid. The function drawn through the
  data stands at these medians.

Where the data cannot place the threshold, its `ThresholdStatus` says so in words instead of
a number. The likelihood of each threshold (slope and lapse rate integrated out over their
priors) tells: where it is still within `OPEN_END` of its best at the grid's lowest threshold,
the answers do not bound the threshold from below (a subject who got everything right), and
it is ``below the lowest value tested``, with ``ci_high`` its one-sided 95 % upper bound;
likewise ``above the highest value tested`` (answers at chance), ``ci_low`` its one-sided
95 % lower bound; open at both ends (too few answers), ``not estimable``. The slope gets the
same rule (`SlopeStatus`): still within `OPEN_END` of its best at the grid's steepest slope,
the answers do not bound it from above (a subject who answered every value tested as if at
a step) and ``slope_ci_low`` is its one-sided 95 % lower bound; at the shallowest, likewise
from below with ``slope_ci_high``.

Measured calibration (`make bench`, bench_thresholds): on simulated subjects running
``protocols/staircase_motion.yaml`` and ``protocols/quest_stroke.yaml`` with thresholds across
the tested range and slopes 1.5-5, the 95 % interval holds the true threshold for 92-98 % of
them (the README gives the numbers).

Cost: the grid is ``THRESHOLDS x SLOPES x 11`` cells (41 250) evaluated at each distinct
intensity; about 10-40 ms for 10-30 intensities.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from pinarray.adaptive.psychometric import KINDS, Psychometric, PsychometricKind, rise
from pinarray.errors import PinArrayError

CREDIBLE_MASS = 0.95
MAX_LAPSE = 0.1
THRESHOLDS, SLOPES = 150, 25
REACH = 1.0  # the threshold grid reaches this many tested ranges past each end
TAIL_SD = 0.5  # the threshold prior's fall-off beyond the tested range, in tested ranges
SLOPE_RANGE = (0.3, 30.0)
SLOPE_MEDIAN, SLOPE_LOG_SD = 3.0, 0.55
LAPSE_STEP = 0.01
LAPSE_BETA = 10.0  # the lapse prior's shape: (1 - lapse) ** (LAPSE_BETA - 1)
# A threshold at the grid's end whose likelihood is within this factor of the best one's is
# not ruled out by the data: the end lies inside the 95 % likelihood-ratio interval
# (exp(-3.84 / 2), 3.84 the 95 % point of chi-square with 1 degree of freedom).
OPEN_END = float(np.exp(-3.841458820694124 / 2))
_MIN_LOG_RANGE = float(np.log(2.0))  # a Weibull's tested range counts as at least a factor 2
_LOGISTIC_SLOPE_UNIT = 4.0  # a logistic slope of 1 (per range / 4) rises 24-76 % over it


class ThresholdStatus(StrEnum):
    """Whether the data place the threshold (the module docstring's rule)."""

    ESTIMATED = "estimated"
    BELOW = "below the lowest value tested"
    ABOVE = "above the highest value tested"
    NOT_ESTIMABLE = "not estimable"


class SlopeStatus(StrEnum):
    """Whether the data bound the slope (the module docstring's rule)."""

    ESTIMATED = "estimated"
    STEEPER = "steeper than the answers bound"
    SHALLOWER = "shallower than the answers bound"
    NOT_ESTIMABLE = "not estimable"


@dataclass(frozen=True)
class ThresholdPosterior:
    """A subject's threshold (intensity unit) from the grid posterior: its median and 95 %
    credible interval, the slope's likewise (the `Psychometric`'s unit), the lapse rate's
    median, the tested range, and whether the data place the threshold (``status``) and bound
    the slope (``slope_status``; where they do not, the medians are still the posterior's, and
    the words are what to report)."""

    kind: PsychometricKind
    guess: float
    threshold: float
    ci_low: float
    ci_high: float
    slope: float
    lapse: float
    lowest_tested: float
    highest_tested: float
    status: ThresholdStatus
    slope_ci_low: float
    slope_ci_high: float
    slope_status: SlopeStatus

    @property
    def function(self) -> Psychometric:
        """The function at the marginal medians: the curve drawn through the data."""
        return Psychometric(self.kind, self.threshold, self.slope, self.guess, self.lapse)

    def holds(self, threshold: float) -> bool:
        """Whether what this fit states holds ``threshold``: within the interval (estimated),
        at most ``ci_high`` (below), at least ``ci_low`` (above); not estimable states nothing,
        so nothing it states is wrong."""
        match self.status:
            case ThresholdStatus.ESTIMATED:
                return self.ci_low <= threshold <= self.ci_high
            case ThresholdStatus.BELOW:
                return threshold <= self.ci_high
            case ThresholdStatus.ABOVE:
                return threshold >= self.ci_low
        return True

    @property
    def rise_at_threshold(self) -> float:
        """How far of its way from ``guess`` to ``1 - lapse`` the function has risen at its
        threshold: 1 - 1/e (63.2 %) for a Weibull, 1/2 for a logistic."""
        return float(-np.expm1(-1.0)) if self.kind == "weibull" else 0.5

    @property
    def probability_at_threshold(self) -> float:
        """The probability of a correct answer at the threshold, at the median lapse rate."""
        return self.guess + (1.0 - self.guess - self.lapse) * self.rise_at_threshold


@dataclass(frozen=True)
class _Grid:
    """The parameter grid and the prior's logarithm, one factor per parameter: ``first`` is
    log threshold (Weibull) or threshold (logistic), evenly spaced; the slopes are evenly
    spaced in log."""

    first: NDArray[np.float64]
    slopes: NDArray[np.float64]
    lapses: NDArray[np.float64]
    log_threshold_prior: NDArray[np.float64]  # (thresholds,)
    log_slope_prior: NDArray[np.float64]  # (slopes,)
    log_lapse_prior: NDArray[np.float64]  # (lapses,)


def _grid(kind: PsychometricKind, lowest: float, highest: float, guess: float,
          lapse: float | None) -> _Grid:
    if kind == "weibull":
        low, high = float(np.log(lowest)), float(np.log(highest))
        span = max(high - low, _MIN_LOG_RANGE)
    else:
        low, high = lowest, highest
        span = high - low
    first = np.linspace(low - REACH * span, high + REACH * span, THRESHOLDS)
    outside = np.maximum(low - first, 0.0) + np.maximum(first - high, 0.0)
    threshold_prior = -0.5 * (outside / (TAIL_SD * span)) ** 2
    slopes = np.geomspace(*SLOPE_RANGE, SLOPES)
    slope_prior = -0.5 * (np.log(slopes / SLOPE_MEDIAN) / SLOPE_LOG_SD) ** 2
    if kind == "logistic":
        slopes = slopes * _LOGISTIC_SLOPE_UNIT / span
    if lapse is None:
        top = min(MAX_LAPSE, 1.0 - guess - LAPSE_STEP)
        lapses = np.arange(0.0, top + LAPSE_STEP / 2, LAPSE_STEP)
        lapse_prior = (LAPSE_BETA - 1.0) * np.log1p(-lapses)
    else:
        lapses, lapse_prior = np.array([lapse]), np.zeros(1)
    return _Grid(first, slopes, lapses, threshold_prior, slope_prior, lapse_prior)


@dataclass(frozen=True)
class _Placed:
    """One parameter's marginal posterior read on its evenly spaced axis: the median and the
    95 % interval (one-sided where one end is open), and which ends the data leave open."""

    median: float
    low: float
    high: float
    open_low: bool
    open_high: bool


def _placed(axis: NDArray[np.float64], likelihood: NDArray[np.float64],
            log_prior: NDArray[np.float64]) -> _Placed:
    """The marginal posterior ``likelihood x prior`` on ``axis`` read as the module docstring
    says: an end is open where the likelihood there is within `OPEN_END` of its best; with
    one end open, the other bound is one-sided at the credible mass."""
    tail = (1 - CREDIBLE_MASS) / 2
    median, low, high, low_bound, high_bound = _quantiles(
        axis, likelihood * np.exp(log_prior),
        [0.5, tail, 1 - tail, 1 - CREDIBLE_MASS, CREDIBLE_MASS])
    open_low, open_high = (bool(v) for v in likelihood[[0, -1]] >= OPEN_END * likelihood.max())
    if open_low and not open_high:
        high = high_bound
    if open_high and not open_low:
        low = low_bound
    return _Placed(float(median), float(low), float(high), open_low, open_high)


def _quantiles(first: NDArray[np.float64], mass: NDArray[np.float64],
               points: Sequence[float]) -> NDArray[np.float64]:
    """Where the cumulative ``mass`` (one value per grid cell, summing to 1) reaches each of
    ``points``: each cell's mass spread evenly across it, so the inverse is linear within it."""
    step = first[1] - first[0]
    edges = np.concatenate([[first[0] - step / 2], first + step / 2])
    cumulative = np.concatenate([[0.0], np.cumsum(mass)])
    cumulative /= cumulative[-1]
    return np.interp(points, cumulative, edges)


def _median_of(values: NDArray[np.float64], mass: NDArray[np.float64]) -> float:
    """The lowest grid value at which the cumulative ``mass`` reaches one half."""
    cumulative = np.cumsum(mass)
    return float(values[min(int(np.searchsorted(cumulative, 0.5 * cumulative[-1])),
                            len(values) - 1)])


def log_likelihood_grid(kind: PsychometricKind, x: NDArray[np.float64], k: NDArray[np.float64],
                        n: NDArray[np.float64], guess: float, thresholds: NDArray[np.float64],
                        slopes: NDArray[np.float64],
                        lapses: NDArray[np.float64]) -> NDArray[np.float64]:
    """The binomial log-likelihood (without the binomial coefficients) at every grid cell,
    shape (thresholds, slopes, lapses); -inf where the model calls an answer impossible."""
    from scipy.special import xlog1py, xlogy  # scipy loads only when a posterior is asked for

    risen = rise(kind, x[None, None, :], thresholds[:, None, None], slopes[None, :, None])
    span = (1.0 - guess - lapses)[None, None, :, None]
    p = guess + span * risen[:, :, None, :]
    with np.errstate(divide="ignore"):
        return np.asarray(np.sum(xlogy(k, p) + xlog1py(n - k, -p), axis=-1), dtype=np.float64)


def threshold_posterior(kind: PsychometricKind, intensities: Sequence[float],
                        n_correct: Sequence[int], n_trials: Sequence[int], *,
                        guess: float, lapse: float | None = None) -> ThresholdPosterior:
    """The threshold from the grid posterior (the module docstring's rule).

    ``intensities`` in the adapted parameter's unit (above 0 for a Weibull; any sign for a
    logistic), two distinct ones or more; ``guess`` the task's guess rate (0 to below 0.9);
    ``lapse`` a lapse rate the model takes as known (0 to below ``1 - guess``), or None to
    fit it (0 to `MAX_LAPSE`).
    """
    if kind not in KINDS:
        raise PinArrayError(f"a psychometric function is weibull or logistic, found {kind!r}")
    x = np.asarray(intensities, dtype=np.float64)
    k = np.asarray(n_correct, dtype=np.float64)
    n = np.asarray(n_trials, dtype=np.float64)
    if not (x.ndim == 1 and x.shape == k.shape == n.shape):
        raise PinArrayError("a fit needs one count of correct answers and of trials per intensity, "
                            f"found {x.size} intensities, {k.size} and {n.size} counts")
    if not np.all(np.isfinite(x)) or len(np.unique(x)) < 2:
        raise PinArrayError(f"a fit needs 2 distinct finite intensities or more, found {x.tolist()}")
    if kind == "weibull" and not np.all(x > 0):
        raise PinArrayError(f"a Weibull fit needs intensities above 0, found {x.min()}")
    if not (np.all(n >= 1) and np.all(k >= 0) and np.all(k <= n)
            and np.all(k == np.round(k)) and np.all(n == np.round(n))):
        raise PinArrayError("a fit needs whole counts with 0 <= correct <= trials and 1 trial or "
                            f"more per intensity, found correct {k.tolist()}, trials {n.tolist()}")
    if not 0 <= guess < 1 - MAX_LAPSE:
        raise PinArrayError(f"a guess rate from 0 to below {1 - MAX_LAPSE:g} is needed, found {guess}")
    if lapse is not None and not 0 <= lapse < 1 - guess:
        raise PinArrayError(f"a stated lapse rate from 0 to below 1 - guess rate ({1 - guess:g}) "
                            f"is needed, found {lapse}")

    lowest, highest = float(x.min()), float(x.max())
    grid = _grid(kind, lowest, highest, float(guess), None if lapse is None else float(lapse))
    thresholds = np.exp(grid.first) if kind == "weibull" else grid.first
    log_weights = grid.log_lapse_prior + log_likelihood_grid(
        kind, x, k, n, float(guess), thresholds, grid.slopes, grid.lapses)
    top = float(log_weights.max())
    if not np.isfinite(top):
        raise PinArrayError("these answers are impossible under every threshold, slope and lapse "
                            f"rate of the grid (guess rate {guess}): correct {k.tolist()} of "
                            f"{n.tolist()} at {x.tolist()}")
    # Every cell's weight with the lapse rate's prior in it; the threshold's and the slope's
    # priors are applied below, each left out of its own parameter's likelihood.
    weights = np.exp(log_weights - top)
    # Each parameter's likelihood, the others integrated out over their priors; times its own
    # prior, its marginal posterior.
    slope_prior = np.exp(grid.log_slope_prior)[None, :, None]
    threshold_prior = np.exp(grid.log_threshold_prior)[:, None, None]
    threshold = _placed(grid.first, (weights * slope_prior).sum(axis=(1, 2)),
                        grid.log_threshold_prior)
    slope = _placed(np.log(grid.slopes), (weights * threshold_prior).sum(axis=(0, 2)),
                    grid.log_slope_prior)
    back = np.exp if kind == "weibull" else float
    return ThresholdPosterior(
        kind, float(guess), float(back(threshold.median)), float(back(threshold.low)),
        float(back(threshold.high)), float(np.exp(slope.median)),
        _median_of(grid.lapses, (weights * slope_prior * threshold_prior).sum(axis=(0, 1))),
        lowest, highest, _THRESHOLD_WORDS[threshold.open_low, threshold.open_high],
        float(np.exp(slope.low)), float(np.exp(slope.high)),
        _SLOPE_WORDS[slope.open_low, slope.open_high])


# Which ends of an axis the data leave open -> the parameter's words.
_THRESHOLD_WORDS = {(False, False): ThresholdStatus.ESTIMATED, (True, False): ThresholdStatus.BELOW,
                    (False, True): ThresholdStatus.ABOVE, (True, True): ThresholdStatus.NOT_ESTIMABLE}
_SLOPE_WORDS = {(False, False): SlopeStatus.ESTIMATED, (True, False): SlopeStatus.SHALLOWER,
                (False, True): SlopeStatus.STEEPER, (True, True): SlopeStatus.NOT_ESTIMABLE}
