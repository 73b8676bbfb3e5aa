"""The ``adaptive`` key of a design: which parameter adapts, over which values, by which procedures.

    adaptive:
      parameter: soa_ms                     # soa_ms, frequency_hz, duration_ms, stroke_steps/us
      values: {from: 40, to: 400, step: 20} # or a list; ascending: a higher value is easier
      task: direction                       # direction, detection or localisation
      guess_rate: 0.5                       # default: 1/directions, 1/pins, or 0 (detection)
      catch_trials: {count: 4, stimulus: no_wave}
      procedures:
        from_above: {method: staircase, start: 400, down: 2, up: 1, stop_after_trials: 40,
                     stop_after_reversals: 10, estimate_reversals: 6,
                     step_sizes: [{after_reversals: 0, down: 2, up: 2},
                                  {after_reversals: 2, down: 1, up: 1}]}
        quest: {method: quest_plus, function: weibull, stop_after_trials: 60,
                slopes: [1, 2, 3, 4, 5], lapse_rates: [0, 0.02, 0.04],
                threshold_prior: {mean: 120, sd: 60}, stop_below_width: 20}

Every procedure has a trial limit (one that stops on reversals or on the posterior's width
alone may never end); every value is checked on every stimulus the design draws from, as the
trial would play it (its period, the servo's speed, no pin driven twice at once, the pins'
calibrated limits for a stroke), so no value a procedure can choose is refused mid-run.
Pure Python, like the rest of the protocol's reading.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from fractions import Fraction
from functools import partial
from typing import TYPE_CHECKING, cast

from pinarray.errors import PinArrayError
from pinarray.protocol.adapted import adapted_drives
from pinarray.protocol.device import MS, whole_ns
from pinarray.protocol.drives import check_no_overlap, pulse_slots
from pinarray.protocol.model import Condition, Device, Stimulus, Train
from pinarray.protocol.procedures import (
    CATCH,
    PRACTICE,
    Adaptive,
    CatchTrials,
    Function,
    NormalPrior,
    Parameter,
    Prior,
    Procedure,
    QuestPlus,
    Staircase,
    StepSize,
    UniformPrior,
)
from pinarray.protocol.quest_grid import uninformative
from pinarray.protocol.stimuli import check_bus, check_period, check_train_on_pins
from pinarray.protocol.yaml_nodes import Invalid, MappingNode, Node, Reader

if TYPE_CHECKING:
    from pinarray.protocol.seam import ParadigmDesign, Rehearse

ADAPTIVE_KEYS = {"parameter", "values", "task", "guess_rate", "catch_trials", "procedures"}
STAIRCASE_KEYS = {"method", "start", "down", "up", "step_sizes", "stop_after_trials",
                  "stop_after_reversals", "estimate_reversals"}
QUEST_KEYS = {"method", "function", "thresholds", "slopes", "lapse_rates", "threshold_prior",
              "stop_after_trials", "stop_below_width"}
MAX_VALUES = 1000  # values a parameter may take, and thresholds a QUEST+ grid may hold
MAX_PROCEDURES = 16
MAX_PROCEDURE_TRIALS = 2000
# QUEST+'s grid: values x thresholds x slopes x lapse rates, what its two tables hold (8 B
# each), summed over a design's procedures: a run holds them all (64 MB at most), and a trial
# computes over its procedure's (about 60 ms at the limit).
MAX_GRID = 4_000_000
MAX_CHECKS = 20_000  # (value, stimulus) pairs checked as they would play
RESERVED = (CATCH, PRACTICE)
PROCEDURE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,31}")
DEFAULT_SLOPES: tuple[Fraction, ...] = tuple(map(Fraction, (1, 2, 3, 4, 5)))
DEFAULT_LAPSES: tuple[Fraction, ...] = (Fraction(0), Fraction(1, 50), Fraction(1, 25))


def read_parameter(reader: Reader, node: Node, paradigm: ParadigmDesign,
                   device: Device) -> Parameter:
    """The adapted parameter: one the paradigm's stimuli have, a stroke in the device's unit."""
    allowed = tuple(p.value for p in paradigm.parameters)
    parameter = Parameter(reader.string(node, f"the adapted parameter of a {paradigm.name} "
                                              "design", allowed))
    unit = device.servo.position_unit
    if parameter.is_stroke and parameter.unit != unit:
        raise reader.error(node, f"expected stroke_{unit} (this device's positions are in "
                                 f"{unit}), found {parameter.value}")
    return parameter


def adaptive_keys(reader: Reader, node: Node) -> dict[str, Node]:
    return reader.mapping(node, ADAPTIVE_KEYS, {"parameter", "values", "task", "procedures"},
                          "adaptive design")


def read_values(reader: Reader, keys: Mapping[str, Node], parameter: Parameter) -> tuple[Fraction, ...]:
    """The values the parameter takes; an SOA or a signal length in whole nanoseconds, as
    every time inside the core is (rounded, two values could become one)."""
    values = _values(reader, keys["values"], parameter.unit, parameter.is_stroke)
    if parameter.unit == "ms":
        node = keys["values"]
        items = ([node] * len(values) if isinstance(node, MappingNode)
                 else reader.sequence(node, "the values"))
        what = "each SOA" if parameter is Parameter.SOA_MS else "each signal length"
        for item, value in zip(items, values, strict=True):
            whole_ns(reader, item, value, MS, what, "ms")
    return values


def read_adaptive(reader: Reader, keys: Mapping[str, Node], paradigm: ParadigmDesign, device: Device,
                  parameter: Parameter, values: tuple[Fraction, ...],
                  conditions: Sequence[Condition], by_name: Mapping[str, Stimulus],
                  rehearse: Rehearse | None = None) -> Adaptive:
    """The ``adaptive`` section (its ``keys``), every value checked on every condition it can
    present (``rehearse``: and played on the model it stands for, as
    `pinarray.protocol.seam.check_conditions` plays a fixed design's conditions)."""
    task = reader.string(keys["task"], f"the task of a {paradigm.name} design",
                         tuple(paradigm.tasks))
    guess = reader.optional(
        keys, "guess_rate",
        lambda n: reader.number(n, "the guess rate", "", maximum=Fraction(99, 100), allow_zero=True),
        paradigm.default_guess(task, conditions))
    catch = reader.optional(keys, "catch_trials",
                            lambda n: _catch(reader, n, paradigm, parameter, by_name),
                            CatchTrials(0))
    procedures = _procedures(reader, keys["procedures"], values, guess)
    _check_values(reader, keys["values"], paradigm, device, parameter, values, conditions,
                  by_name, rehearse)
    return Adaptive(parameter, values, task, guess, procedures, catch)


def _values(reader: Reader, node: Node, unit: str, whole: bool,
            what: str = "the values") -> tuple[Fraction, ...]:
    """A list, or ``{from, to, step}`` (``to`` a whole number of steps from ``from``);
    ``whole``: each a whole number of ``unit``."""
    if isinstance(node, MappingNode):
        keys = reader.mapping(node, {"from", "to", "step"}, {"from", "to", "step"}, what)
        first, last, step = (reader.number(keys[k], f"{what}' {k}", unit)
                             for k in ("from", "to", "step"))
        count = (last - first) / step
        if last <= first or count.denominator != 1:
            raise reader.error(node, f"expected {what} to run from {float(first):g} up to "
                                     f"{float(first):g} plus a whole number of {float(step):g} "
                                     f"{unit} steps, found to: {float(last):g}")
        if count + 1 > MAX_VALUES:
            raise reader.error(node, f"expected at most {MAX_VALUES} of {what}, found "
                                     f"{int(count) + 1}")
        values = tuple(first + i * step for i in range(int(count) + 1))
    else:
        items = reader.sequence(node, what, 2)
        if len(items) > MAX_VALUES:
            raise reader.error(node, f"expected at most {MAX_VALUES} of {what}, found {len(items)}")
        values = tuple(reader.number(n, f"each of {what}", unit) for n in items)
        for item, before, after in zip(items[1:], values, values[1:], strict=False):
            if after <= before:
                raise reader.error(item, f"expected {what} in ascending order (a higher value is "
                                         f"an easier stimulus), found {float(after):g} after "
                                         f"{float(before):g}")
    if whole and any(v.denominator != 1 for v in values):
        raise reader.error(node, f"expected strokes in whole {unit}, found "
                                 f"{float(next(v for v in values if v.denominator != 1)):g}")
    return values


def _catch(reader: Reader, node: Node, paradigm: ParadigmDesign, parameter: Parameter,
           by_name: Mapping[str, Stimulus]) -> CatchTrials:
    keys = reader.mapping(node, {"count", "stimulus"}, {"count"}, "catch trials")
    count = reader.integer(keys["count"], "the catch trials' count", 0, MAX_PROCEDURE_TRIALS)
    if "stimulus" not in keys:
        if not parameter.is_stroke:
            raise reader.error(node, "expected catch trials to name the stimulus they present "
                                     "(e.g. a no-wave control), found none: only a stroke "
                                     "can be presented at 0 (nothing lifts)")
        return CatchTrials(count)
    name = reader.string(keys["stimulus"], "the catch trials' stimulus", tuple(by_name))
    try:
        paradigm.catch_condition(by_name[name])
    except PinArrayError as problem:
        raise reader.error(keys["stimulus"], str(problem)) from None
    return CatchTrials(count, name)


def _procedures(reader: Reader, node: Node, values: tuple[Fraction, ...],
                guess: Fraction) -> tuple[Procedure, ...]:
    pairs = reader.items(node, "the procedures")
    if not 1 <= len(pairs) <= MAX_PROCEDURES:
        raise reader.error(node, f"expected 1 to {MAX_PROCEDURES} procedures, found {len(pairs)}")
    procedures: list[Procedure] = []
    with reader.section():
        for key_node, value_node in pairs:
            name = str(reader.attempt(partial(reader.scalar_value, key_node), ""))
            if not PROCEDURE_NAME.fullmatch(name) or name in RESERVED:
                reader.error(key_node, "expected a procedure name (a letter, then up to 31 "
                                       "letters, digits, _ or -; not catch or practice), found "
                                       f"{name!r}")
                continue
            procedure: Procedure | None = reader.attempt(
                partial(_procedure, reader, value_node, name, values, guess), None)
            if procedure is not None:
                procedures.append(procedure)
    # A run holds every procedure's tables at once, and power computes over them all.
    size = sum(_grid_size(p, values) for p in procedures if isinstance(p, QuestPlus))
    if size > MAX_GRID:
        raise reader.error(node, f"expected QUEST+ grids of at most {MAX_GRID:,} points in all "
                                 "(values x thresholds x slopes x lapse rates, summed over the "
                                 f"procedures), found {size:,}")
    return tuple(procedures)


def _grid_size(procedure: QuestPlus, values: tuple[Fraction, ...]) -> int:
    return (len(values) * len(procedure.thresholds) * len(procedure.slopes)
            * len(procedure.lapse_rates))


def _procedure(reader: Reader, node: Node, name: str, values: tuple[Fraction, ...],
               guess: Fraction) -> Procedure:
    keys = reader.mapping(node, STAIRCASE_KEYS | QUEST_KEYS, {"method"}, f"procedure {name!r}")
    method = reader.string(keys["method"], "the method", ("staircase", "quest_plus"))
    allowed = STAIRCASE_KEYS if method == "staircase" else QUEST_KEYS
    for key in sorted(keys.keys() - allowed):  # the first wrong key, the same every time
        raise reader.error(keys[key], f"expected the keys of a {method} ("
                                      f"{', '.join(sorted(allowed))}), found {key!r}")
    if "stop_after_trials" not in keys:
        raise reader.error(node, f"expected a 'stop_after_trials' key in procedure {name!r}, "
                                 "found none: one that stops on "
                                 + ("reversals" if method == "staircase" else "its posterior")
                                 + " alone may never end")
    trials = reader.integer(keys["stop_after_trials"], "the trial limit", 1, MAX_PROCEDURE_TRIALS)
    if method == "staircase":
        return _staircase(reader, node, keys, name, values, trials)
    return _quest_plus(reader, node, keys, name, values, guess, trials)


def _staircase(reader: Reader, node: Node, keys: dict[str, Node], name: str,
               values: tuple[Fraction, ...], trials: int) -> Staircase:
    for key in ("start", "down", "up", "estimate_reversals"):
        if key not in keys:
            raise reader.error(node, f"expected a {key!r} key in staircase {name!r}, found none")
    start = reader.number(keys["start"], "the start", "")
    if start not in values:
        raise reader.error(keys["start"], f"expected the start to be one of the values "
                                          f"({_listed(values)}), found {float(start):g}")
    down = reader.integer(keys["down"], "down (correct answers in a row to move down)", 1, 10)
    up = reader.integer(keys["up"], "up (wrong answers in a row to move up)", 1, 10)
    reversals = reader.optional(
        keys, "stop_after_reversals",
        lambda n: reader.integer(n, "the reversals to stop after", 1, MAX_PROCEDURE_TRIALS), 0)
    estimate = reader.integer(keys["estimate_reversals"], "the reversals to estimate from", 1,
                              MAX_PROCEDURE_TRIALS)
    if reversals and estimate > reversals:
        raise reader.error(keys["estimate_reversals"], f"expected at most the {reversals} "
                                                       f"reversals it stops after, found {estimate}")
    one_each: tuple[StepSize, ...] = (StepSize(0, 1, 1),)
    steps = reader.optional(keys, "step_sizes", lambda n: _step_sizes(reader, n, len(values)),
                            one_each)
    return Staircase(name, start, down, up, steps, trials, reversals, estimate)


def _step_sizes(reader: Reader, node: Node, count: int) -> tuple[StepSize, ...]:
    steps: list[StepSize] = []
    for item in reader.sequence(node, "the step sizes"):
        keys = reader.mapping(item, {"after_reversals", "down", "up"},
                              {"after_reversals", "down", "up"}, "step size")
        after = reader.integer(keys["after_reversals"], "after_reversals", 0, MAX_PROCEDURE_TRIALS)
        if steps and after <= steps[-1].after_reversals:
            raise reader.error(keys["after_reversals"],
                               f"expected step sizes after more reversals than "
                               f"{steps[-1].after_reversals}, found {after}")
        if not steps and after != 0:
            raise reader.error(keys["after_reversals"], "expected the first step sizes "
                                                        f"after 0 reversals, found {after}")
        steps.append(StepSize(after, *(reader.integer(keys[k], f"the {k} step (in values)", 1,
                                                       count - 1) for k in ("down", "up"))))
    return tuple(steps)


def _quest_plus(reader: Reader, node: Node, keys: dict[str, Node], name: str,
                values: tuple[Fraction, ...], guess: Fraction, trials: int) -> QuestPlus:
    function = Function(reader.optional(
        keys, "function", lambda n: reader.string(n, "the function", tuple(Function)),
        Function.WEIBULL.value))
    thresholds = values
    if "thresholds" in keys:
        thresholds = _values(reader, keys["thresholds"], "", False, "the thresholds")
    if function is Function.LOGISTIC and "slopes" not in keys:
        raise reader.error(node, f"procedure {name!r}: a logistic's slope is per unit of the "
                                 "parameter; expected its 'slopes' stated, found none")
    slopes = reader.optional(keys, "slopes", lambda n: _grid(reader, n, "the slopes", False),
                             DEFAULT_SLOPES)
    lapses = reader.optional(keys, "lapse_rates", lambda n: _grid(reader, n, "the lapse rates",
                                                                   True), DEFAULT_LAPSES)
    if max(lapses) + guess >= 1:
        raise reader.error(keys.get("lapse_rates", node), f"expected lapse rates below "
                                                           f"{float(1 - guess):g} (1 - the guess "
                                                           f"rate), found {float(max(lapses)):g}")
    size = len(values) * len(thresholds) * len(slopes) * len(lapses)
    if size > MAX_GRID:  # this one alone; `_procedures` adds them up
        raise reader.error(node, f"expected a QUEST+ grid of at most {MAX_GRID:,} points (values "
                                 f"x thresholds x slopes x lapse rates), found {size:,}")
    prior = reader.optional(keys, "threshold_prior", lambda n: _prior(reader, n),
                                   cast(Prior, UniformPrior()))
    width = reader.optional(keys, "stop_below_width",
                            lambda n: reader.number(n, "the credible interval's width", ""),
                            Fraction(0))
    procedure = QuestPlus(name, function, thresholds, slopes, lapses, prior, trials, width)
    problem = uninformative(procedure, values, guess)
    if problem:
        where = next((keys[k] for k in ("threshold_prior", "thresholds") if k in keys), node)
        raise reader.error(where, problem)
    return procedure


def _grid(reader: Reader, node: Node, what: str, zero: bool) -> tuple[Fraction, ...]:
    items = reader.sequence(node, what)
    if len(items) > MAX_VALUES:
        raise reader.error(node, f"expected at most {MAX_VALUES} of {what}, found {len(items)}")
    grid = tuple(reader.number(n, f"each of {what}", "", allow_zero=zero,
                               maximum=Fraction(1, 2) if zero else None) for n in items)
    if len(set(grid)) != len(grid):
        raise reader.error(node, f"expected each of {what} once, found {_listed(grid)}")
    return tuple(sorted(grid))


def _prior(reader: Reader, node: Node) -> Prior:
    if not isinstance(node, MappingNode):
        reader.string(node, "the threshold prior", ("uniform",))
        return UniformPrior()
    keys = reader.mapping(node, {"mean", "sd"}, {"mean", "sd"}, "threshold prior")
    return NormalPrior(reader.number(keys["mean"], "the prior's mean", ""),
                       reader.number(keys["sd"], "the prior's sd", ""))


def _listed(values: Sequence[Fraction]) -> str:
    shown = [f"{float(v):g}" for v in values]
    return ", ".join(shown if len(shown) <= 6 else [*shown[:3], "...", *shown[-2:]])


def _check_values(reader: Reader, node: Node, paradigm: ParadigmDesign, device: Device,
                  parameter: Parameter,
                  values: tuple[Fraction, ...], conditions: Sequence[Condition],
                  by_name: Mapping[str, Stimulus], rehearse: Rehearse | None = None) -> None:
    """Every value on every condition, as the trial would play it (played on ``rehearse``'s
    model last, when nothing else in the file is wrong); the first problem reported."""
    distinct = list(dict.fromkeys(conditions))
    if len(distinct) * len(values) > MAX_CHECKS:
        raise reader.error(node, f"expected at most {MAX_CHECKS:,} values x stimuli, found "
                                 f"{len(values)} x {len(distinct)}")
    # Here, not at the top: the design's reader imports this module.
    from pinarray.protocol.design import MAX_PULSES_PER_TRIAL

    for value in values:
        for condition in distinct:
            where = f"at {parameter.value} {float(value):g}: "
            try:
                played, drives = adapted_drives(paradigm, device, by_name[condition.stimulus],
                                                condition, parameter, value)
                check_no_overlap(drives)
            except PinArrayError as problem:
                raise reader.error(node, where + str(problem)) from None
            trains: dict[Train, set[int]] = {}
            for drive in drives:
                trains.setdefault(drive.train, set()).add(drive.pin)
            slots = sum(pulse_slots(d.train) for d in drives)
            if slots > MAX_PULSES_PER_TRIAL:
                raise reader.error(node, f"{where}expected at most {MAX_PULSES_PER_TRIAL:,} "
                                         f"pulses in one trial, found {slots:,}")
            # The stimuli's own checks, their message told at this value.
            probe = Reader(reader.source)
            probe.guessing = reader.guessing
            try:
                for train, pins in trains.items():
                    check_period(probe, node, node, train)
                    check_train_on_pins(probe, node, train, sorted(pins), played)
                check_bus(probe, node, drives, played)
            except Invalid:
                raise reader.error(node, where + probe.errors[0].message) from None
            if rehearse is not None and not reader.errors and not reader.guessing:
                undelivered = rehearse(drives, played)
                if undelivered is not None:
                    raise reader.error(node, where + undelivered)
