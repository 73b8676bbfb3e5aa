"""Can a QUEST+ grid and its prior learn anything at the design's values? Checked when the
protocol is read, so that a design no run can use is refused with its location, not at a
run's first answer.

QUEST+ (`pinarray.adaptive.questplus`) multiplies its posterior by each answer's probability;
an answer that has no chance under every threshold the prior weighs leaves nothing, and the
run stops there. So at some value both answers must have a chance (above `SMALLEST_CHANCE`)
under the thresholds the prior gives weight: the lowest of them for a correct answer (the
function rises with the value past a threshold, and fastest for the smallest slope below it),
the highest for a wrong one. The chances are computed on their logarithms, so thresholds far
from the values (``1e90``) or a prior far narrower than their spacing are judged, not turned
into infinities; the prior's weights are compared exactly, as fractions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction

from pinarray.protocol.procedures import Function, NormalPrior, QuestPlus

SMALLEST_CHANCE = 1e-12  # an answer less likely than this under every weighted triple: none
_LOG_SMALLEST = math.log(SMALLEST_CHANCE)
# Weights below exp(-700) are 0 in float64: such thresholds count for nothing in a run.
_LOG_WEIGHTLESS = 700


def weighted_thresholds(procedure: QuestPlus) -> tuple[Fraction, ...]:
    """The thresholds the prior gives a weight a float64 holds (all of them when uniform)."""
    prior = procedure.threshold_prior
    if not isinstance(prior, NormalPrior):
        return procedure.thresholds
    squares = [((t - prior.mean) / prior.sd) ** 2 for t in procedure.thresholds]
    least = min(squares)
    return tuple(t for t, z in zip(procedure.thresholds, squares, strict=True)
                 if (z - least) / 2 < _LOG_WEIGHTLESS)


def _log_rise(function: Function, x: float, t: float, s: float) -> float:
    """log of the function's rise from guess to ceiling (0 to 1) at ``x``."""
    if function is Function.WEIBULL:
        if x <= 0:
            return -math.inf
        power = s * math.log(x / t)  # log of (x/t)**s
        if power < -30:
            return power  # 1 - exp(-y) is y for so small a y
        return math.log(-math.expm1(-math.exp(min(power, 700))))
    u = s * (x - t)
    return -(max(0.0, -u) + math.log1p(math.exp(-abs(u))))


def _log_fall(function: Function, x: float, t: float, s: float) -> float:
    """log of 1 - the rise at ``x``."""
    if function is Function.WEIBULL:
        if x <= 0:
            return 0.0
        power = s * math.log(x / t)
        return -math.exp(min(power, 700))
    return _log_rise(function, -x, -t, s)  # the logistic is symmetric about its threshold


def uninformative(procedure: QuestPlus, values: Sequence[Fraction], guess: Fraction) -> str | None:
    """Why no value can tell ``procedure``'s thresholds apart, or None when one can."""
    weighted = weighted_thresholds(procedure)
    low, high = float(weighted[0]), float(weighted[-1])
    slope = float(procedure.slopes[0])
    correct = [guess > 0 or _log_rise(procedure.function, float(x), low, slope) >= _LOG_SMALLEST
               for x in values]
    wrong = [max(procedure.lapse_rates) > 0
             or _log_fall(procedure.function, float(x), high, slope) >= _LOG_SMALLEST
             for x in values]
    if any(c and w for c, w in zip(correct, wrong, strict=True)):
        return None
    answer = ("a correct" if not any(correct) else "a wrong" if not any(wrong)
              else "a correct or a wrong")
    if len(weighted) == len(procedure.thresholds):
        held = f"every threshold of its grid ({low:g} to {high:g})"
    else:
        held = (f"every threshold its prior weighs ({low:g} to {high:g}, {len(weighted)} of "
                f"{len(procedure.thresholds)})")
    return (f"procedure {procedure.name!r}: at every value ({float(values[0]):g} to "
            f"{float(values[-1]):g}) {answer} answer has less than a {SMALLEST_CHANCE:g} chance "
            f"under {held}: no answer can move it, and a run would stop at the first such "
            "answer; bring the thresholds and the prior near the values"
            + ("" if any(wrong) else ", or state a lapse rate above 0"))
