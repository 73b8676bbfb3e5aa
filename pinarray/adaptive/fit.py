"""Maximum-likelihood psychometric fits with a parametric bootstrap interval for the threshold.

Data: at each intensity, ``n_correct`` correct answers out of ``n_trials``. The model is a
`Psychometric` of the stated kind with the guess rate stated and the lapse rate stated or
fitted within 0..`MAX_FITTED_LAPSE`; its binomial log-likelihood (with the binomial
coefficients, so it is the log of the data's probability) is maximised over the threshold,
the slope and, when fitted, the lapse rate:

- first over a coarse grid (30 thresholds x 20 slopes x 5 lapses spanning the bounds' middle),
  then from the best grid point by scipy's truncated Newton (TNC) with the analytic gradient;
- bounds: a Weibull threshold within 1/100 of the lowest intensity to 100 times the highest,
  its slope (shape) 0.05 to 100; a logistic threshold within ten intensity ranges of the
  intensities, its slope 0.01 to 1000 per intensity range; the lapse rate 0 to 0.1;
- probabilities are kept within 1e-12 of 0 and 1, so an answer the model calls impossible
  costs a large finite amount rather than an infinite one.

The interval: ``resamples`` data sets are drawn from the fitted function (binomial counts at
the same intensities and trial numbers, `numpy.random.default_rng(seed)`), each is fitted
again (from the fit's parameters), and the 2.5 % and 97.5 % percentiles of their thresholds
(numpy's linear interpolation) are ``ci_low`` and ``ci_high``. The same seed gives the same
interval with the same numpy and scipy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize
from scipy.special import gammaln

from pinarray.adaptive.psychometric import KINDS, Psychometric, PsychometricKind
from pinarray.errors import PinArrayError

MAX_FITTED_LAPSE = 0.1
DEFAULT_RESAMPLES = 500
_EDGE = 1e-12
_GRID_THRESHOLDS, _GRID_SLOPES = 30, 20
_GRID_LAPSES = (0.0, 0.01, 0.03, 0.06, 0.1)
_MAX_LOG_Z = 700.0  # exp(700) is finite: the Weibull's (x/t)**s kept from overflowing


@dataclass(frozen=True)
class PsychometricFit:
    """A fitted function: threshold (intensity unit), slope, lapse rate (fitted or as stated),
    the 95 % bootstrap interval of the threshold, the maximum log-likelihood (nats) and the
    number of bootstrap resamples."""

    kind: PsychometricKind
    guess: float
    threshold: float
    slope: float
    lapse: float
    lapse_fitted: bool
    ci_low: float
    ci_high: float
    log_likelihood: float
    resamples: int

    @property
    def function(self) -> Psychometric:
        return Psychometric(self.kind, self.threshold, self.slope, self.guess, self.lapse)


@dataclass(frozen=True)
class _Model:
    """The negative log-likelihood of one data set in the optimiser's coordinates: (log
    threshold or threshold, log slope[, lapse])."""

    kind: PsychometricKind
    x: NDArray[np.float64]
    guess: float
    fixed_lapse: float | None
    bounds: tuple[tuple[float, float], ...]

    def parameters(self, theta: NDArray[np.float64]) -> tuple[float, float, float]:
        threshold = float(np.exp(theta[0])) if self.kind == "weibull" else float(theta[0])
        lapse = self.fixed_lapse if self.fixed_lapse is not None else float(theta[2])
        return threshold, float(np.exp(theta[1])), lapse

    def coordinates(self, threshold: float, slope: float, lapse: float) -> NDArray[np.float64]:
        first = np.log(threshold) if self.kind == "weibull" else threshold
        theta = [first, np.log(slope)] + ([] if self.fixed_lapse is not None else [lapse])
        return np.clip(np.asarray(theta, dtype=np.float64),
                       [b[0] for b in self.bounds], [b[1] for b in self.bounds])

    def rise_and_gradient(self, theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """F(x) and its derivatives by the first two coordinates."""
        slope = np.exp(theta[1])
        if self.kind == "weibull":
            log_z = np.minimum(slope * (np.log(self.x) - theta[0]), _MAX_LOG_Z)
            z = np.exp(log_z)
            rise = -np.expm1(-z)
            dz = np.exp(-z) * z
            return rise, -slope * dz, dz * log_z
        u = slope * (self.x - theta[0])
        rise = 0.5 * (1.0 + np.tanh(0.5 * u))
        d = rise * (1.0 - rise)
        return rise, -slope * d, d * u

    def cost(self, theta: NDArray[np.float64], k: NDArray[np.float64],
             n: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        rise, d_first, d_slope = self.rise_and_gradient(theta)
        lapse = self.fixed_lapse if self.fixed_lapse is not None else theta[2]
        span = 1.0 - self.guess - lapse
        p = np.clip(self.guess + span * rise, _EDGE, 1.0 - _EDGE)
        cost = -float(np.sum(k * np.log(p) + (n - k) * np.log1p(-p)))
        d_p = -(k / p - (n - k) / (1.0 - p))
        gradient = [np.sum(d_p * span * d_first), np.sum(d_p * span * d_slope)]
        if self.fixed_lapse is None:
            gradient.append(np.sum(d_p * -rise))
        return cost, np.asarray(gradient, dtype=np.float64)

    def grid_start(self, k: NDArray[np.float64], n: NDArray[np.float64]) -> NDArray[np.float64]:
        """The best point of the coarse grid."""
        firsts = np.linspace(*_inner(self.bounds[0]), _GRID_THRESHOLDS)
        log_slopes = np.linspace(*_inner(self.bounds[1]), _GRID_SLOPES)
        lapses = np.asarray(_GRID_LAPSES if self.fixed_lapse is None else (self.fixed_lapse,))
        f, b, lam = np.meshgrid(firsts, log_slopes, lapses, indexing="ij")
        x = self.x[:, None, None, None]
        slope = np.exp(b)[None]
        if self.kind == "weibull":
            rise = -np.expm1(-np.exp(np.minimum(slope * (np.log(x) - f[None]), _MAX_LOG_Z)))
        else:
            rise = 0.5 * (1.0 + np.tanh(0.5 * slope * (x - f[None])))
        p = np.clip(self.guess + (1.0 - self.guess - lam[None]) * rise, _EDGE, 1.0 - _EDGE)
        log_likelihood = np.tensordot(k, np.log(p), 1) + np.tensordot(n - k, np.log1p(-p), 1)
        best = np.unravel_index(int(np.argmax(log_likelihood)), log_likelihood.shape)
        theta = [firsts[best[0]], log_slopes[best[1]]]
        return np.asarray(theta + ([] if self.fixed_lapse is not None else [lapses[best[2]]]))

    def maximise(self, start: NDArray[np.float64], k: NDArray[np.float64],
                 n: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        found = minimize(self.cost, start, args=(k, n), jac=True, method="TNC",
                         bounds=self.bounds)
        return np.asarray(found.x, dtype=np.float64), float(found.fun)


def _inner(bounds: tuple[float, float]) -> tuple[float, float]:
    """The middle half of a bounded interval, where the coarse grid looks."""
    low, high = bounds
    quarter = (high - low) / 4
    return low + quarter, high - quarter


def fit_psychometric(
    kind: PsychometricKind,
    intensities: Sequence[float],
    n_correct: Sequence[int],
    n_trials: Sequence[int],
    *,
    guess: float,
    lapse: float | Literal["fit"],
    resamples: int = DEFAULT_RESAMPLES,
    seed: int = 0,
) -> PsychometricFit:
    """The maximum-likelihood fit and its bootstrap interval (the module docstring's rule).

    ``intensities`` in the adapted parameter's unit (above 0 for a Weibull); ``lapse`` a stated
    rate or ``"fit"`` (fitted within 0..0.1); ``resamples`` 100 or more.
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
    fixed_lapse = None if lapse == "fit" else float(lapse)
    highest_lapse = MAX_FITTED_LAPSE if fixed_lapse is None else fixed_lapse
    if not (0 <= guess and 0 <= highest_lapse and guess + highest_lapse < 1):
        raise PinArrayError(f"guess and lapse rates must be 0 or more with guess + lapse below 1, "
                            f"found guess {guess}, lapse {lapse}")
    if isinstance(resamples, bool) or not isinstance(resamples, int) or resamples < 100:
        raise PinArrayError(f"a bootstrap interval needs 100 resamples or more, found {resamples!r}")

    span = float(x.max() - x.min())
    if kind == "weibull":
        first = (float(np.log(x.min()) - np.log(100.0)), float(np.log(x.max()) + np.log(100.0)))
        log_slope = (float(np.log(0.05)), float(np.log(100.0)))
    else:
        first = (float(x.min() - 10 * span), float(x.max() + 10 * span))
        log_slope = (float(np.log(0.01 / span)), float(np.log(1000.0 / span)))
    bounds = (first, log_slope) + (((0.0, MAX_FITTED_LAPSE),) if fixed_lapse is None else ())
    model = _Model(kind, x, float(guess), fixed_lapse, bounds)

    theta, cost = model.maximise(model.grid_start(k, n), k, n)
    threshold, slope, fitted_lapse = model.parameters(theta)
    combinations = float(np.sum(gammaln(n + 1) - gammaln(k + 1) - gammaln(n - k + 1)))

    fitted = Psychometric(kind, threshold, slope, float(guess), fitted_lapse).probability(x)
    draws = np.random.default_rng(seed).binomial(n.astype(np.int64), fitted,
                                                 size=(resamples, len(x)))
    thresholds = np.empty(resamples)
    for r in range(resamples):
        again, _ = model.maximise(theta, draws[r].astype(np.float64), n)
        thresholds[r] = model.parameters(again)[0]
    ci_low, ci_high = np.percentile(thresholds, [2.5, 97.5])
    return PsychometricFit(kind, float(guess), threshold, slope, fitted_lapse, fixed_lapse is None,
                           float(ci_low), float(ci_high), combinations - cost, resamples)
