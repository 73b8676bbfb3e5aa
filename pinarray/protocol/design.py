"""The ``design`` section: conditions, blocks and ordering, checked to be playable and bounded.

A design names its paradigm (``paradigm:``), whose room reads its conditions
(`pinarray.protocol.seam.ParadigmDesign.read`); blocks, order, constraints, pauses, practice
and the adaptive procedures are every design's, read here. Every condition is then checked as
it would play, whatever its paradigm (`pinarray.protocol.seam.check_conditions`).

A design is refused at validation when its plan could not be drawn (an impossible ordering
constraint) or would not fit in a bounded time and memory: at most `MAX_TRIALS` trials, at
most `MAX_PULSES_PER_TRIAL` pulse slots in one trial (what a trial may play) and `MAX_PULSES` in
the whole plan (what `pinarray compile` writes and holds in memory). A design read for a file
only (``long_trials``: ``pinarray compile --allow-long``) may put the whole plan's pulses in one
trial. Pure Python: `pinarray validate` runs it without numpy.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from functools import partial
from typing import TYPE_CHECKING

from yaml import MappingNode, ScalarNode

from pinarray import registry
from pinarray.errors import PinArrayError
from pinarray.protocol.adaptive_design import (
    adaptive_keys,
    read_adaptive,
    read_parameter,
    read_values,
)
from pinarray.protocol.device import whole_ns
from pinarray.protocol.model import (
    NS_PER_S,
    Constraints,
    Design,
    Device,
    Ordering,
    Stimulus,
    TrainShape,
    TrainStimulus,
    condition_value,
)
from pinarray.protocol.procedures import Parameter
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader, close_match, describe

if TYPE_CHECKING:
    from pinarray.protocol.seam import Adapting, DesignSection, ParadigmDesign, Rehearse

MAX_TRIALS = 20_000
MAX_PULSES_PER_TRIAL = 1_000_000
MAX_PULSES = 10_000_000
# Ordering under constraints weighs every distinct condition at each trial placed: trials x
# conditions is the work, about 0.2 us each here (a few seconds at most).
MAX_SHUFFLE_WORK = 20_000_000
# Keys every design may have, whatever its paradigm (its room reads the rest).
COMMON_KEYS = frozenset({"paradigm", "repetitions", "blocks", "order", "constraints", "seed",
                         "inter_trial_interval_s", "practice_trials", "adaptive"})
# What an adaptive design's procedures decide instead.
FIXED_ONLY = ("repetitions", "blocks", "order", "constraints")


def read_design(
    reader: Reader,
    node: Node,
    device: Device,
    stimuli: Sequence[Stimulus],
    declared: Mapping[str, Node],
    long_trials: bool = False,
    rehearse: Rehearse | None = None,
) -> Design:
    """The design, checked against the device and stimuli; ``declared`` names every stimulus
    written in the file, broken ones included (their problems are already reported).

    ``long_trials``: the design is compiled to a file, never played, so one trial may hold
    more than `MAX_PULSES_PER_TRIAL` pulses (up to the plan's `MAX_PULSES`). ``rehearse``:
    every condition is also played on the model it stands for (`check_conditions`).
    """
    from pinarray.protocol.seam import DesignSection, check_conditions

    paradigm = _paradigm(reader, node)
    keys = _keys(reader, node, paradigm)
    by_name = {s.name: s for s in stimuli}
    adapting = None
    if "adaptive" in keys:
        adapting = reader.attempt(lambda: _adapting(reader, keys, keys["adaptive"], paradigm,
                                                    device), None)
        if adapting is None:
            raise Invalid("adaptive")
    section = DesignSection(reader, node, keys, device, by_name, declared, adapting)
    found = reader.attempt(lambda: paradigm.read(section), None)
    # An adaptive design's trials play its conditions at its values (practice at the easiest),
    # never as written (a stroke_steps design never plays the calibration's full stroke):
    # each value is rehearsed on each condition (`read_adaptive`), the conditions as written
    # are not.
    read = None if found is None else reader.attempt(lambda: check_conditions(
        reader, found, device, by_name, paradigm,
        partial(check_trial_pulses, reader, long_trials=long_trials),
        rehearse if adapting is None else None), None)
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
    iti_ns = reader.optional(
        keys, "inter_trial_interval_s",
        lambda n: whole_ns(reader, n, reader.number(n, "the inter-trial interval", "s",
                                                    allow_zero=True, maximum=3600),
                           NS_PER_S, "the inter-trial interval", "s"),
        2 * NS_PER_S,
    )
    practice = reader.optional(
        keys, "practice_trials", lambda n: reader.integer(n, "practice trials", 0, 100), 0
    )
    if found is None or read is None or not read[0]:
        # Their problems are already recorded (a design holds at least one condition, so none
        # left means every one was wrong).
        raise Invalid("conditions")
    conditions, slots = read
    adaptive = None
    if adapting is not None:
        conditions = tuple(dict.fromkeys(conditions))
        slots = (max(slots, default=0),) * len(conditions)
        adaptive = read_adaptive(reader, adaptive_keys(reader, keys["adaptive"]), paradigm,
                                 device, adapting.parameter, adapting.values, conditions,
                                 by_name, rehearse)
    design = Design(
        paradigm,
        conditions,
        repetitions,
        blocks,
        ordering,
        constraints,
        seed,
        iti_ns,
        practice,
        adaptive,
        found.judgement,
    )
    _check_size(reader, node, design, slots)
    problem = ordering_problem(design)
    if problem:
        raise reader.error(keys.get("constraints", node), problem)
    return design


def _paradigm(reader: Reader, node: Node) -> ParadigmDesign:
    """The design's paradigm, read before its other keys (which keys it has depends on it)."""
    from pinarray.protocol.seam import paradigm_named

    if not isinstance(node, MappingNode):
        raise reader.error(node, f"expected a mapping for the design, found {describe(node)}")
    for key_node, value_node in node.value:
        if isinstance(key_node, ScalarNode) and key_node.value == "paradigm":
            name = reader.string(value_node, "the paradigm")
            if not registry.is_known(name):
                if any(plug_in.name == name for plug_in in registry.ignored()):
                    raise reader.error(value_node, registry.why_not(name))  # and why not
                reader.string(value_node, "the paradigm", registry.names())  # says which
            try:
                return paradigm_named(name)
            except PinArrayError as problem:
                raise reader.error(value_node, str(problem)) from None
    raise reader.error(node, "expected a 'paradigm' key in the design, found none")


def _keys(reader: Reader, node: Node, paradigm: ParadigmDesign) -> dict[str, Node]:
    """The design's keys: every design's and its paradigm's; a misspelt one is named with a
    hint (and left out), a key its paradigm does not read is refused."""
    allowed = COMMON_KEYS | paradigm.keys
    written = [str(k.value) for k, _ in node.value if isinstance(k, ScalarNode)]
    strays = {k for k in written if k not in allowed and not close_match(k, sorted(allowed))}
    keys = reader.mapping(node, set(allowed | strays), {"paradigm"}, "design")
    for key in [k for k in keys if k in strays]:
        reader.error(keys.pop(key), f"expected the keys of {paradigm.name} designs "
                                    f"({', '.join(sorted(paradigm.keys))} beside every "
                                    f"design's), found {key!r}")
    return keys


def _adapting(reader: Reader, keys: Mapping[str, Node], node: Node, paradigm: ParadigmDesign,
              device: Device) -> Adapting:
    """An adaptive design's parameter and values (read before its conditions: a design may
    take its conditions' values from them)."""
    from pinarray.protocol.seam import Adapting

    if not paradigm.parameters:
        article = "an" if paradigm.name[0] in "aeiou" else "a"
        raise reader.error(node, f"expected no 'adaptive' in {article} {paradigm.name} design "
                                 "(it has no intensity to adapt), found one")
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
    return Adapting(parameter, read_values(reader, adaptive, parameter), adaptive["values"])


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


def _check_shapes_completed(reader: Reader, section: DesignSection,
                            paradigm: ParadigmDesign) -> None:
    """Every train without a frequency is the stimulus of a design that gives it one."""
    completed = paradigm.completes(section)  # the name itself is checked with the design
    for stimulus in section.stimuli.values():
        if (isinstance(stimulus, TrainStimulus) and isinstance(stimulus.train, TrainShape)
                and stimulus.name != completed):
            reader.error(
                section.declared.get(stimulus.name, section.node),
                f"expected a frequency_hz in train {stimulus.name!r}, found none: only the "
                "stimulus of a localisation design may leave it to the design's frequencies_hz",
            )


# What a trial of too many pulses can do instead, in a protocol (its default) and in code.
LONGER_IN_A_FILE = "or, to write a longer schedule to a file, use pinarray compile --allow-long"
LONGER_IN_CODE = "or present it as several shorter stimuli, one after another"


def check_trial_pulses(reader: Reader, node: Node, count: int, *, long_trials: bool,
                       longer: str = LONGER_IN_A_FILE) -> None:
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
            f"(frequency x pulses per cycle x signal length, for each pin); shorten the signal, "
            f"{longer}",
        )


