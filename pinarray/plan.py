"""The trial plan: which condition each trial presents, in which order. Seeded and reproducible.

Trials are numbered 1..N in plan order (practice trials first), and that number is the one
every output uses. The same protocol and seed give a byte-identical plan.
"""

from __future__ import annotations

import json
import secrets
from collections import Counter
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

from pinarray.errors import PinArrayError
from pinarray.protocol.design import MAX_SHUFFLE_WORK
from pinarray.protocol.model import Condition, Ordering, Protocol, condition_value
from pinarray.protocol.seam import paradigm_named

if TYPE_CHECKING:
    import numpy as np

# numpy is imported where a plan is drawn, not here: modules that only name `PlannedTrial`
# or `TrialPlan` stay light.

SEARCH_BUDGET_STEPS = 200_000


@dataclass(frozen=True)
class PlannedTrial:
    """One trial of a plan: its ``trial`` number (1..N in plan order, the number every output
    uses), its ``block`` (0 for practice), whether it is ``practice``, the ``condition`` it
    presents, and whether it is a ``catch`` trial of an adaptive design."""

    trial: int  # 1..N in plan order, the number every output uses
    block: int  # 0 for practice, then 1..blocks
    practice: bool
    condition: Condition
    # A catch trial of an adaptive design: it presents no stimulus to judge and moves no
    # procedure (its condition is the catch stimulus, or the adapted one at a stroke of 0).
    catch: bool = False

    def record(self) -> dict:
        """JSON-safe description, as stored in manifests and compile outputs: the trial, its
        block, practice and stimulus, then what its paradigm says of the condition
        (`ParadigmDesign.plan_fields`). Every entry has a pin, frequency_hz, direction and row
        (null where its paradigm has none), as plans have had since the first release."""
        c = self.condition
        what: dict[str, object] = {"pin": None, "frequency_hz": None, "direction": None,
                                   "row": None}
        what |= paradigm_named(c.paradigm).plan_fields(c)
        return ({"trial": self.trial, "block": self.block, "practice": self.practice,
                 "stimulus": c.stimulus} | what | ({"catch": True} if self.catch else {}))


@dataclass(frozen=True)
class TrialPlan:
    """A seeded plan: the ``seed`` it was drawn with and its ``trials`` in plan order."""

    seed: int
    trials: tuple[PlannedTrial, ...]

    def __len__(self) -> int:
        return len(self.trials)

    def trial(self, number: int) -> PlannedTrial:
        """Trial ``number`` (1-based), or a `PinArrayError` saying the plan's range."""
        if not 1 <= number <= len(self.trials):
            raise PinArrayError(
                f"trial {number} is not in the plan: expected 1 to {len(self.trials)}"
            )
        return self.trials[number - 1]

    def to_json(self) -> str:
        """The plan as JSON, as a run's manifest stores it."""
        return json.dumps(
            {"seed": self.seed, "trials": [t.record() for t in self.trials]}, indent=1
        )


class _Pool:
    """The trials still to place, as counts of each distinct condition, with every constrained
    attribute's value coded as an integer: a search step costs a few array operations, not a
    pass over Python objects, whatever the number of conditions."""

    def __init__(self, items: list[Condition], limits: dict[str, int]) -> None:
        import numpy as np

        counts = Counter(items)
        self.conditions = list(counts)  # in order of first appearance, as Counter keeps them
        self.remaining = np.array([counts[c] for c in self.conditions], dtype=np.int64)
        # Candidates are offered in this fixed order (a condition's key is unique to it).
        self.order = np.array(sorted(range(len(self.conditions)),
                                     key=lambda i: repr(self.conditions[i].key)), dtype=np.int64)
        # Codes numbered in order of first appearance, so the first of equally frequent values
        # is the one a Counter would name first.
        self.codes: dict[str, dict[object, int]] = {}
        self.coded: dict[str, np.ndarray] = {}
        for attribute in limits:
            codes = self.codes[attribute] = {}
            self.coded[attribute] = np.array(
                [codes.setdefault(condition_value(c, attribute), len(codes)) for c in self.conditions],
                dtype=np.int64,
            )

    def code(self, attribute: str, value: object) -> int:
        return self.codes[attribute].get(value, -1)


