"""Apparent motion's simulated studies (`pinarray.analysis.power`): the seed's findings, tested.

The criteria (subjects as the unit): **direction above chance** (each subject's direction-right
% of the wave trials felt against 50 %, a one-sample t-test) and **motion felt more on waves**
(each subject's felt % on wave against no-wave trials, a paired t-test).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.analysis.power import Criterion, StudyOutcome, significant_above
from pinarray.paradigms.apparent_motion.design import MotionAnswer, MotionCondition, directions
from pinarray.paradigms.apparent_motion.observer import MotionObserver, MotionObserverModel
from pinarray.protocol.model import Direction, Protocol

CRITERIA = {
    "direction above chance": Criterion("one-sample t-test of each subject's direction-right % "
                                        "(of the wave trials felt) against 50 %: p < 0.05 and "
                                        "above", test=True),
    "motion felt more on waves": Criterion("paired t-test of each subject's felt % on wave "
                                           "against no-wave trials: p < 0.05 and higher on "
                                           "waves", test=True),
}


@dataclass(frozen=True)
class SubjectCounts:
    """One simulated subject's answers, counted."""

    wave: int
    felt: int
    right: int
    no_wave: int
    no_wave_felt: int


@dataclass(frozen=True)
class MotionPower:
    """Apparent motion's `pinarray.analysis.power.PowerModel` of one protocol: the main
    trials' wave directions (none: the no-wave control), those a subject may name."""

    model: MotionObserverModel
    trials: tuple[Direction, ...]
    named: tuple[Direction, ...]

    @property
    def criteria(self) -> Mapping[str, Criterion]:
        return CRITERIA

    @property
    def answers(self) -> int:
        return len(self.trials)

    @property
    def subject_sd(self) -> float:
        return self.model.subject_sd_logit

    def described(self) -> str:
        return f"a between-subject SD of {self.model.subject_sd_logit:g} logit units"

    def subject(self, rng: np.random.Generator) -> SubjectCounts:
        observer = MotionObserver(self.model, rng, self.named)
        wave = felt = right = no_wave = no_wave_felt = 0
        for direction in self.trials:
            said = observer.respond(direction)
            if direction == Direction.NONE:
                no_wave += 1
                no_wave_felt += said != MotionAnswer.NONE
            else:
                wave += 1
                felt += said != MotionAnswer.NONE
                right += said.value == direction.value  # named the way the wave went
        return SubjectCounts(wave, felt, right, no_wave, no_wave_felt)

    def study(self, subjects: Sequence[object]) -> StudyOutcome:
        counted = [s for s in subjects if isinstance(s, SubjectCounts)]
        outcome = StudyOutcome()
        if not self.trials:
            return outcome
        felt = [100 * s.felt / s.wave for s in counted if s.wave]
        direction = [100 * s.right / s.felt for s in counted if s.felt]
        outcome.record("motion felt", felt)
        outcome.record("direction right of felt", direction)
        outcome.found["direction above chance"] = significant_above(direction, 50.0)
        paired = [100 * s.felt / s.wave - 100 * s.no_wave_felt / s.no_wave for s in counted
                  if s.wave and s.no_wave]
        if paired:
            outcome.found["motion felt more on waves"] = significant_above(paired)
        return outcome


def power(protocol: Protocol, model: MotionObserverModel) -> MotionPower:
    """Simulated studies of ``protocol`` by subjects of ``model``."""
    from pinarray.plan import make_plan

    trials = tuple(t.condition.direction for t in make_plan(protocol, 0).trials
                   if not t.practice and isinstance(t.condition, MotionCondition))
    return MotionPower(model, trials, directions(protocol.design))
