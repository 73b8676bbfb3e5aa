"""Adaptive procedures: the cost of QUEST+'s next-trial decision on the issue's grid (50
intensities x 40 thresholds x 10 slopes x 5 lapse rates) beside a naive pure-Python loop
computing the same expected entropies, the memory its tables take, a staircase's step, and a
subject's threshold from the grid posterior (its coverage: bench_thresholds).

Target (issue 26): an update and the choice of the next intensity in milliseconds, so that
the decision never delays a trial.
"""

import math
import statistics

import numpy as np

from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.posterior import threshold_posterior
from pinarray.adaptive.psychometric import Psychometric
from pinarray.adaptive.questplus import QuestPlus, QuestPlusRule
from pinarray.adaptive.staircase import StaircaseRule, StepSizes, advance, replay
from tests.benchmarks._timing import (
    SPREAD_HEADER,
    interleaved_seconds,
    peak_bytes,
    ratio,
    spread,
)

RULE = QuestPlusRule(
    kind="weibull",
    intensities=tuple(float(v) for v in np.geomspace(0.5, 40.0, 50)),  # stroke, mm
    thresholds=tuple(float(v) for v in np.geomspace(0.4, 50.0, 40)),
    slopes=tuple(float(v) for v in np.linspace(1.0, 5.5, 10)),
    lapses=(0.0, 0.01, 0.02, 0.04, 0.06),
    guess=0.5,
    stop_after_trials=1000,
)
SUBJECT = Psychometric("weibull", threshold=6.0, slope=3.0, guess=0.5, lapse=0.02)


def naive_trial(probability: list[list[float]], posterior: list[float], intensity_index: int,
                correct: bool) -> tuple[list[float], int]:
    """The update and the next intensity as first written: loops over every intensity, answer
    and parameter triple, each posterior's entropy computed from scratch."""
    row = probability[intensity_index]
    updated = [w * (p if correct else 1.0 - p) for w, p in zip(posterior, row, strict=True)]
    total = sum(updated)
    updated = [w / total for w in updated]
    best, best_index = math.inf, 0
    for i, p_row in enumerate(probability):
        expected = 0.0
        for answer_correct in (True, False):
            joint = [w * (p if answer_correct else 1.0 - p) for w, p in zip(updated, p_row, strict=True)]
            mass = sum(joint)
            if mass > 0:
                expected -= mass * sum(q / mass * math.log(q / mass) for q in joint if q > 0)
        if expected < best:
            best, best_index = expected, i
    return updated, best_index


def quest_plus() -> None:
    prepared = QuestPlus.prepare(RULE)
    observer = PsychometricObserver(SUBJECT, seed=1)
    state = prepared.start()
    for trial in range(1, 21):  # a posterior partway through a run, not the flat prior
        intensity = prepared.next_intensity(state)
        state = prepared.update(state, intensity, observer.answer(trial, intensity))
    intensity = prepared.next_intensity(state)
    answer = observer.answer(21, intensity)
    probability = prepared.probability.tolist()
    posterior = state.posterior.tolist()
    index = prepared.index_of(intensity)

    def vectorised() -> int:
        return prepared.next_index(prepared.update(state, intensity, answer))

    def naive() -> int:
        return naive_trial(probability, posterior, index, answer)[1]

    times = interleaved_seconds({"numpy": vectorised, "naive": naive, "prepare": lambda: QuestPlus.prepare(RULE)})
    cells = prepared.probability.size
    print(f"QUEST+ grid: {len(RULE.intensities)} intensities x {len(RULE.thresholds)} thresholds x "
          f"{len(RULE.slopes)} slopes x {len(RULE.lapses)} lapses = {cells} cells per table")
    print(f"{'what':<40} {SPREAD_HEADER} {'unit':<4} {'ratio':>9}")
    share = statistics.median(times["numpy"]) / statistics.median(times["naive"])
    print(f"{'update + next intensity (numpy)':<40} {spread(times['numpy'], digits=3)} ms   "
          f"{share:>8.4f}x  (the naive loop {1 / share:.0f} times slower)")
    print(f"{'  naive pure-Python loop (reference)':<40} {spread(times['naive'])} ms")
    print(f"{'prepare the tables (once)':<40} {spread(times['prepare'], digits=2)} ms")
    same = vectorised() == naive()
    print(f"same next intensity from both: {'yes' if same else 'NO'}")
    tables = prepared.probability.nbytes + prepared.answer_entropy.nbytes
    print(f"memory: tables {tables / 1e6:.2f} MB (2 x {cells} float64); preparing peaks at "
          f"{peak_bytes(lambda: QuestPlus.prepare(RULE)) / 1e6:.2f} MB; a trial at "
          f"{peak_bytes(vectorised) / 1e3:.0f} kB")


def staircase_and_fit() -> None:
    rule = StaircaseRule(domain=tuple(float(v) for v in range(10, 301, 10)), down=2, up=1,
                         steps=(StepSizes(0, 4, 4), StepSizes(2, 2, 2), StepSizes(4, 1, 1)),
                         stop_after_trials=100, estimate_reversals=8)
    outcomes = [bool(v) for v in np.random.default_rng(0).random(100) < 0.7]
    state = replay(rule, 20, outcomes[:50])[-1].state
    intensities = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0])
    n = np.full(len(intensities), 40)
    k = np.random.default_rng(0).binomial(n, SUBJECT.probability(intensities))
    times = interleaved_seconds({
        "advance": lambda: advance(rule, state, True),
        "replay": lambda: replay(rule, 20, outcomes),
        "posterior": lambda: threshold_posterior("weibull", intensities, k, n, guess=0.5),
    }, runs=3)
    print(f"\n{'what':<40} {SPREAD_HEADER} {'unit':<4} {'ratio':>9}")
    print(f"{'staircase: one answer (advance)':<40} {spread(times['advance'], 1e6)} us")
    print(f"{'staircase: replay of 100 answers':<40} {spread(times['replay'], 1e3, 2)} ms   "
          f"{ratio(times['replay'], times['advance']):>9}  (of one answer)")
    print(f"{'threshold posterior, 8 intensities':<40} {spread(times['posterior'])} ms   "
          f"{ratio(times['posterior'], times['replay']):>9}  (of the replay)")


def run() -> None:
    quest_plus()
    staircase_and_fit()
