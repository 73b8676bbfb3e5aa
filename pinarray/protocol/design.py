"""The ``design`` section: conditions, blocks and ordering, checked to be playable and bounded.

A design is refused at validation when its plan could not be drawn (an impossible ordering
constraint) or would not fit in a bounded time and memory: at most `MAX_TRIALS` trials, at
most `MAX_PULSES_PER_TRIAL` pulse slots in one trial (what a trial may play) and `MAX_PULSES` in
the whole plan (what `pinarray compile` writes and holds in memory). A design read for a file
only (``long_trials``: ``pinarray compile --allow-long``) may put the whole plan's pulses in one
trial. Pure Python: `pinarray validate` runs it without numpy. The lab's paradigms' conditions
are read by `pinarray.protocol.judgements`; blocks, order, constraints and bounds here, for all.

Past 400 lines on purpose: the section's reading and its bounds are one job (every paradigm's
conditions end in the same checks of size and order).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import replace
from fractions import Fraction
from functools import partial
from typing import NamedTuple

from pinarray.protocol.adaptive_design import (
    adaptive_keys,
    read_adaptive,
    read_parameter,
    read_values,
)
from pinarray.protocol.device import read_pin
from pinarray.protocol.drives import pulse_slots
from pinarray.protocol.judgements import KEYS_OF, Adapting, read_lab_design
from pinarray.protocol.model import (
    NS_PER_S,
    Condition,
    Constraints,
    Design,
    Device,
    LocalisationCondition,
    MotionCondition,
    Ordering,
    Paradigm,
    PathWave,
    Stimulus,
    TrainShape,
    TrainStimulus,
    Wave,
    WaveStimulus,
    condition_value,
)
from pinarray.protocol.procedures import Parameter
from pinarray.protocol.stimuli import (
    MAX_FREQUENCY_HZ,
    check_period,
    check_train_on_pins,
    stimulus_named,
)
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader

MAX_TRIALS = 20_000
MAX_PULSES_PER_TRIAL = 1_000_000
MAX_PULSES = 10_000_000
# Ordering under constraints weighs every distinct condition at each trial placed: trials x
# conditions is the work, about 0.2 us each here (a few seconds at most).
MAX_SHUFFLE_WORK = 20_000_000
# What an order constraint may name, by paradigm: what its trials have.
ATTRIBUTES_OF = {Paradigm.LOCALISATION: ("pin", "frequency_hz", "stimulus"),
                 Paradigm.APPARENT_MOTION: ("direction", "stimulus"),
                 Paradigm.IDENTIFICATION: ("pattern", "count"),
                 Paradigm.TWO_INTERVAL: ("comparison", "interval_order"),
                 Paradigm.TEMPORAL_ORDER: ("soa_ms", "first_pin")}
CONDITION_ATTRIBUTES = tuple(dict.fromkeys(a for names in ATTRIBUTES_OF.values() for a in names))
DESIGN_KEYS = {
    "paradigm",
    "stimulus",
    "pins",
    "frequencies_hz",
    "configurations",
    "repetitions",
    "blocks",
    "order",
    "constraints",
    "seed",
    "inter_trial_interval_s",
    "practice_trials",
    "adaptive",
    *(key for keys in KEYS_OF.values() for key in keys),
}
# Keys only the lab's paradigms read (identification, two intervals, temporal order).
LAB_ONLY_KEYS = frozenset(DESIGN_KEYS - {"paradigm", "stimulus", "pins", "frequencies_hz",
                                         "configurations", "repetitions", "blocks", "order",
                                         "constraints", "seed", "inter_trial_interval_s",
                                         "practice_trials", "adaptive"})
# What an adaptive design's procedures decide instead.
FIXED_ONLY = ("repetitions", "blocks", "order", "constraints")

# (conditions, pulse slots of each) of one block's worth, before repetitions
_Conditions = tuple[tuple[Condition, ...], tuple[int, ...]]


class _Section(NamedTuple):
    """What reading the conditions needs: the design's node and keys, and what it refers to."""

    node: Node
    keys: dict[str, Node]
    device: Device
    by_name: Mapping[str, Stimulus]
    declared: Mapping[str, Node]  # every stimulus name written (broken ones too), where
    long_trials: bool  # read for a file only: a trial may hold up to `MAX_PULSES`
    # An adaptive design's frequencies (the values it adapts), where the values are written.
    adapted_frequencies: tuple[Node, tuple[Fraction, ...]] | None = None


