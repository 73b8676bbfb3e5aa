"""Localisation's simulated studies (`pinarray.analysis.power`): the seed's findings, tested.

The criteria (subjects as the unit):

- **highest vs lowest frequency (paired t)**: each subject's correct % at the highest against
  the lowest frequency, a paired t-test. Not the frequency effect `pinarray analyse` reports
  (a mixed-effects logistic regression over every frequency), whose fit (tenths of a second
  each, and only from 6 subjects) is too slow to repeat for thousands of simulated studies;
- **rising means**, **error A on top**, **pin N best**: how often the across-subject means come
  out in the seed's order (descriptive, not tests).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pinarray.analysis.power import Criterion, StudyOutcome, significant_above
from pinarray.grid import Grid
from pinarray.paradigms.localisation.design import LocalisationCondition
from pinarray.paradigms.localisation.observer import ObserverModel, SimulatedObserver
from pinarray.paradigms.localisation.stats import CATEGORIES
from pinarray.protocol.model import Protocol

PAIRED_FREQUENCY = "highest vs lowest frequency (paired t)"
CRITERIA = {
    PAIRED_FREQUENCY: Criterion(
        "paired t-test of each subject's correct % at the highest against the lowest "
        "frequency: p < 0.05 and higher at the highest. Not the frequency effect `pinarray "
        "analyse` reports (a mixed-effects logistic regression over every frequency): a "
        "different test, whose power is not simulated here", test=True),
    "rising means": Criterion("the across-subject mean correct % rises strictly from each "
                              "frequency to the next", test=False),
    "error A on top": Criterion("the across-subject mean % of error A exceeds B, C and D at "
                                "every frequency", test=False),
    "pin best": Criterion("the pin the model localises best (pin 4 by default) has the highest "
                          "across-subject mean correct % over all frequencies, strictly (no "
                          "tie)", test=False),
}


@dataclass(frozen=True)
class Design:
    """The main trials of a protocol, as the observer needs them: (pin, frequency_hz) each."""

    trials: tuple[tuple[int, float], ...]
    grid: Grid

    @property
    def frequencies_hz(self) -> tuple[float, ...]:
        return tuple(sorted({f for _, f in self.trials}))

    @property
    def pins(self) -> tuple[int, ...]:
        return tuple(sorted({p for p, _ in self.trials}))


def protocol_design(protocol: Protocol) -> Design:
    """The protocol's main trials (one plan; order does not matter to the observer)."""
    from pinarray.plan import make_plan

    trials = [(t.condition.pin, float(t.condition.frequency_hz))
              for t in make_plan(protocol, 0).trials
              if not t.practice and isinstance(t.condition, LocalisationCondition)]
    return Design(tuple(trials), protocol.device.grid)


@dataclass(frozen=True)
class SubjectCounts:
    """One simulated subject's answers, counted."""

    categories: np.ndarray  # [frequency index, category index] counts, `CATEGORIES` order
    pin_correct: np.ndarray  # [pin - 1]
    pin_trials: np.ndarray


def simulate_subject(design: Design, observer: SimulatedObserver) -> SubjectCounts:
    """Let one simulated subject answer every main trial of ``design``."""
    grid = design.grid
    frequencies = design.frequencies_hz
    categories = np.zeros((len(frequencies), len(CATEGORIES)), dtype=int)
    pin_correct = np.zeros(grid.pin_count, dtype=int)
    pin_trials = np.zeros(grid.pin_count, dtype=int)
    for pin, frequency_hz in design.trials:
        answer = observer.respond_localisation(pin, frequency_hz)
        verdict = "none" if answer is None else grid.classify(pin, answer).value
        categories[frequencies.index(frequency_hz), CATEGORIES.index(verdict)] += 1
        pin_trials[pin - 1] += 1
        pin_correct[pin - 1] += verdict == "correct"
    return SubjectCounts(categories, pin_correct, pin_trials)


def analyse_study(design: Design, subjects: Sequence[SubjectCounts],
                  best_pin: int | None) -> StudyOutcome:
    """The criteria and precision measures of one study, subjects as the unit."""
    outcome = StudyOutcome()
    found = outcome.found
    frequencies = design.frequencies_hz
    if not frequencies:
        return outcome
    counts = np.array([s.categories for s in subjects])  # subject x frequency x category
    shares = 100 * counts / counts.sum(axis=2, keepdims=True)
    correct = shares[:, :, 0]
    for i, f in enumerate(frequencies):
        outcome.record(f"correct at {f:g} Hz", correct[:, i])
    mean_correct = correct.mean(axis=0)
    if len(frequencies) > 1:
        found[PAIRED_FREQUENCY] = significant_above(correct[:, -1] - correct[:, 0])
        found["rising means"] = bool(np.all(np.diff(mean_correct) > 0))
    errors = shares[:, :, 1:5].mean(axis=0)  # frequency x A..D
    found["error A on top"] = bool(np.all(errors[:, 0] > errors[:, 1:].max(axis=1)))
    if best_pin is not None:
        pin_trials = np.array([s.pin_trials for s in subjects])
        pin_correct = np.array([s.pin_correct for s in subjects])
        stimulated = pin_trials[0] > 0
        pin_means = (100 * pin_correct[:, stimulated] / pin_trials[:, stimulated]).mean(axis=0)
        pins = [int(p) + 1 for p in np.flatnonzero(stimulated)]
        top = pin_means.max()
        found[f"pin {best_pin} best"] = bool(
            pin_means[pins.index(best_pin)] == top and np.sum(pin_means == top) == 1)
    return outcome


@dataclass(frozen=True)
class LocalisationPower:
    """Localisation's `pinarray.analysis.power.PowerModel` of one protocol."""

    model: ObserverModel
    design: Design
    best_pin: int | None

    @property
    def criteria(self) -> Mapping[str, Criterion]:
        return CRITERIA

    @property
    def answers(self) -> int:
        return len(self.design.trials)

    @property
    def subject_sd(self) -> float:
        return self.model.subject_sd_logit

    def described(self) -> str:
        return (f"a between-subject SD of {self.model.subject_sd_logit:g} logit units, "
                f"calibrated on pins {', '.join(map(str, self.model.pins))}")

    def subject(self, rng: np.random.Generator) -> SubjectCounts:
        return simulate_subject(self.design, SimulatedObserver(self.model, rng))

    def study(self, subjects: Sequence[object]) -> StudyOutcome:
        counted = [s for s in subjects if isinstance(s, SubjectCounts)]
        return analyse_study(self.design, counted, self.best_pin)


def power(protocol: Protocol, model: ObserverModel) -> LocalisationPower:
    """Simulated studies of ``protocol`` by subjects of ``model`` (calibrated on its pins)."""
    design = protocol_design(protocol)
    best_pin = None
    if design.trials:
        accuracy = np.mean([model.expected_pin_accuracy(f).ravel()
                            for f in design.frequencies_hz], axis=0)
        best_pin = max(design.pins, key=lambda p: accuracy[p - 1])
    return LocalisationPower(model, design, best_pin)