def _feasible(pool: _Pool, limits: dict[str, int], runs: dict[str, tuple[int, int]]) -> bool:
    """Whether the trials left can still be ordered: no value outnumbers what can separate it."""
    import numpy as np

    size = int(pool.remaining.sum())
    if not size:
        return True
    for attribute, limit in limits.items():
        counts = np.bincount(pool.coded[attribute], weights=pool.remaining)
        value = int(np.argmax(counts))  # the first of the most frequent
        count = int(counts[value])
        last, run = runs.get(attribute, (-1, 0))
        head = limit - run if value == last else limit
        if count > head + limit * (size - count):
            return False
    return True


def constrained_shuffle(
    items: list[Condition],
    limits: dict[str, int],
    rng: np.random.Generator,
    runs: dict[str, tuple[object, int]] | None = None,
) -> list[Condition]:
    """A random order of ``items`` with runs of equal attribute values capped by ``limits``.

    Depth-first search over random choices, pruned by a counting bound, with a step budget so
    a pathological case ends in an error rather than a hang.
    """

    if not limits:
        order = list(items)
        rng.shuffle(order)
        return order
    pool = _Pool(items, limits)
    remaining = pool.remaining
    # A step weighs every distinct condition: with many of them, fewer steps make the budget
    # (never fewer than twice the trials, which a search without dead ends takes).
    budget = min(SEARCH_BUDGET_STEPS,
                 max(2 * len(items), MAX_SHUFFLE_WORK // len(pool.conditions)))
    start = {attribute: (pool.code(attribute, value), run)
             for attribute, (value, run) in (runs or {}).items() if attribute in limits}
    # A stack of (candidates still to try at this depth, runs before the choice).
    path: list[int] = []
    stack: list[tuple[list[int], dict[str, tuple[int, int]]]] = []

    def candidates() -> list[int]:
        keys = pool.order[remaining[pool.order] > 0]
        weights = remaining[keys].astype(float)
        order = rng.choice(len(keys), size=len(keys), replace=False, p=weights / weights.sum())
        return keys[order].tolist()

    stack.append((candidates(), start))
    steps = 0
    while len(path) < len(items):
        steps += 1
        if steps > budget:
            raise PinArrayError(
                f"could not order {len(items)} trials under the constraints {limits} within "
                f"{budget} search steps; relax no_repeat/max_run"
            )
        options, runs_before = stack[-1]
        if not options:
            stack.pop()
            if not path:
                raise PinArrayError(f"no order of the trials satisfies the constraints {limits}")
            remaining[path.pop()] += 1
            continue
        choice = options.pop()
        new_runs = {}
        allowed = True
        for attribute, limit in limits.items():
            value = int(pool.coded[attribute][choice])
            last, run = runs_before.get(attribute, (-1, 0))
            run = run + 1 if value == last else 1
            if run > limit:
                allowed = False
                break
            new_runs[attribute] = (value, run)
        if not allowed:
            continue
        remaining[choice] -= 1
        if not _feasible(pool, limits, new_runs):
            remaining[choice] += 1
            continue
        path.append(choice)
        stack.append((candidates() if len(path) < len(items) else [], new_runs))
    return [pool.conditions[i] for i in path]


def _runs_after(sequence: list[Condition], limits: dict[str, int]) -> dict[str, tuple[object, int]]:
    runs: dict[str, tuple[object, int]] = {}
    for condition in sequence:
        for attribute in limits:
            value = condition_value(condition, attribute)
            last, run = runs.get(attribute, (None, 0))
            runs[attribute] = (value, run + 1 if value == last else 1)
    return runs


def williams_square(n: int) -> list[list[int]]:
    """A balanced Latin square (Williams design): each condition follows each other equally.

    For odd ``n`` the mirrored rows are appended, giving 2n rows.
    """
    return [williams_row(n, r) for r in range(williams_rows(n))]


def williams_rows(n: int) -> int:
    """How many rows the Williams square of ``n`` conditions has."""
    return 2 * n if n % 2 else n


def williams_row(n: int, r: int) -> list[int]:
    """Row ``r`` of the Williams square of ``n`` conditions, without building the square (a
    plan of thousands of conditions needs a few rows of it, not millions of cells)."""
    if r >= n:
        return williams_row(n, r - n)[::-1]  # the mirrored half of an odd square
    first = [0]
    low, high = 1, n - 1
    for i in range(1, n):
        if i % 2:
            first.append(low)
            low += 1
        else:
            first.append(high)
            high -= 1
    return [(x + r) % n for x in first]


class _Draws:
    """The plan's seeded generator, made when the plan first draws from it: a sequential plan
    draws nothing, and `numpy.random` is some 20 ms of a command's start-up."""

    def __init__(self, seed: int):
        self.seed = seed

    @cached_property
    def rng(self) -> np.random.Generator:
        import numpy as np

        return np.random.default_rng(self.seed)


def make_plan(protocol: Protocol, seed: int | None = None) -> TrialPlan:
    """The seeded trial plan; the seed is the argument, else the protocol's, else a fresh one."""
    design = protocol.design
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)
                             or not 0 <= seed < 2**63):
        raise PinArrayError(f"a plan seed must be a whole number from 0 to 2^63-1, found "
                            f"{seed!r}")
    if seed is None:
        seed = design.seed if design.seed is not None else secrets.randbits(32)
    draws = _Draws(seed)
    if design.adaptive is not None:
        return TrialPlan(seed, _adaptive_trials(protocol, draws.rng))
    limits = design.constraints.limits()
    conditions = list(design.conditions)
    blocks: list[list[Condition]] = []
    if design.ordering is Ordering.SEQUENTIAL:
        blocks = [conditions * design.repetitions for _ in range(design.blocks)]
    elif design.ordering is Ordering.LATIN_SQUARE:
        rows = williams_rows(len(conditions))
        offset = int(draws.rng.integers(rows))
        for b in range(design.blocks):
            row = williams_row(len(conditions), (offset + b) % rows)
            blocks.append([conditions[i] for i in row] * design.repetitions)
    elif design.ordering is Ordering.FULL_RANDOM:
        pooled = constrained_shuffle(conditions * design.repetitions * design.blocks, limits,
                                     draws.rng)
        size = len(conditions) * design.repetitions
        blocks = [pooled[i * size : (i + 1) * size] for i in range(design.blocks)]
    else:
        runs: dict[str, tuple[object, int]] = {}
        for _ in range(design.blocks):
            block = constrained_shuffle(conditions * design.repetitions, limits, draws.rng, runs)
            runs = _runs_after(block, limits)
            blocks.append(block)

    trials: list[PlannedTrial] = []
    if design.practice_trials:
        picks = draws.rng.permutation(
            len(conditions) * -(-design.practice_trials // len(conditions)))
        for i in picks[: design.practice_trials]:
            trials.append(
                PlannedTrial(len(trials) + 1, 0, True, conditions[int(i) % len(conditions)])
            )
    for number, block in enumerate(blocks, start=1):
        for condition in block:
            trials.append(PlannedTrial(len(trials) + 1, number, False, condition))
    return TrialPlan(seed, tuple(trials))


def _adaptive_trials(protocol: Protocol, rng: np.random.Generator) -> tuple[PlannedTrial, ...]:
    """An adaptive design's trials: practice, then as many as its procedures can take with its
    catch trials among them at random places; each draws its condition at random. Which
    procedure runs a trial, and at which value, is decided as the run goes (from its rows)."""
    design = protocol.design
    adaptive = design.adaptive
    assert adaptive is not None
    conditions = design.conditions
    catch_condition: Condition | None = None
    if adaptive.catch.stimulus:
        stimulus = protocol.stimulus(adaptive.catch.stimulus)
        catch_condition = design.paradigm.catch_condition(stimulus)
    trials = [PlannedTrial(n, 0, True, conditions[int(rng.integers(len(conditions)))])
              for n in range(1, design.practice_trials + 1)]
    main = adaptive.procedure_trials + adaptive.catch.count
    catches = set(rng.choice(main, size=adaptive.catch.count, replace=False).tolist())
    balanced = None
    if design.paradigm.balanced_draws:
        # Which interval holds the comparison, which pin goes first: as often one way as the
        # other (to within one trial), in a seeded order.
        copies = -(-main // len(conditions))
        balanced = rng.permutation(len(conditions) * copies) % len(conditions)
    for index in range(main):
        drawn = (conditions[int(rng.integers(len(conditions)))] if balanced is None
                 else conditions[int(balanced[index])])
        catch = index in catches
        condition = catch_condition if catch and catch_condition is not None else drawn
        trials.append(PlannedTrial(len(trials) + 1, 1, False, condition, catch))
    return tuple(trials)