def read_design(
    reader: Reader,
    node: Node,
    device: Device,
    stimuli: Sequence[Stimulus],
    declared: Mapping[str, Node],
    long_trials: bool = False,
) -> Design:
    """The design, checked against the device and stimuli; ``declared`` names every stimulus
    written in the file, broken ones included (their problems are already reported).

    ``long_trials``: the design is compiled to a file, never played, so one trial may hold
    more than `MAX_PULSES_PER_TRIAL` pulses (up to the plan's `MAX_PULSES`).
    """
    keys = reader.mapping(node, DESIGN_KEYS, {"paradigm"}, "design")
    paradigm = Paradigm(
        reader.string(keys["paradigm"], "the paradigm", tuple(p.value for p in Paradigm))
    )
    by_name = {s.name: s for s in stimuli}
    if paradigm not in KEYS_OF:
        for key in sorted(keys.keys() & LAB_ONLY_KEYS):
            reader.error(keys[key], f"expected no {key!r} in a {paradigm.value} design (the "
                                    "lab's paradigms read it), found one")
    adaptive_node = keys.get("adaptive")
    adapting = None
    if adaptive_node is not None:
        adapting = reader.attempt(lambda: _adapting(reader, keys, adaptive_node, paradigm, device),
                                  None)
        if adapting is None:
            raise Invalid("adaptive")
    frequencies = None
    if (adapting is not None and adapting[1] is Parameter.FREQUENCY_HZ
            and paradigm is Paradigm.LOCALISATION):
        frequencies = (adapting[0]["values"], adapting[2])
    section = _Section(node, keys, device, by_name, declared, long_trials, frequencies)
    judgement = None
    if paradigm in KEYS_OF:
        lab = reader.attempt(lambda: read_lab_design(
            reader, node, keys, paradigm, device, by_name, declared,
            None if adapting is None else Adapting(adapting[1], adapting[2],
                                                   adapting[0]["values"])), None)
        read = None
        if lab is not None:
            read, judgement = (lab.conditions, lab.slots), lab.judgement
            for count in lab.slots:
                _check_pulses(reader, node, count, long_trials)
    else:
        read_conditions = _localisation if paradigm is Paradigm.LOCALISATION else _motion
        read = reader.attempt(lambda: read_conditions(reader, section), None)
    _check_shapes_completed(reader, section, paradigm)
    repetitions = reader.optional(
        keys, "repetitions", lambda n: reader.integer(n, "repetitions", 1, 1000), 1
    )
    blocks = reader.optional(keys, "blocks", lambda n: reader.integer(n, "blocks", 1, 1000), 1)
    ordering = Ordering(reader.optional(
        keys, "order", lambda n: reader.string(n, "the order", tuple(o.value for o in Ordering)),
        Ordering.RANDOM.value,
    ))
    constraints = reader.optional(
        keys, "constraints", lambda n: _constraints(reader, n, paradigm), Constraints()
    )
    seed = reader.optional(
        keys, "seed",
        lambda n: None if n.tag.endswith(":null") else reader.integer(n, "the seed", 0, 2**63 - 1),
        None,
    )
    iti = reader.optional(
        keys, "inter_trial_interval_s",
        lambda n: reader.number(n, "the inter-trial interval", "s", allow_zero=True, maximum=3600),
        Fraction(2),
    )
    practice = reader.optional(
        keys, "practice_trials", lambda n: reader.integer(n, "practice trials", 0, 100), 0
    )
    if read is None or not read[0]:
        # Their problems are already recorded (a design lists at least one pin and frequency,
        # or configuration, so none left means every one was wrong).
        raise Invalid("conditions")
    conditions, slots = read
    adaptive = None
    if adapting is not None:
        conditions = tuple(dict.fromkeys(
            replace(c, frequency_hz=frequencies[1][0])
            if frequencies is not None and isinstance(c, LocalisationCondition) else c
            for c in conditions))
        slots = (max(slots, default=0),) * len(conditions)
        adaptive_keys_, parameter, values = adapting
        adaptive = read_adaptive(reader, adaptive_keys_, paradigm, device, parameter, values,
                                 conditions, by_name)
    design = Design(
        paradigm,
        conditions,
        repetitions,
        blocks,
        ordering,
        constraints,
        seed,
        round(iti * NS_PER_S),
        practice,
        adaptive,
        judgement,
    )
    _check_size(reader, node, design, slots)
    problem = ordering_problem(design)
    if problem:
        raise reader.error(keys.get("constraints", node), problem)
    return design


