"""An adaptive design's procedures running: the protocol's staircases and QUEST+ as live rules.

`ProcedureSet` builds each procedure of a protocol's `Adaptive` from `pinarray.adaptive`,
says which procedure runs the next trial and at which value, and takes answers. Which one runs
is decided from the seed, the number of procedure trials answered so far plus one, and the
procedures still unfinished (`pinarray.adaptive.interleave`), so a run rebuilt from its
answers continues identically. Practice trials present the easiest value, catch trials the
catch stimulus (or a stroke of 0); neither moves a procedure. The session feeds it the rows on
disk (`pinarray.session.procedures`); `pinarray power` feeds it simulated subjects.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from fractions import Fraction

from pinarray.adaptive.interleave import pick_procedure
from pinarray.adaptive.questplus import QuestPlus as QuestPlusMachine
from pinarray.adaptive.questplus import QuestPlusRule, QuestPlusState, normal_weights
from pinarray.adaptive.staircase import (
    StaircaseRule,
    StaircaseState,
    StepSizes,
    advance,
    reversal_mean,
    start,
)
from pinarray.protocol.model import Condition
from pinarray.protocol.procedures import (
    CATCH,
    PRACTICE,
    Adaptive,
    NormalPrior,
    Procedure,
    QuestPlus,
    Staircase,
    Task,
)


@dataclass(frozen=True)
class Presented:
    """What an adaptive trial presents: for ``procedure`` (a name, `CATCH` or `PRACTICE`),
    the parameter at ``value``; None: the catch stimulus as the protocol states it."""

    procedure: str
    value: Fraction | None


@dataclass(frozen=True)
class AdaptiveFields:
    """What an answer did to its procedure: a reversal (staircases; None: QUEST+), and the
    procedure's threshold estimate after it (QUEST+: with its 95 % credible interval)."""

    reversal: bool | None
    estimate: float | None
    ci_low: float | None
    ci_high: float | None


def counts_as_correct(task: Task, condition: Condition, catch: bool, response: str) -> bool:
    """Whether ``response`` counts as correct for ``task``: on a catch trial, nothing felt (no
    motion); otherwise as the condition's paradigm judges it (`ParadigmDesign.counts_as_correct`:
    the wave's direction named, the moved pin named, anything felt...)."""
    from pinarray.protocol.seam import paradigm_named

    return paradigm_named(condition.paradigm).counts_as_correct(task, condition, catch,
                                                                response)


class _Staircase:
    def __init__(self, procedure: Staircase, values: tuple[Fraction, ...]):
        self.rule = StaircaseRule(
            domain=tuple(map(float, values)), down=procedure.down, up=procedure.up,
            stop_after_trials=procedure.stop_after_trials,
            estimate_reversals=procedure.estimate_reversals,
            steps=tuple(StepSizes(s.after_reversals, s.down, s.up) for s in procedure.steps),
            stop_after_reversals=procedure.stop_after_reversals or None)
        self.state: StaircaseState = start(self.rule, values.index(procedure.start))

    @property
    def finished(self) -> bool:
        return self.state.finished

    def next_index(self) -> int:
        return self.state.index

    def estimate(self) -> AdaptiveFields:
        return AdaptiveFields(None, reversal_mean(self.rule, self.state), None, None)

    def take(self, index: int, correct: bool) -> AdaptiveFields:
        """The answer to the trial at ``index`` (the staircase's own: it stands there)."""
        step = advance(self.rule, self.state, correct)
        self.state = step.state
        return replace(self.estimate(), reversal=step.reversal)


