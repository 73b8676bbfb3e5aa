"""Psychometric fits of two-interval and temporal-order runs: Weber fractions, PSS and JND.

Both go through the fitting the adaptive designs use (`pinarray.adaptive.fit`: maximum
likelihood, then a parametric bootstrap interval of the threshold, `FIT_RESAMPLES` resamples
seeded with the analysis's bootstrap seed), over each subject's counted rows of a task (status
ok, not practice), fixed and adaptive alike:

- **two intervals**: the proportion of answers naming the interval with the higher value
  against the difference ``|comparison - standard|`` (per standard), a Weibull with guess rate
  1/2 and the lapse rate fitted (0-0.1). The difference threshold is the Weibull's (its rise
  1 - 1/e of the way, 81.6 % correct without lapses), with its bootstrap interval; the **Weber
  fraction** is that threshold over the standard (interval likewise); the difference at 75 %
  correct is given beside it.
- **temporal order**: the proportion of answers naming pin A first (the pin the protocol
  lists first) against the SOA (B's onset minus A's, ms), a logistic from 0 to 1 (guess and
  lapse rates 0: a lapse would pull both ends alike, which the fit's one-sided lapse cannot
  say). The **PSS** is its 50 % point, with the bootstrap interval; the **JND** half the
  distance between its 25 % and 75 % points, ``ln 3 / slope``.

Across subjects (subject ``all``): the mean of the subjects' values, with the interval the
analysis's settings name; a subject without a fit is left out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pinarray.adaptive.fit import PsychometricFit, fit_psychometric
from pinarray.adaptive.psychometric import PsychometricKind
from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.subjects import IntervalSettings, interval_of
from pinarray.analysis.thresholds import FIT_RESAMPLES, NotFitted, parameter_and_unit
from pinarray.errors import PinArrayError
from pinarray.journal.records import TemporalOrderRecord, TwoIntervalRecord


@dataclass(frozen=True)
class Point:
    """The answers at one value: ``hits`` of ``trials`` (two intervals: the higher interval
    named; temporal order: pin A named first)."""

    x: float
    hits: int
    trials: int

    @property
    def proportion(self) -> float:
        return self.hits / self.trials


Fit = PsychometricFit | NotFitted


@dataclass(frozen=True)
class IntervalFit:
    """One subject's two-interval discrimination of ``compared`` around ``standard``."""

    subject: str
    task: str
    compared: str
    standard: float
    points: tuple[Point, ...]  # x: the difference from the standard
    fit: Fit

    @property
    def unit(self) -> str:
        return parameter_and_unit(self.compared)[1]

    @property
    def trials(self) -> int:
        return sum(p.trials for p in self.points)

    @property
    def threshold(self) -> tuple[float, float, float]:
        """The difference threshold and its interval, in the compared unit (NaN: no fit)."""
        if isinstance(self.fit, NotFitted):
            return math.nan, math.nan, math.nan
        return self.fit.threshold, self.fit.ci_low, self.fit.ci_high

    @property
    def weber(self) -> tuple[float, float, float]:
        """The Weber fraction (threshold over the standard) and its interval."""
        scale = abs(self.standard) or math.nan
        threshold, low, high = self.threshold
        return threshold / scale, low / scale, high / scale

    @property
    def difference_75(self) -> float:
        """The difference answered right 75 % of the time."""
        if isinstance(self.fit, NotFitted):
            return math.nan
        try:
            return self.fit.function.intensity_for(0.75)
        except PinArrayError:
            return math.nan


@dataclass(frozen=True)
class OrderFit:
    """One subject's temporal-order judgements of ``pins`` (A, B)."""

    subject: str
    task: str
    pins: tuple[int, ...]
    points: tuple[Point, ...]  # x: the SOA in ms, B's onset minus A's
    fit: Fit

    @property
    def trials(self) -> int:
        return sum(p.trials for p in self.points)

    @property
    def pss(self) -> tuple[float, float, float]:
        """The point of subjective simultaneity (ms) and its interval (NaN: no fit)."""
        if isinstance(self.fit, NotFitted):
            return math.nan, math.nan, math.nan
        return self.fit.threshold, self.fit.ci_low, self.fit.ci_high

    @property
    def jnd_ms(self) -> float:
        """Half the distance between the 25 % and 75 % points, ms."""
        return math.nan if isinstance(self.fit, NotFitted) else math.log(3) / self.fit.slope


