"""The frequency effect on correct localisation, as a mixed-effects logistic regression.

Model (a random-intercept binomial GLMM, as lme4's ``glmer(correct ~ log2(f) + (1|subject))``)::

    logit P(correct | subject i, frequency f) = b0 + b1 * (log2 f - c) + u_i,   u_i ~ N(0, s^2)

with ``c`` the mean log2 of the frequencies tested, so ``b1`` is the change in log-odds per
doubling of frequency and ``exp(b1)`` the odds ratio per doubling. "Nothing felt" counts as
not correct. Fitted by maximum likelihood: each subject's likelihood is integrated over
``u_i`` by adaptive Gauss-Hermite quadrature (`QUADRATURE_NODES` nodes around each subject's
mode, as glmer with nAGQ > 1), the sum of their logs
maximised with L-BFGS-B over ``(b0, b1, log s)``. The interval of ``b1`` is Wald's, from the
numerical Hessian; the p-value is the likelihood-ratio test against the model without
``b1`` (chi-squared, 1 df), Wald's is given too.

A random effect's variance is poorly estimated from few groups, so the fit is made only with
at least `MIN_SUBJECTS` subjects and two frequencies; otherwise the result says why not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

MIN_SUBJECTS = 6
QUADRATURE_NODES = 25
_Z_95 = 1.959963984540054
_LOG_SD_BOUNDS = (math.log(1e-4), math.log(20.0))


@dataclass(frozen=True)
class Cell:
    """One subject's counts at one frequency."""

    subject: str
    frequency_hz: float
    correct: int
    trials: int


@dataclass(frozen=True)
class FrequencyEffect:
    """The fitted model; slopes in logit units per doubling of frequency."""

    subjects: int
    trials: int
    frequencies_hz: tuple[float, ...]
    slope_per_doubling: float
    slope_se: float
    subject_sd_logit: float
    typical_subject_pct: tuple[float, ...]  # P(correct) at u = 0, per frequency, in percent
    lrt_statistic: float
    lrt_p: float
    wald_p: float
    log_likelihood: float
    converged: bool

    @property
    def odds_ratio_per_doubling(self) -> float:
        return math.exp(self.slope_per_doubling)

    @property
    def odds_ratio_interval(self) -> tuple[float, float]:
        """95 % Wald interval of the odds ratio per doubling of frequency."""
        half = _Z_95 * self.slope_se
        return math.exp(self.slope_per_doubling - half), math.exp(self.slope_per_doubling + half)

    def describe(self) -> str:
        low, high = self.odds_ratio_interval
        note = "" if self.converged else " (the optimiser did not report convergence)"
        return (f"odds of a correct answer x{self.odds_ratio_per_doubling:.2f} per doubling of "
                f"frequency, 95 % Wald interval [{low:.2f}, {high:.2f}], likelihood-ratio "
                f"p = {_p(self.lrt_p)} (Wald p = {_p(self.wald_p)}); subject SD "
                f"{self.subject_sd_logit:.2f} logit; {self.subjects} subjects, "
                f"{self.trials} trials{note}")


@dataclass(frozen=True)
class FitSkipped:
    """The model was not fitted; ``reason`` says why."""

    reason: str

    def describe(self) -> str:
        return f"not fitted: {self.reason}"


def _p(p: float) -> str:
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


class _Data:
    """Cells as arrays, with the quadrature nodes, ready for repeated likelihood calls."""

    def __init__(self, cells: Sequence[Cell], nodes: int):
        subjects = sorted({c.subject for c in cells})
        index = {s: i for i, s in enumerate(subjects)}
        self.subject = np.array([index[c.subject] for c in cells])
        self.subjects = len(subjects)
        log_f = np.log2([c.frequency_hz for c in cells])
        self.centre = float(np.mean(np.unique(log_f)))
        self.x = log_f - self.centre
        self.k = np.array([c.correct for c in cells], dtype=float)
        self.n = np.array([c.trials for c in cells], dtype=float)
        self.log_binomial = np.array([math.lgamma(n + 1) - math.lgamma(k + 1)
                                      - math.lgamma(n - k + 1) for k, n in zip(self.k, self.n,
                                                                               strict=True)])
        self.nodes, weights = np.polynomial.hermite.hermgauss(nodes)
        self.log_w = np.log(weights) + self.nodes ** 2
        # Sums each cell's terms into its subject's: a (subjects x cells) indicator.
        self.member = np.zeros((self.subjects, len(cells)))
        self.member[self.subject, np.arange(len(cells))] = 1.0

    def _log_joint(self, eta: np.ndarray, u: np.ndarray, sd: float) -> np.ndarray:
        """log p(counts of subject i | u) + log N(u; 0, sd), for ``u`` of shape (subjects, Q)."""
        cells = eta[:, None] + u[self.subject]
        log_p = (-self.k[:, None] * np.logaddexp(0, -cells)
                 - (self.n - self.k)[:, None] * np.logaddexp(0, cells)
                 + self.log_binomial[:, None])
        return (self.member @ log_p - u * u / (2 * sd * sd)
                - math.log(sd * math.sqrt(2 * math.pi)))

    def _modes(self, eta: np.ndarray, sd: float) -> tuple[np.ndarray, np.ndarray]:
        """Each subject's most likely ``u`` and the curvature scale there (Newton's method)."""
        u = np.zeros(self.subjects)
        for _ in range(100):
            p = 1 / (1 + np.exp(-(eta + u[self.subject])))
            gradient = self.member @ (self.k - self.n * p) - u / (sd * sd)
            curvature = self.member @ (self.n * p * (1 - p)) + 1 / (sd * sd)
            step = np.clip(gradient / curvature, -5, 5)
            u = u + step
            if np.abs(step).max() < 1e-10:
                break
        p = 1 / (1 + np.exp(-(eta + u[self.subject])))
        curvature = self.member @ (self.n * p * (1 - p)) + 1 / (sd * sd)
        return u, 1 / np.sqrt(curvature)

    def negative_log_likelihood(self, b0: float, b1: float, log_sd: float) -> float:
        # Adaptive quadrature: each subject's integral over u is taken on nodes centred on
        # the mode and scaled by the curvature there, so it stays exact when the integrand is
        # narrow (many trials per subject), where fixed nodes miss it.
        sd = math.exp(log_sd)
        eta = b0 + b1 * self.x
        mode, scale = self._modes(eta, sd)
        u = mode[:, None] + math.sqrt(2) * scale[:, None] * self.nodes[None, :]
        terms = self._log_joint(eta, u, sd) + self.log_w[None, :]
        top = terms.max(axis=1, keepdims=True)
        log_l = (top[:, 0] + np.log(np.exp(terms - top).sum(axis=1))
                 + np.log(math.sqrt(2) * scale))
        return -float(log_l.sum())