def _adapting(reader: Reader, keys: Mapping[str, Node], node: Node, paradigm: Paradigm,
              device: Device) -> tuple[dict[str, Node], Parameter, tuple[Fraction, ...]]:
    """An adaptive design's keys, parameter and values (read before its conditions: a
    localisation design adapting the frequency takes its frequencies from the values)."""
    if paradigm is Paradigm.IDENTIFICATION:
        raise reader.error(node, "expected no 'adaptive' in an identification design (it has "
                                 "no intensity to adapt: two_interval and temporal_order do), "
                                 "found one")
    for key in FIXED_ONLY:
        if key in keys:
            raise reader.error(keys[key], f"expected no {key!r} in an adaptive design (its "
                                          f"procedures decide its trials), found one")
    adaptive = adaptive_keys(reader, node)
    parameter = read_parameter(reader, adaptive["parameter"], paradigm, device)
    if parameter is Parameter.FREQUENCY_HZ and "frequencies_hz" in keys:
        raise reader.error(keys["frequencies_hz"], "expected no 'frequencies_hz' in a design "
                                                   "that adapts the frequency (its values are "
                                                   "the frequencies), found one")
    return adaptive, parameter, read_values(reader, adaptive, parameter)


def _check_size(reader: Reader, node: Node, design: Design, slots: Sequence[int]) -> None:
    """The plan fits `MAX_TRIALS` and its pulses `MAX_PULSES` (each trial was checked alone)."""
    trials = design.trial_count
    if trials > MAX_TRIALS:
        raise reader.error(
            node,
            f"expected a design of at most {MAX_TRIALS:,} trials, found {trials:,} ("
            + (f"{len(design.conditions)} conditions x {design.repetitions} repetitions x "
               f"{design.blocks} blocks" if design.adaptive is None else
               "the procedures' trial limits and the catch trials")
            + f" + {design.practice_trials} practice)",
        )
    if design.adaptive is not None:
        return  # each trial at each value was checked alone; no plan is compiled whole
    pulses = sum(slots) * design.repetitions * design.blocks
    pulses += design.practice_trials * max(slots, default=0)
    if pulses > MAX_PULSES:
        raise reader.error(
            node,
            f"expected a design of at most {MAX_PULSES:,} pulses in all, found up to "
            f"{pulses:,} in its {trials:,} trials; shorten the signals or run fewer trials",
        )