@dataclass(frozen=True)
class AcrossMeasure:
    """One measure of a task with the subject as the unit."""

    task: str
    measure: str  # weber_fraction, threshold, pss_ms, jnd_ms
    unit: str
    per_subject: tuple[tuple[str, float], ...]
    mean: float
    interval: tuple[float, float]


@dataclass(frozen=True)
class Judgements:
    """Every subject's two-interval and temporal-order fits, and their across-subject means."""

    intervals: tuple[IntervalFit, ...]
    orders: tuple[OrderFit, ...]
    across: tuple[AcrossMeasure, ...]
    resamples: int
    seed: int

    @property
    def found(self) -> bool:
        return bool(self.intervals or self.orders)


def _fit(kind: PsychometricKind, points: Sequence[Point], guess: float,
         lapse: float | Literal["fit"], seed: int, resamples: int) -> Fit:
    if len(points) < 2:
        return NotFitted(f"answers at {len(points)} value; a fit needs 2 or more")
    try:
        return fit_psychometric(kind, [p.x for p in points], [p.hits for p in points],
                                [p.trials for p in points], guess=guess, lapse=lapse,
                                resamples=resamples, seed=seed)
    except PinArrayError as problem:
        return NotFitted(str(problem))


def _points(pairs: Sequence[tuple[float, bool]]) -> tuple[Point, ...]:
    xs = sorted({x for x, _ in pairs})
    return tuple(Point(x, sum(hit for v, hit in pairs if v == x), sum(v == x for v, _ in pairs))
                 for x in xs)


def judgements(trials: Sequence[LoadedTrial], settings: IntervalSettings,
               resamples: int = FIT_RESAMPLES) -> Judgements:
    """The two-interval and temporal-order rows of ``trials`` (those that count), fitted."""
    seed = settings.bootstrap_seed
    two: dict[tuple[str, str, str, float], list[tuple[float, bool]]] = {}
    order: dict[tuple[str, str, tuple[int, ...]], list[tuple[float, bool]]] = {}
    for trial in trials:
        record = trial.record
        if not record.counts:
            continue
        match record:
            case TwoIntervalRecord(correct=bool(correct)):
                key = (record.task, trial.subject, record.compared, record.standard)
                two.setdefault(key, []).append(
                    (abs(record.comparison - record.standard), correct))
            case TemporalOrderRecord(named_a_first=bool(a_first)):
                order.setdefault((record.task, trial.subject, record.pins), []).append(
                    (record.soa_ns / 1e6, a_first))
    intervals = tuple(
        IntervalFit(subject, task, compared, standard, points,
                    _fit("weibull", points, 0.5, "fit", seed, resamples))
        for (task, subject, compared, standard), pairs in sorted(two.items())
        for points in [_points(pairs)])
    orders = tuple(
        OrderFit(subject, task, pins, points, _fit("logistic", points, 0.0, 0.0, seed,
                                                   resamples))
        for (task, subject, pins), pairs in sorted(order.items())
        for points in [_points(pairs)])
    across: list[AcrossMeasure] = []
    for task in sorted({f.task for f in intervals}):
        mine = [f for f in intervals if f.task == task]
        unit = mine[0].unit
        across += [_across(task, "weber_fraction", "", [(f.subject, f.weber[0]) for f in mine],
                           settings),
                   _across(task, "threshold", unit, [(f.subject, f.threshold[0]) for f in mine],
                           settings)]
    for task in sorted({f.task for f in orders}):
        mine_orders = [f for f in orders if f.task == task]
        across += [_across(task, "pss_ms", "ms", [(f.subject, f.pss[0]) for f in mine_orders],
                           settings),
                   _across(task, "jnd_ms", "ms", [(f.subject, f.jnd_ms) for f in mine_orders],
                           settings)]
    return Judgements(intervals, orders, tuple(across), resamples, seed)


def _across(task: str, measure: str, unit: str, values: Sequence[tuple[str, float]],
            settings: IntervalSettings) -> AcrossMeasure:
    """The mean over subjects with a value (a subject fitted in several runs counts once)."""
    by_subject: dict[str, list[float]] = {}
    for subject, value in values:
        if not math.isnan(value):
            by_subject.setdefault(subject, []).append(value)
    kept = tuple((s, float(np.mean(v))) for s, v in sorted(by_subject.items()))
    numbers = [v for _, v in kept]
    mean = float(np.mean(numbers)) if numbers else math.nan
    return AcrossMeasure(task, measure, unit, kept, mean, interval_of(numbers, settings))
