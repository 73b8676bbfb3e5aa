"""Checking an adaptive design's procedures before running people: simulated subjects of a known function.

Each simulated subject answers as `pinarray.adaptive.observer.PsychometricObserver` draws from
the function, through the protocol's own procedures interleaved as a run interleaves them
(`pinarray.procedures.ProcedureSet`; catch and practice trials move no procedure and are left
out). Per procedure: the estimate's bias (mean minus the truth) and spread (sd, and the 2.5 and
97.5 % points) over the subjects, and the trials it took.

The truth a procedure aims at: QUEST+ estimates the function's threshold; a staircase converges
on the value answered correctly with the probability its rule balances. With ``up`` = 1 and
step sizes ``d`` down and ``u`` up (the last in force), it moves down with probability
``p**down`` a trial's worth and up otherwise, so it is at equilibrium where
``p**down * d = (1 - p**down) * u`` (1-up/2-down with equal steps: p = 0.707; Kaernbach's
weighted 1-up/1-down: p = u / (d + u)); its truth is the function's value at that p. With
``up`` > 1 there is no such closed form, and the bias is reported against the threshold.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric
from pinarray.errors import PinArrayError
from pinarray.procedures import ProcedureSet, prepare_quest_plus
from pinarray.protocol.procedures import Adaptive, Procedure, QuestPlus, Staircase

if TYPE_CHECKING:
    from pinarray.adaptive.questplus import QuestPlus as QuestPlusMachine

MAX_SUBJECTS = 10_000
# The work of a check, measured on the 2-core machine this was written on: any procedure's
# trial takes about 80 us (choosing, answering, the estimate); a QUEST+ trial also computes
# over its grid (the next value, the update), 10-15 ns a point; preparing its tables once,
# 50-120 ns a point. An upper bound: QUEST+ may stop before its trial limit.
TRIAL_NS = 80_000
QUEST_NS_PER_POINT = 15
PREPARE_NS_PER_POINT = 120


def target_probability(procedure: Procedure) -> float | None:
    """The probability correct a staircase converges on (see the module); None for QUEST+
    and for staircases with ``up`` above 1."""
    if not isinstance(procedure, Staircase) or procedure.up != 1:
        return None
    last = procedure.steps[-1]
    return float((last.up / (last.down + last.up)) ** (1.0 / procedure.down))


def truth_for(procedure: Procedure, function: Psychometric) -> tuple[float, str]:
    """The value the procedure estimates for a subject of ``function``, and what it is."""
    p = target_probability(procedure)
    if p is None or not function.guess < p < 1 - function.lapse:
        return function.threshold, "threshold"
    return function.intensity_for(p), f"{p:.1%} correct"


@dataclass(frozen=True)
class ProcedureCheck:
    """One procedure over the simulated subjects."""

    name: str
    truth: float
    truth_is: str
    estimates: tuple[float, ...]  # one per subject whose procedure made an estimate
    trials: tuple[int, ...]  # per subject
    no_estimate: int  # subjects whose staircase never reversed

    @property
    def bias(self) -> float:
        return float(np.mean(self.estimates)) - self.truth if self.estimates else float("nan")

    @property
    def sd(self) -> float:
        return float(np.std(self.estimates, ddof=1)) if len(self.estimates) > 1 else float("nan")

    def interval(self) -> tuple[float, float]:
        if not self.estimates:
            return float("nan"), float("nan")
        low, high = np.percentile(self.estimates, [2.5, 97.5])
        return float(low), float(high)


def grid_points(adaptive: Adaptive, procedure: Procedure) -> int:
    """The cells of a QUEST+ procedure's tables (values x thresholds x slopes x lapse rates;
    0 for a staircase): what each of its trials computes over."""
    if not isinstance(procedure, QuestPlus):
        return 0
    return (len(adaptive.values) * len(procedure.thresholds) * len(procedure.slopes)
            * len(procedure.lapse_rates))


def check_seconds(adaptive: Adaptive, subjects: int) -> float:
    """About how long `check_procedures` takes at most, s: each procedure's trial limit for
    each subject, a QUEST+ trial `QUEST_NS_PER_POINT` per grid point, preparing its tables once
    (`PREPARE_NS_PER_POINT`); any trial, `TRIAL_NS` besides."""
    work_ns = sum(subjects * p.stop_after_trials
                  * (TRIAL_NS + QUEST_NS_PER_POINT * grid_points(adaptive, p))
                  + PREPARE_NS_PER_POINT * grid_points(adaptive, p)
                  for p in adaptive.procedures)
    return work_ns / 1e9


@dataclass(frozen=True)
class SimulatedAnswer:
    """One procedure trial of a simulated run: which procedure presented which value (the
    adapted parameter's unit), and whether the answer was correct."""

    procedure: str
    intensity: float
    correct: bool


def subject_seed(seed: int, subject: int) -> int:
    """The run seed of simulated subject ``subject`` (0-based) of a check seeded ``seed``."""
    return (seed * 1_000_003 + subject) % 2**63


def simulated_run(adaptive: Adaptive, function: Psychometric, run_seed: int,
                  prepared: Mapping[str, QuestPlusMachine] | None = None,
                  ) -> tuple[ProcedureSet, tuple[SimulatedAnswer, ...]]:
    """One simulated subject of ``function`` through every procedure of ``adaptive``, as a run
    interleaves them (catch and practice trials left out): the procedures as they finished and
    the answers in order. ``prepared``: the QUEST+ tables, computed once for many subjects
    (`pinarray.procedures.prepare_quest_plus`)."""
    procedures = ProcedureSet(adaptive, run_seed, prepared)
    observer = PsychometricObserver(function, run_seed)
    answers = []
    while not procedures.finished:
        presented = procedures.next()
        assert presented.value is not None
        correct = observer.answer(procedures.taken + 1, float(presented.value))
        procedures.take(presented.procedure, presented.value, correct)
        answers.append(SimulatedAnswer(presented.procedure, float(presented.value), correct))
    return procedures, tuple(answers)


def check_procedures(adaptive: Adaptive, function: Psychometric, subjects: int,
                     seed: int, progress: Callable[[int], object] = lambda done: None,
                     ) -> tuple[ProcedureCheck, ...]:
    """Every procedure of ``adaptive`` run by ``subjects`` simulated subjects of ``function``;
    ``progress`` hears how many subjects are done after each."""
    if not 1 <= subjects <= MAX_SUBJECTS:
        raise PinArrayError(f"expected 1 to {MAX_SUBJECTS:,} simulated subjects, found {subjects}")
    names = [p.name for p in adaptive.procedures]
    estimates: dict[str, list[float]] = {n: [] for n in names}
    trials: dict[str, list[int]] = {n: [] for n in names}
    missing = dict.fromkeys(names, 0)
    prepared = prepare_quest_plus(adaptive)  # once: every subject's procedures share the tables
    for subject in range(subjects):
        procedures, answers = simulated_run(adaptive, function, subject_seed(seed, subject),
                                            prepared)
        taken = dict.fromkeys(names, 0)
        for answer in answers:
            taken[answer.procedure] += 1
        for name in names:
            estimate = procedures.estimate(name).estimate
            trials[name].append(taken[name])
            if estimate is None:
                missing[name] += 1
            else:
                estimates[name].append(estimate)
        progress(subject + 1)
    checks = []
    for procedure in adaptive.procedures:
        truth, what = truth_for(procedure, function)
        checks.append(ProcedureCheck(procedure.name, truth, what,
                                     tuple(estimates[procedure.name]),
                                     tuple(trials[procedure.name]), missing[procedure.name]))
    return tuple(checks)


def check_table(checks: Sequence[ProcedureCheck], unit: str) -> list[str]:
    """The checks as a table: one line per procedure."""
    lines = [f"{'procedure':<14} {'truth':>10} {'(of)':<14} {'bias':>8} {'sd':>8} "
             f"{'95% of estimates':>20} {'trials median [min-max]':>24}"]
    for c in checks:
        low, high = c.interval()
        t = sorted(c.trials)
        lines.append(f"{c.name:<14} {c.truth:>10.4g} {c.truth_is:<14} {c.bias:>+8.3g} "
                     f"{c.sd:>8.3g} {f'{low:.4g}-{high:.4g} {unit}':>20} "
                     f"{f'{int(np.median(t))} [{t[0]}-{t[-1]}]':>24}"
                     + (f"  ({c.no_estimate} without a reversal)" if c.no_estimate else ""))
    return lines