def _localisation(reader: Reader, section: _Section) -> _Conditions:
    node, keys, device, by_name, declared, long_trials, adapted = section
    for key in ("stimulus", "pins", *(() if adapted else ("frequencies_hz",))):
        if key not in keys:
            raise reader.error(node, f"a localisation design needs a {key!r} key, found none")
    pin_nodes = reader.sequence(keys["pins"], "the pins")
    pins = [
        pin for n in pin_nodes
        if (pin := reader.attempt(partial(read_pin, reader, n, device.grid), None)) is not None
    ]
    if len(set(pins)) != len(pins):
        raise reader.error(keys["pins"], f"expected each pin once, found {pins}")
    stimulus = stimulus_named(reader, keys["stimulus"], by_name, declared, TrainStimulus)
    if adapted is None:
        frequency_nodes = reader.sequence(keys["frequencies_hz"], "the frequencies")
        frequencies = [(n, reader.number(n, "a frequency", "Hz", maximum=MAX_FREQUENCY_HZ))
                       for n in frequency_nodes]
    else:
        frequencies = [(adapted[0], value) for value in adapted[1]]
        if adapted[1][-1] > MAX_FREQUENCY_HZ:
            raise reader.error(adapted[0], f"expected frequencies of at most {MAX_FREQUENCY_HZ} "
                                           f"Hz, found {float(adapted[1][-1]):g}")
    if len(pin_nodes) * len(frequencies) > MAX_TRIALS:
        raise reader.error(
            keys.get("frequencies_hz", node),
            f"expected at most {MAX_TRIALS:,} conditions (pins x frequencies), found "
            f"{len(pin_nodes)} x {len(frequencies)}",
        )
    conditions: list[Condition] = []
    slots: list[int] = []
    for frequency_node, frequency in frequencies:
        train = stimulus.train.with_frequency(frequency)
        if isinstance(stimulus.train, TrainShape):  # a train with a frequency was checked alone
            check_period(reader, frequency_node, frequency_node, train)
        _check_pulses(reader, frequency_node, pulse_slots(train), long_trials)
        check_train_on_pins(reader, frequency_node, train, pins, device)
        conditions.extend(LocalisationCondition(stimulus.name, pin, frequency) for pin in pins)
        slots.extend(pulse_slots(train) for _ in pins)
    return tuple(conditions), tuple(slots)


def _check_shapes_completed(reader: Reader, section: _Section, paradigm: Paradigm) -> None:
    """Every train without a frequency is the stimulus of a localisation design that gives one."""
    completed = None
    if paradigm is Paradigm.LOCALISATION and "stimulus" in section.keys:
        completed = section.keys["stimulus"].value  # the name itself is checked with the design
    for stimulus in section.by_name.values():
        if (isinstance(stimulus, TrainStimulus) and isinstance(stimulus.train, TrainShape)
                and stimulus.name != completed):
            reader.error(
                section.declared.get(stimulus.name, section.node),
                f"expected a frequency_hz in train {stimulus.name!r}, found none: only the "
                "stimulus of a localisation design may leave it to the design's frequencies_hz",
            )


def _motion(reader: Reader, section: _Section) -> _Conditions:
    node, keys, _, by_name, declared, long_trials, _ = section
    if "configurations" not in keys:
        raise reader.error(
            node,
            "an apparent_motion design needs a 'configurations' key (wave stimuli), found none",
        )
    items = reader.sequence(keys["configurations"], "the configurations")
    if len(items) > MAX_TRIALS:
        raise reader.error(
            keys["configurations"],
            f"expected at most {MAX_TRIALS:,} configurations, found {len(items):,}",
        )
    conditions: list[Condition] = []
    slots: list[int] = []
    for item in items:
        stimulus = stimulus_named(reader, item, by_name, declared, WaveStimulus)
        wave = stimulus.wave
        count = sum(pulse_slots(drive.train) for drive in wave.drives())
        _check_pulses(reader, item, count, long_trials)
        conditions.append(wave_condition(stimulus))
        slots.append(count)
    return tuple(conditions), tuple(slots)


def wave_condition(stimulus: WaveStimulus) -> MotionCondition:
    """What a trial presenting the wave ``stimulus`` is."""
    wave = stimulus.wave
    match wave:
        case Wave():
            return MotionCondition(stimulus.name, wave.kind, wave.direction, wave.row)
        case PathWave():
            return MotionCondition(stimulus.name, wave.kind, wave.direction, None, wave.pins)
    raise AssertionError(wave)