def prepare_quest_plus(adaptive: Adaptive) -> dict[str, QuestPlusMachine]:
    """Each QUEST+ procedure of ``adaptive``, its tables computed (they never change: one
    preparation serves every `ProcedureSet` of the design, e.g. each simulated subject's)."""
    prepared = {}
    for procedure in adaptive.procedures:
        if not isinstance(procedure, QuestPlus):
            continue
        thresholds = tuple(map(float, procedure.thresholds))
        prior = procedure.threshold_prior
        prepared[procedure.name] = QuestPlusMachine.prepare(QuestPlusRule(
            kind=procedure.function.value, intensities=tuple(map(float, adaptive.values)),
            thresholds=thresholds, slopes=tuple(map(float, procedure.slopes)),
            lapses=tuple(map(float, procedure.lapse_rates)), guess=float(adaptive.guess_rate),
            stop_after_trials=procedure.stop_after_trials,
            stop_below_width=float(procedure.stop_below_width) or None,
            threshold_prior=(normal_weights(thresholds, float(prior.mean), float(prior.sd))
                             if isinstance(prior, NormalPrior) else None)))
    return prepared


class _QuestPlus:
    def __init__(self, machine: QuestPlusMachine):
        self.machine = machine
        self.state: QuestPlusState = self.machine.start()
        self._next: tuple[int, int] | None = None  # (trials, index): chosen once per state
        self._finished: tuple[QuestPlusState, bool] | None = None  # asked once per state too

    @property
    def finished(self) -> bool:
        # Asked several times a trial (which procedures are left to run), and it can read the
        # posterior's interval: answered once for each state.
        if self._finished is None or self._finished[0] is not self.state:
            self._finished = (self.state, self.machine.finished(self.state))
        return self._finished[1]

    def next_index(self) -> int:
        if self._next is None or self._next[0] != self.state.trials:
            self._next = (self.state.trials, self.machine.next_index(self.state))
        return self._next[1]

    def estimate(self) -> AdaptiveFields:
        summary = self.machine.summary(self.state)
        return AdaptiveFields(None, summary.threshold_mean, summary.threshold_ci_low,
                              summary.threshold_ci_high)

    def take(self, index: int, correct: bool) -> AdaptiveFields:
        """The answer to a trial at the value of ``index``."""
        self.state = self.machine.update(self.state, self.machine.rule.intensities[index], correct)
        return self.estimate()


class ProcedureSet:
    """Every procedure of an adaptive design, from its first trial on."""

    def __init__(self, adaptive: Adaptive, seed: int,
                 prepared: Mapping[str, QuestPlusMachine] | None = None):
        self.adaptive = adaptive
        self.seed = seed
        prepared = prepare_quest_plus(adaptive) if prepared is None else prepared
        self._running: dict[str, _Staircase | _QuestPlus] = {
            p.name: self._machine(p, prepared) for p in adaptive.procedures}
        self.taken = 0  # procedure trials answered so far

    def _machine(self, procedure: Procedure,
                 prepared: Mapping[str, QuestPlusMachine]) -> _Staircase | _QuestPlus:
        if isinstance(procedure, Staircase):
            return _Staircase(procedure, self.adaptive.values)
        return _QuestPlus(prepared[procedure.name])

    @property
    def unfinished(self) -> tuple[str, ...]:
        return tuple(name for name, m in self._running.items() if not m.finished)

    @property
    def finished(self) -> bool:
        return not self.unfinished

    def runs(self, name: str) -> bool:
        return name in self._running

    def next(self, practice: bool = False, catch: bool = False) -> Presented:
        """What the next trial presents, the procedures standing as they do."""
        if practice:
            return Presented(PRACTICE, self.adaptive.easiest)
        if catch:
            return Presented(CATCH, None if self.adaptive.catch.stimulus else Fraction(0))
        name = pick_procedure(self.seed, self.taken + 1, self.unfinished)
        return Presented(name, self.adaptive.values[self._running[name].next_index()])

    def take(self, name: str, value: Fraction, correct: bool) -> AdaptiveFields:
        """Procedure ``name`` presented ``value`` (what `next` said) and got ``correct``."""
        machine = self._running[name]
        fields = machine.take(self.adaptive.values.index(value), correct)
        self.taken += 1
        return fields

    def estimate(self, name: str) -> AdaptiveFields:
        """Procedure ``name``'s threshold estimate as it stands."""
        return self._running[name].estimate()