def _hessian(f, x: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """Central-difference Hessian of ``f`` at ``x``."""
    size = len(x)
    h = np.zeros((size, size))
    for i in range(size):
        for j in range(i, size):
            e_i, e_j = np.eye(size)[i] * step, np.eye(size)[j] * step
            h[i, j] = h[j, i] = (f(x + e_i + e_j) - f(x + e_i - e_j) - f(x - e_i + e_j)
                                 + f(x - e_i - e_j)) / (4 * step * step)
    return h


def fit_frequency_effect(cells: Sequence[Cell], nodes: int = QUADRATURE_NODES,
                         min_subjects: int = MIN_SUBJECTS) -> FrequencyEffect | FitSkipped:
    """Fit the model to per-subject, per-frequency counts (cells with no trials are ignored)."""
    from scipy.optimize import minimize  # loads only when a fit is asked for

    cells = [c for c in cells if c.trials > 0]
    subjects = {c.subject for c in cells}
    frequencies = tuple(sorted({c.frequency_hz for c in cells}))
    if len(subjects) < min_subjects:
        return FitSkipped(f"needs at least {min_subjects} subjects with localisation trials "
                          f"(a random effect's variance is poorly estimated from fewer), "
                          f"found {len(subjects)}")
    if len(frequencies) < 2:
        return FitSkipped(f"needs at least 2 frequencies, found {len(frequencies)}")
    data = _Data(cells, nodes)
    pooled = min(max(data.k.sum() / data.n.sum(), 1e-3), 1 - 1e-3)
    start = np.array([math.log(pooled / (1 - pooled)), 0.0, math.log(0.5)])
    bounds = [(None, None), (None, None), _LOG_SD_BOUNDS]

    def full(theta: np.ndarray) -> float:
        return data.negative_log_likelihood(*theta)

    def null(theta: np.ndarray) -> float:
        return data.negative_log_likelihood(theta[0], 0.0, theta[1])

    best = minimize(full, start, method="L-BFGS-B", bounds=bounds)
    base = minimize(null, start[[0, 2]], method="L-BFGS-B", bounds=[bounds[0], bounds[2]])
    b0, b1, log_sd = best.x
    at_boundary = log_sd <= _LOG_SD_BOUNDS[0] + 1e-3
    # At the boundary (no spread between subjects) the SD has no curvature to invert; the
    # slope's error then comes from the fixed effects alone.
    free = 2 if at_boundary else 3
    hessian = _hessian(lambda t: full(np.r_[t, best.x[free:]]), best.x[:free])
    try:
        covariance = np.linalg.inv(hessian)
        slope_se = math.sqrt(covariance[1, 1]) if covariance[1, 1] > 0 else math.nan
    except np.linalg.LinAlgError:
        slope_se = math.nan
    statistic = max(0.0, 2 * (base.fun - best.fun))
    frequency_x = np.log2(frequencies) - data.centre
    return FrequencyEffect(
        subjects=data.subjects, trials=int(data.n.sum()), frequencies_hz=frequencies,
        slope_per_doubling=float(b1), slope_se=slope_se, subject_sd_logit=math.exp(log_sd),
        typical_subject_pct=tuple(float(100 / (1 + math.exp(-(b0 + b1 * x))))
                                  for x in frequency_x),
        lrt_statistic=statistic, lrt_p=math.erfc(math.sqrt(statistic / 2)),
        wald_p=math.erfc(abs(b1 / slope_se) / math.sqrt(2)) if slope_se > 0 else math.nan,
        log_likelihood=-float(best.fun), converged=bool(best.success and base.success),
    )