def _check_pulses(reader: Reader, node: Node, count: int, long_trials: bool) -> None:
    if long_trials and count > MAX_PULSES:
        raise reader.error(
            node,
            f"expected at most {MAX_PULSES:,} pulses in one trial written to a file, found "
            f"{count:,} (frequency x pulses per cycle x signal length, for each pin); shorten "
            "the signal",
        )
    if not long_trials and count > MAX_PULSES_PER_TRIAL:
        raise reader.error(
            node,
            f"expected at most {MAX_PULSES_PER_TRIAL:,} pulses in one trial, found {count:,} "
            "(frequency x pulses per cycle x signal length, for each pin); shorten the signal, "
            "or, to write a longer schedule to a file, use pinarray compile --allow-long",
        )


def _constraints(reader: Reader, node: Node, paradigm: Paradigm) -> Constraints:
    keys = reader.mapping(node, {"no_repeat", "max_run"}, what="constraints")
    no_repeat: tuple[str, ...] = ()
    if "no_repeat" in keys:
        no_repeat = tuple(
            _attribute(reader, n, "an attribute that may not repeat", paradigm)
            for n in reader.sequence(keys["no_repeat"], "no_repeat")
        )
    max_run: list[tuple[str, int]] = []
    if "max_run" in keys:
        for key_node, value_node in reader.items(keys["max_run"], "max_run"):
            attribute = _attribute(reader, key_node, "an attribute", paradigm)
            max_run.append(
                (attribute, reader.integer(value_node, f"the longest run of equal {attribute}", 1))
            )
    return Constraints(no_repeat, tuple(max_run))


def _attribute(reader: Reader, node: Node, what: str, paradigm: Paradigm) -> str:
    """An attribute the paradigm's trials have (a constraint on another could never hold)."""
    attribute = reader.string(node, what, CONDITION_ATTRIBUTES)
    have = ATTRIBUTES_OF[paradigm]
    if attribute not in have:
        raise reader.error(node, f"expected an attribute {paradigm.value} trials have "
                                 f"({', '.join(have)}), found {attribute!r}")
    return attribute


def ordering_problem(design: Design) -> str | None:
    """Why the design's constraints cannot be met, or None. Counts only: never a hang."""
    limits = design.constraints.limits()
    if not limits or not design.conditions:
        return None
    if design.ordering in (Ordering.SEQUENTIAL, Ordering.LATIN_SQUARE):
        return (
            f"order constraints ({', '.join(limits)}) need a random order; "
            f"'{design.ordering.value}' fixes the order itself"
        )
    main_trials = len(design.conditions) * design.repetitions * design.blocks
    if main_trials * len(design.conditions) > MAX_SHUFFLE_WORK:
        return (
            f"expected order constraints over at most {MAX_SHUFFLE_WORK:,} trials x conditions "
            f"(the work of ordering them), found {main_trials:,} trials x "
            f"{len(design.conditions):,} conditions; constrain fewer conditions or trials"
        )
    # Trials shuffled together: one block's, or every block's with full_random.
    copies = design.repetitions * (design.blocks if design.ordering is Ordering.FULL_RANDOM else 1)
    size = len(design.conditions) * copies
    for attribute, limit in limits.items():
        counts: Counter = Counter()
        for condition in design.conditions:
            counts[condition_value(condition, attribute)] += copies
        value, count = counts.most_common(1)[0]
        # `count` equal values need `count / limit` runs separated by at least one other trial.
        if count > limit * (size - count + 1):
            others = size - count
            return (
                f"impossible order constraint: {attribute} {value} appears {count} times among "
                f"{size} trials, but with runs of at most {limit} the other {others} trials can "
                f"separate at most {limit * (others + 1)}"
            )
    return None
