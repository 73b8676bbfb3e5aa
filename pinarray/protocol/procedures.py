"""An adaptive design's procedures as the protocol states them: frozen values, exact numbers.

A design that adapts one stimulus parameter names it with its unit (`Parameter`), lists the
values it may take (ascending: a higher value is an easier stimulus), says what the subject
does (`Task`, which fixes the answer that counts as correct) and runs one or more procedures,
interleaved at random: transformed or weighted up/down staircases (`Staircase`) and QUEST+
(`QuestPlus`). `pinarray.protocol.adaptive_design` reads them; `pinarray.adaptive` holds the
rules as numbers; the session decides each trial's value from the rows on disk.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from fractions import Fraction

# What a trial row's procedure cell says of trials no procedure ran (no procedure is so named).
CATCH = "catch"
PRACTICE = "practice"


class Parameter(StrEnum):
    """The stimulus parameter a design adapts, with its unit, as the protocol names it."""

    SOA_MS = "soa_ms"  # a wave's stimulus onset asynchrony
    FREQUENCY_HZ = "frequency_hz"  # a train's frequency
    DURATION_MS = "duration_ms"  # a train's signal length
    STROKE_STEPS = "stroke_steps"  # how far a pin lifts: STS servos, in encoder steps
    STROKE_US = "stroke_us"  # how far a pin lifts: hobby servos, in us of pulse width

    @property
    def unit(self) -> str:
        return {"ms": "ms", "hz": "Hz", "steps": "steps", "us": "us"}[self.value.rsplit("_", 1)[1]]

    @property
    def quantity(self) -> str:
        """The parameter's name without its unit (soa, stroke...)."""
        return self.value.rsplit("_", 1)[0]

    @property
    def is_stroke(self) -> bool:
        return self in (Parameter.STROKE_STEPS, Parameter.STROKE_US)


Task = str
"""What the subject answers in an adaptive design, which fixes the answer that counts as
correct: each paradigm names its own (`pinarray.protocol.seam.ParadigmDesign.tasks`: ``order``
for temporal order, ``discrimination`` for two intervals...)."""
DETECTION: Task = "detection"  # anything felt on a stimulus trial (nothing, on a catch trial)


class Function(StrEnum):
    """The psychometric function QUEST+ assumes (see `pinarray.adaptive.psychometric`)."""

    WEIBULL = "weibull"
    LOGISTIC = "logistic"


@dataclass(frozen=True)
class StepSize:
    """From the ``after_reversals``-th reversal on, a move down takes ``down`` steps of the
    values' index and a move up takes ``up``."""

    after_reversals: int
    down: int
    up: int


@dataclass(frozen=True)
class Staircase:
    """A transformed (``down`` correct in a row to move down, ``up`` wrong to move up) and
    weighted (step sizes) up/down staircase; the rule is `pinarray.adaptive.staircase`'s.

    ``start`` is one of the design's values; ``stop_after_reversals`` 0 stops on the trial
    limit alone; the estimate is the mean of the last ``estimate_reversals`` reversals.
    """

    name: str
    start: Fraction
    down: int
    up: int
    steps: tuple[StepSize, ...]
    stop_after_trials: int
    stop_after_reversals: int
    estimate_reversals: int


@dataclass(frozen=True)
class UniformPrior:
    """Every threshold of the grid equally likely before the first trial."""


@dataclass(frozen=True)
class NormalPrior:
    """Thresholds weighted by a normal density (``mean``, ``sd`` in the parameter's unit)."""

    mean: Fraction
    sd: Fraction


Prior = UniformPrior | NormalPrior


@dataclass(frozen=True)
class QuestPlus:
    """QUEST+ over a grid of thresholds x slopes x lapse rates (the guess rate is the task's),
    each trial's value the one of least expected posterior entropy; it stops after
    ``stop_after_trials``, or once the threshold's 95 % credible interval is narrower than
    ``stop_below_width`` (0: on the trial limit alone)."""

    name: str
    function: Function
    thresholds: tuple[Fraction, ...]
    slopes: tuple[Fraction, ...]
    lapse_rates: tuple[Fraction, ...]
    threshold_prior: Prior
    stop_after_trials: int
    stop_below_width: Fraction


Procedure = Staircase | QuestPlus


@dataclass(frozen=True)
class CatchTrials:
    """Trials that present no stimulus to judge, mixed in at random and moving no procedure.

    ``stimulus`` names the stimulus they present (a no-wave control); empty: the adapted
    stimulus at a stroke of 0 (nothing lifts).
    """

    count: int
    stimulus: str = ""


@dataclass(frozen=True)
class Adaptive:
    """What a design adapts, over which values, for which task, by which procedures."""

    parameter: Parameter
    values: tuple[Fraction, ...]  # strictly ascending
    task: Task
    guess_rate: Fraction  # the chance of a correct answer without feeling the stimulus
    procedures: tuple[Procedure, ...]
    catch: CatchTrials = CatchTrials(0)

    @property
    def procedure_trials(self) -> int:
        """The most trials the procedures can take (each stops at its limit at the latest)."""
        return sum(p.stop_after_trials for p in self.procedures)

    @property
    def easiest(self) -> Fraction:
        """The value practice trials present: the highest."""
        return self.values[-1]

    def procedure(self, name: str) -> Procedure:
        return next(p for p in self.procedures if p.name == name)
