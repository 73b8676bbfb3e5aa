"""Transformed and weighted up/down staircases over a discrete domain of intensities.

The rule, step by step (a test recomputes every row from it):

- The domain is a tuple of intensities in ascending order; the staircase stands on an index
  into it and presents ``domain[index]``. It starts at a stated index.
- Two counters: consecutive correct answers and consecutive wrong answers. A correct answer
  adds one to the first and sets the second to 0; a wrong answer the other way round.
- When the correct counter reaches ``down`` the staircase *moves down* and both counters
  return to 0; when the wrong counter reaches ``up`` it *moves up* and both return to 0.
  Otherwise it does not move (1-up/2-down: ``up=1, down=2``, converging on 70.7 % correct;
  1-up/3-down on 79.4 %).
- A move is a *reversal* when the staircase has moved before and its previous move went the
  other way. The reversal's intensity is that of the trial whose answer made the move (the
  intensity just presented).
- The size of a move, in whole steps of the domain's index, comes from the `StepSizes` entry
  with the largest ``after_reversals`` not above the number of reversals so far, counting this
  move's own reversal if it is one; within an entry, a move down takes ``down_steps`` and a
  move up ``up_steps`` (weighted up/down, Kaernbach 1991: with ``up=down=1`` it converges on
  the intensity answered correctly ``up_steps / (up_steps + down_steps)`` of the time, 75 %
  for up 3, down 1).
- The new index is clamped to the domain: at an end the staircase stays at the end. A move
  decided there still counts as a move in its direction (it can make a reversal, and a later
  move the other way is a reversal), even though the index did not change.
- The staircase is finished after ``stop_after_trials`` trials, or earlier once it has made
  ``stop_after_reversals`` reversals. Every rule has a trial limit: a staircase that stops on
  reversals alone never ends for a subject who answers wrong at the top of the domain (or
  right at its bottom) every time.
- Its estimate is the arithmetic mean of the intensities (not the indices) of its last
  ``estimate_reversals`` reversals, or of all of them while it has fewer.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from itertools import pairwise

import numpy as np

from pinarray.errors import PinArrayError


class Move(StrEnum):
    DOWN = "down"
    UP = "up"


@dataclass(frozen=True)
class StepSizes:
    """From the ``after_reversals``-th reversal on, a move down takes ``down_steps`` steps of
    the domain's index and a move up ``up_steps``."""

    after_reversals: int
    down_steps: int
    up_steps: int


@dataclass(frozen=True, kw_only=True)
class StaircaseRule:
    """A staircase's rule (the module docstring says how each field acts).

    ``domain``: intensities in the adapted parameter's unit, strictly ascending.
    ``steps``: step sizes, the first from 0 reversals, ``after_reversals`` strictly rising
    (default: one step of the index each way throughout).
    ``stop_after_reversals``: None stops on the trial limit alone.
    """

    domain: tuple[float, ...]
    down: int
    up: int
    stop_after_trials: int
    estimate_reversals: int
    steps: tuple[StepSizes, ...] = (StepSizes(0, 1, 1),)
    stop_after_reversals: int | None = None

    def __post_init__(self) -> None:
        domain = self.domain
        if self.stop_after_trials is None:
            raise PinArrayError(
                "a staircase needs a trial limit (stop_after_trials), found none: one that stops "
                "on reversals alone never ends for a subject who answers wrong at the top of its "
                "domain every time")
        if len(domain) < 2:
            raise PinArrayError(f"a staircase's domain needs 2 intensities or more, found {len(domain)}")
        if not all(np.isfinite(x) for x in domain) or any(b <= a for a, b in pairwise(domain)):
            raise PinArrayError(f"a staircase's domain must be finite and strictly ascending, found {domain}")
        for name, value in (("down", self.down), ("up", self.up),
                            ("stop_after_trials", self.stop_after_trials),
                            ("estimate_reversals", self.estimate_reversals)):
            _at_least_one(name, value)
        if self.stop_after_reversals is not None:
            _at_least_one("stop_after_reversals", self.stop_after_reversals)
            if self.estimate_reversals > self.stop_after_reversals:
                raise PinArrayError(
                    f"a staircase that stops after {self.stop_after_reversals} reversals cannot "
                    f"estimate from its last {self.estimate_reversals}")
        if not self.steps or self.steps[0].after_reversals != 0:
            raise PinArrayError("a staircase's step sizes must start after 0 reversals, found "
                                f"{[s.after_reversals for s in self.steps]}")
        for before, after in pairwise(self.steps):
            if after.after_reversals <= before.after_reversals:
                raise PinArrayError("a staircase's step sizes must change after strictly more "
                                    f"reversals each time, found {[s.after_reversals for s in self.steps]}")
        for sizes in self.steps:
            _at_least_one("down_steps", sizes.down_steps)
            _at_least_one("up_steps", sizes.up_steps)

    def step_sizes(self, reversals: int) -> StepSizes:
        """The step sizes in force once ``reversals`` reversals have been made."""
        return [s for s in self.steps if s.after_reversals <= reversals][-1]


