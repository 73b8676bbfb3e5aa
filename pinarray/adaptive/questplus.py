"""QUEST+ (Watson 2017, J. Vis. 17(3):10) for one stimulus dimension and a correct/wrong answer.

The parameter space is the grid thresholds x slopes x lapses of one `Psychometric` shape with
the guess rate fixed by the task (stated by the caller: 0.5 for a two-alternative task, the
false-alarm rate for detection). Intensities are the procedure's discrete domain.

- Prior: the product of one weight vector per parameter, each uniform unless stated
  (`normal_weights` gives a normal over the thresholds from a mean and an sd), normalised.
- Likelihood: ``p[i, k]``, the probability of a correct answer at intensity ``i`` under
  parameter triple ``k``, computed once when the procedure is prepared.
- Update: after an answer at intensity ``i`` the posterior is multiplied by ``p[i, :]``
  (correct) or ``1 - p[i, :]`` (wrong) and divided by its sum, in float64, every trial (so it
  never underflows by accumulation). A posterior whose sum is 0 (every triple the grid holds
  makes the answer impossible) is an error naming the trial.
- Next intensity: the one whose answer leaves the least expected entropy (in nats) of the
  posterior, ``E[i] = H(w) - I[i]`` with the mutual information
  ``I[i] = h(P_i) - sum_k w_k h(p[i, k])``, ``P_i = sum_k w_k p[i, k]`` and ``h`` the entropy of
  a correct/wrong answer. That is exactly the expected entropy of the updated posterior; the
  sums ``sum_k w_k h(p[i, k])`` for every intensity are one matrix-vector product with a table
  also computed once. Intensities whose expected entropies differ by no more than the
  rounding error their sums can carry are tied, and the lowest of them is chosen: the choice
  is deterministic and does not hang on the last bits of a sum (which differ between
  machines' vector units), yet a real difference, however small, is never taken for a tie.
  The bound (`rounding_bound`) is the classic one for a sum of K nonnegative products in any
  order, ``K eps`` times the sum (Higham, Accuracy and Stability of Numerical Algorithms,
  2nd ed., section 4.2; eps the float64 machine epsilon, twice the unit roundoff: a factor
  2 of margin), applied to both sums and carried through ``h`` by its slope; ``H(w)`` is the
  same for every intensity and cancels. With the issue's grid (2000 triples) it is about
  1e-12 nats, where rounding measured 1.7e-14 (issue 37: the former fixed window of 1e-9
  nats tied real differences and chose otherwise than the reference `questplus` package).
- Stop: after ``stop_after_trials`` trials, or earlier once the threshold's 95 % credible
  interval is at most ``stop_below_width`` wide (when stated). Every procedure has a trial
  limit: the interval of a discrete grid need never narrow below a stated width.
- Credible interval: from the threshold's marginal posterior, the 2.5 % point is the lowest
  grid threshold at which the cumulative mass reaches 0.025, the 97.5 % point the lowest at
  which it reaches 0.975.

Memory: two (intensities x triples) float64 tables; 50 intensities x (40 thresholds x 10
slopes x 5 lapses) = 100 000 cells each, 800 kB each, 1.6 MB together; a trial allocates a
few vectors of the grid's size (16 kB each, about 60 kB in all). Preparing peaks near 4 MB
while the logarithms are taken (tests/benchmarks/bench_adaptive.py measures both).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from pinarray.adaptive.psychometric import KINDS, PsychometricKind, probability_correct
from pinarray.errors import PinArrayError

_EPS = float(np.finfo(np.float64).eps)
CREDIBLE_MASS = 0.95
_MATCH_RELATIVE = 1e-9  # an intensity read back from disk matches a domain value this closely


def normal_weights(values: tuple[float, ...], mean: float, sd: float) -> tuple[float, ...]:
    """Prior weights proportional to a normal density with ``mean`` and ``sd`` (the values'
    unit) at each value, scaled so the largest is 1 (a prior's weights need not sum to 1).

    Each is taken relative to the value nearest the mean, ``exp(-(d**2 - d0**2) / (2 sd**2))``
    with ``d**2 - d0**2`` factored as ``(d - d0)(d + d0)``: a normal far narrower than the
    values' spacing, or far from them, gives the nearest value all the weight, never NaN."""
    if not (np.isfinite(mean) and np.isfinite(sd) and sd > 0):
        raise PinArrayError(f"a normal prior needs a finite mean and an sd above 0, found {mean}, {sd}")
    d = np.asarray(values, dtype=np.float64) - mean
    nearest = d[np.argmin(np.abs(d))]
    with np.errstate(over="ignore"):  # an overflow is an exponent of -inf: a weight of 0
        apart, beside = (d - nearest) / sd, (d + nearest) / sd
        exponent = np.where((apart == 0) | (beside == 0), 0.0, apart * beside)
    return tuple(float(w) for w in np.exp(-0.5 * exponent))


@dataclass(frozen=True, kw_only=True)
class QuestPlusRule:
    """A QUEST+ procedure (the module docstring gives the rule).

    ``intensities``: the domain, strictly ascending, in the adapted parameter's unit;
    ``thresholds`` (same unit), ``slopes`` (the shape's, see `Psychometric`), ``lapses``: the
    parameter grid, each strictly ascending; ``guess``: the task's guess rate; each
    ``*_prior``: one weight (0 or more) per grid value, None for uniform;
    ``stop_below_width``: the 95 % credible interval's width (threshold unit), None for the
    trial limit alone.
    """

    kind: PsychometricKind
    intensities: tuple[float, ...]
    thresholds: tuple[float, ...]
    slopes: tuple[float, ...]
    lapses: tuple[float, ...]
    guess: float
    stop_after_trials: int
    stop_below_width: float | None = None
    threshold_prior: tuple[float, ...] | None = None
    slope_prior: tuple[float, ...] | None = None
    lapse_prior: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise PinArrayError(f"a psychometric function is weibull or logistic, found {self.kind!r}")
        for name, values in (("intensities", self.intensities), ("thresholds", self.thresholds),
                             ("slopes", self.slopes), ("lapses", self.lapses)):
            if not values or not all(np.isfinite(v) for v in values) \
                    or any(b <= a for a, b in pairwise(values)):
                raise PinArrayError(f"QUEST+ {name} must be one finite value or more, strictly "
                                    f"ascending, found {values}")
        if self.kind == "weibull" and self.thresholds[0] <= 0:
            raise PinArrayError(f"Weibull thresholds must be above 0, found {self.thresholds[0]}")
        if self.slopes[0] <= 0:
            raise PinArrayError(f"QUEST+ slopes must be above 0, found {self.slopes[0]}")
        if not (0 <= self.guess and 0 <= self.lapses[0] and self.guess + self.lapses[-1] < 1):
            raise PinArrayError("QUEST+ guess and lapse rates must be 0 or more with guess + lapse "
                                f"below 1, found guess {self.guess}, lapses {self.lapses}")
        if self.stop_after_trials is None:
            raise PinArrayError("a QUEST+ procedure needs a trial limit (stop_after_trials), found "
                                "none: the credible interval of a grid need never narrow enough")
        if isinstance(self.stop_after_trials, bool) or not isinstance(self.stop_after_trials, int) \
                or self.stop_after_trials < 1:
            raise PinArrayError("a QUEST+ stop_after_trials must be a whole number of 1 or more, "
                                f"found {self.stop_after_trials!r}")
        if self.stop_below_width is not None and not (
                np.isfinite(self.stop_below_width) and self.stop_below_width > 0):
            raise PinArrayError(f"a QUEST+ stop_below_width must be above 0, found {self.stop_below_width}")
        for name, prior, values in (("threshold", self.threshold_prior, self.thresholds),
                                    ("slope", self.slope_prior, self.slopes),
                                    ("lapse", self.lapse_prior, self.lapses)):
            if prior is None:
                continue
            if len(prior) != len(values):
                raise PinArrayError(f"the {name} prior needs one weight per {name} ({len(values)}), "
                                    f"found {len(prior)}")
            if not all(np.isfinite(w) and w >= 0 for w in prior) or not sum(prior) > 0:
                raise PinArrayError(f"the {name} prior's weights must be 0 or more and not all 0, "
                                    f"found {prior}")


@dataclass(frozen=True, eq=False)
class QuestPlusState:
    """The posterior after ``trials`` answers: one float64 weight per parameter triple, in the
    order thresholds x slopes x lapses (lapses fastest), summing to 1; read-only."""

    trials: int
    posterior: NDArray[np.float64]


@dataclass(frozen=True)
class PosteriorSummary:
    """The marginal posterior: threshold mean, sd and 95 % credible interval (threshold unit),
    slope and lapse means."""

    threshold_mean: float
    threshold_sd: float
    threshold_ci_low: float
    threshold_ci_high: float
    slope_mean: float
    lapse_mean: float

    @property
    def threshold_ci_width(self) -> float:
        return self.threshold_ci_high - self.threshold_ci_low


def _entropy_of_answer(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """``-p log p - (1-p) log(1-p)`` in nats, 0 where p is 0 or 1."""
    q = 1.0 - p
    # Logarithms taken only where positive (no warning to silence: numpy's errstate costs as
    # much as the rest here, on every trial).
    return -(np.where(p > 0, p * _log_where_positive(p), 0.0)
             + np.where(q > 0, q * _log_where_positive(q), 0.0))


def _log_where_positive(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """``log(values)`` where they are above 0, and 0 elsewhere."""
    return np.log(values, out=np.zeros_like(values), where=values > 0)


@dataclass(frozen=True, eq=False)
class QuestPlus:
    """A prepared QUEST+ procedure: its rule and the tables computed once (`prepare`)."""

    rule: QuestPlusRule
    probability: NDArray[np.float64]  # (intensities, triples): p of a correct answer
    answer_entropy: NDArray[np.float64]  # (intensities, triples): its entropy h(p), nats
    prior: NDArray[np.float64]  # (triples,), sums to 1
    threshold_of: NDArray[np.float64]  # (triples,): each triple's threshold
    slope_of: NDArray[np.float64]
    lapse_of: NDArray[np.float64]

    @classmethod
    def prepare(cls, rule: QuestPlusRule) -> QuestPlus:
        x = np.asarray(rule.intensities, dtype=np.float64)[:, None, None, None]
        t = np.asarray(rule.thresholds, dtype=np.float64)[None, :, None, None]
        s = np.asarray(rule.slopes, dtype=np.float64)[None, None, :, None]
        lam = np.asarray(rule.lapses, dtype=np.float64)[None, None, None, :]
        probability = probability_correct(rule.kind, x, t, s, rule.guess, lam).reshape(len(x), -1)
        prior = np.ones(1)
        for weights, values in ((rule.threshold_prior, rule.thresholds),
                                (rule.slope_prior, rule.slopes), (rule.lapse_prior, rule.lapses)):
            w = np.ones(len(values)) if weights is None else np.asarray(weights, dtype=np.float64)
            prior = np.multiply.outer(prior, w / w.sum())
        prior = prior.reshape(-1)
        prior /= prior.sum()
        grid = np.meshgrid(rule.thresholds, rule.slopes, rule.lapses, indexing="ij")
        tables = [probability, _entropy_of_answer(probability), prior,
                  *(g.reshape(-1).astype(np.float64) for g in grid)]
        for table in tables:
            table.flags.writeable = False
        return cls(rule, *tables)

    def start(self) -> QuestPlusState:
        """The state before the first trial: the prior."""
        return QuestPlusState(0, self.prior)

    def index_of(self, intensity: float) -> int:
        """The domain index of ``intensity`` (matched to 1e-9 relative: values read back from disk)."""
        domain = np.asarray(self.rule.intensities)
        distance = np.abs(domain - intensity)
        i = int(np.argmin(distance))
        if not distance[i] <= _MATCH_RELATIVE * max(1.0, abs(intensity)):
            raise PinArrayError(f"QUEST+ can present only its intensities {self.rule.intensities}, "
                                f"found {intensity}")
        return i

    def update(self, state: QuestPlusState, intensity: float, correct: bool) -> QuestPlusState:
        """The state after trial ``state.trials + 1``, answered ``correct`` at ``intensity``."""
        if self.finished(state):
            raise PinArrayError(f"the QUEST+ procedure finished after {state.trials} trials: it "
                                "takes no more answers")
        row = self.probability[self.index_of(intensity)]
        posterior = state.posterior * (row if correct else 1.0 - row)
        total = posterior.sum()
        trial = state.trials + 1
        if not total > 0:
            raise PinArrayError(
                f"QUEST+ trial {trial}: a {'correct' if correct else 'wrong'} answer at {intensity} "
                "is impossible under every threshold, slope and lapse of the grid (the posterior "
                "is all 0); widen the grid or state a lapse rate above 0")
        posterior /= total
        posterior.flags.writeable = False
        return QuestPlusState(trial, posterior)

    def replay(self, outcomes: Iterable[tuple[float, bool]]) -> QuestPlusState:
        """The state after the ``(intensity, correct)`` answers, in order, from the prior."""
        state = self.start()
        for intensity, correct in outcomes:
            state = self.update(state, intensity, correct)
        return state

    def expected_entropies(self, state: QuestPlusState) -> NDArray[np.float64]:
        """The expected posterior entropy (nats) after a trial at each intensity."""
        w = state.posterior
        p_correct = np.clip(self.probability @ w, 0.0, 1.0)
        nonzero = w[w > 0]
        entropy_now = float(-(nonzero * np.log(nonzero)).sum())
        return entropy_now - (_entropy_of_answer(p_correct) - self.answer_entropy @ w)

    def rounding_bound(self, state: QuestPlusState) -> NDArray[np.float64]:
        """How far rounding can move each intensity's expected entropy (nats) relative to the
        others' (the module docstring's bound)."""
        w = state.posterior
        p_correct = np.clip(self.probability @ w, 0.0, 1.0)
        inside = np.clip(p_correct, _EPS, 1.0 - _EPS)
        slope_of_h = np.abs(np.log(inside / (1.0 - inside)))
        scale = self.answer_entropy @ w + _entropy_of_answer(p_correct) + p_correct * slope_of_h
        return (w.size + 4) * _EPS * scale

    def next_index(self, state: QuestPlusState) -> int:
        """The domain index of the next intensity: least expected entropy, ties (differences
        within rounding, `rounding_bound`) to the lowest."""
        expected = self.expected_entropies(state)
        bound = self.rounding_bound(state)
        best = int(np.argmin(expected))
        return int(np.flatnonzero(expected <= expected[best] + bound[best] + bound)[0])

    def next_intensity(self, state: QuestPlusState) -> float:
        return self.rule.intensities[self.next_index(state)]

    def summary(self, state: QuestPlusState) -> PosteriorSummary:
        w = state.posterior
        thresholds = np.asarray(self.rule.thresholds, dtype=np.float64)
        marginal = self._threshold_marginal(state)
        mean = float(marginal @ thresholds)
        sd = float(np.sqrt(max(float(marginal @ (thresholds - mean) ** 2), 0.0)))
        low, high = self._credible_interval(marginal)
        return PosteriorSummary(mean, sd, low, high,
                                float(w @ self.slope_of), float(w @ self.lapse_of))

    def _threshold_marginal(self, state: QuestPlusState) -> NDArray[np.float64]:
        return state.posterior.reshape(len(self.rule.thresholds), -1).sum(axis=1)

    def _credible_interval(self, marginal: NDArray[np.float64]) -> tuple[float, float]:
        thresholds = self.rule.thresholds
        cumulative = np.cumsum(marginal)
        tail = (1.0 - CREDIBLE_MASS) / 2
        last = len(thresholds) - 1
        low = thresholds[min(int(np.searchsorted(cumulative, tail, side="left")), last)]
        high = thresholds[min(int(np.searchsorted(cumulative, 1.0 - tail, side="left")), last)]
        return float(low), float(high)

    def finished(self, state: QuestPlusState) -> bool:
        """The trial limit is reached, or the credible interval is as narrow as asked."""
        if state.trials >= self.rule.stop_after_trials:
            return True
        width = self.rule.stop_below_width
        if width is None or state.trials == 0:
            return False
        # The interval alone, as `summary` reads it: the means are passes over the whole grid.
        low, high = self._credible_interval(self._threshold_marginal(state))
        return high - low <= width