def _constraints(reader: Reader, node: Node, paradigm: ParadigmDesign) -> Constraints:
    keys = reader.mapping(node, {"no_repeat", "max_run"}, what="constraints")
    no_repeat: tuple[str, ...] = ()
    if "no_repeat" in keys:
        for n in reader.sequence(keys["no_repeat"], "no_repeat"):
            attribute = _attribute(reader, n, "an attribute that may not repeat", paradigm)
            if attribute in no_repeat:
                raise reader.error(n, f"expected each attribute once in no_repeat, found "
                                      f"{attribute!r} again")
            no_repeat += (attribute,)
    max_run: list[tuple[str, int]] = []
    if "max_run" in keys:
        for key_node, value_node in reader.items(keys["max_run"], "max_run"):
            attribute = _attribute(reader, key_node, "an attribute", paradigm)
            max_run.append(
                (attribute, reader.integer(value_node, f"the longest run of equal {attribute}", 1))
            )
    return Constraints(no_repeat, tuple(max_run))


def _attribute(reader: Reader, node: Node, what: str, paradigm: ParadigmDesign) -> str:
    """An attribute the paradigm's trials have (a constraint on another could never hold)."""
    attribute = reader.string(node, what)
    have = paradigm.attributes
    if attribute not in have:
        raise reader.error(node, f"expected an attribute {paradigm.name} trials have "
                                 f"({', '.join(have)}), found {attribute!r}")
    return attribute


def ordering_problem(design: Design) -> str | None:
    """Why the design's constraints cannot be met, or None. Counts only: never a hang."""
    limits = design.constraints.limits()
    if not limits or not design.conditions:
        return None
    if design.ordering in (Ordering.SEQUENTIAL, Ordering.LATIN_SQUARE):
        return (
            f"expected a random order for order constraints ({', '.join(limits)}), found "
            f"'{design.ordering.value}', which fixes the order itself"
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
                f"expected order constraints a shuffle can meet, found {attribute} {value} on "
                f"{count} of the {size} trials shuffled together: with runs of at most {limit}, "
                f"the other {others} can separate at most {limit * (others + 1)}"
            )
    return None