def _at_least_one(name: str, value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise PinArrayError(f"a staircase's {name} must be a whole number of 1 or more, found {value!r}")


@dataclass(frozen=True)
class StaircaseState:
    """Where a staircase stands before its next trial.

    ``index``: the next intensity's index into the domain; ``trials``: answers taken so far;
    ``correct_run`` / ``wrong_run``: the two counters; ``last_move``: None before the first
    move; ``reversal_intensities``: every reversal's intensity, in order; ``finished``: the
    rule's stop has been reached (no further trial)."""

    index: int
    trials: int = 0
    correct_run: int = 0
    wrong_run: int = 0
    last_move: Move | None = None
    reversal_intensities: tuple[float, ...] = ()
    finished: bool = False

    @property
    def reversals(self) -> int:
        return len(self.reversal_intensities)


@dataclass(frozen=True)
class StaircaseStep:
    """One trial: its number (1-based), the index and intensity presented, the answer, the move
    it made (None: none), whether that move was a reversal, and the state after it."""

    trial: int
    index: int
    intensity: float
    correct: bool
    move: Move | None
    reversal: bool
    state: StaircaseState


def start(rule: StaircaseRule, start_index: int) -> StaircaseState:
    """The state before the first trial, standing on ``domain[start_index]``."""
    if isinstance(start_index, bool) or not isinstance(start_index, int) \
            or not 0 <= start_index < len(rule.domain):
        raise PinArrayError(f"a staircase's start must be an index from 0 to {len(rule.domain) - 1} "
                            f"into its domain, found {start_index!r}")
    return StaircaseState(index=start_index)


def advance(rule: StaircaseRule, state: StaircaseState, correct: bool) -> StaircaseStep:
    """The trial at ``state`` answered ``correct``, by the module's rule."""
    if state.finished:
        raise PinArrayError(f"the staircase finished after {state.trials} trials and "
                            f"{state.reversals} reversals: it takes no more answers")
    correct_run = state.correct_run + 1 if correct else 0
    wrong_run = 0 if correct else state.wrong_run + 1
    move: Move | None = None
    if correct_run >= rule.down:
        move = Move.DOWN
    elif wrong_run >= rule.up:
        move = Move.UP
    intensity = rule.domain[state.index]
    reversal = move is not None and state.last_move is not None and move != state.last_move
    reversals = state.reversal_intensities + ((intensity,) if reversal else ())
    index = state.index
    if move is not None:
        correct_run = wrong_run = 0
        sizes = rule.step_sizes(len(reversals))
        shift = -sizes.down_steps if move is Move.DOWN else sizes.up_steps
        index = min(max(index + shift, 0), len(rule.domain) - 1)
    trials = state.trials + 1
    finished = trials >= rule.stop_after_trials or (
        rule.stop_after_reversals is not None and len(reversals) >= rule.stop_after_reversals)
    after = StaircaseState(index, trials, correct_run, wrong_run,
                           move if move is not None else state.last_move, reversals, finished)
    return StaircaseStep(trials, state.index, intensity, bool(correct), move, reversal, after)


def replay(rule: StaircaseRule, start_index: int, outcomes: Iterable[bool]) -> tuple[StaircaseStep, ...]:
    """Every step of a staircase started at ``start_index`` and answered ``outcomes`` in order
    (a resumed run rebuilds its state as ``replay(...)[-1].state``)."""
    state = start(rule, start_index)
    steps = []
    for correct in outcomes:
        step = advance(rule, state, correct)
        steps.append(step)
        state = step.state
    return tuple(steps)


def reversal_mean(rule: StaircaseRule, state: StaircaseState) -> float | None:
    """The arithmetic mean of the intensities of the last ``estimate_reversals`` reversals (of
    all of them while there are fewer); None before the first reversal."""
    if not state.reversal_intensities:
        return None
    last = state.reversal_intensities[-rule.estimate_reversals:]
    return float(np.mean(np.asarray(last, dtype=np.float64)))
