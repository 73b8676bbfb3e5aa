"""The ``stimuli`` section: pulse trains and waves, each checked against the device it plays on.

Patterns are read in `pinarray.protocol.patterns`, with the checks kept here (`check_drives`:
trains on their pins, no pin driven twice at once, the servo bus), so that every kind of
stimulus is judged by the same code. Past 400 lines on purpose: one section's reading and the
checks every stimulus shares; apart, a wave and a pattern could be judged differently.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from fractions import Fraction
from functools import lru_cache, partial
from typing import TypeVar

from pinarray.errors import PinArrayError
from pinarray.grid import Grid
from pinarray.protocol.bus import bus_problem
from pinarray.protocol.device import MS, read_pin, read_width_ns, whole_ns
from pinarray.protocol.drives import check_no_overlap
from pinarray.protocol.feasibility import check_train, shortest_lift_ns
from pinarray.protocol.model import (
    DIRECTION_NAME,
    DIRECTION_OF_WAVE,
    MAX_DIRECTION_CHARS,
    MIN_STROKE_STEPS,
    NS_PER_S,
    RESERVED_DIRECTION_NAMES,
    AnyWave,
    Device,
    Direction,
    PathWave,
    PatternStimulus,
    PinCalibration,
    PinDrive,
    ServoSettings,
    Stimulus,
    Train,
    TrainShape,
    TrainStimulus,
    Wave,
    WaveKind,
    WaveStimulus,
    exact_words,
)
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader, close_match, shown

MAX_DURATION_S = 48 * 3600
MAX_FREQUENCY_HZ = 1000
TRAIN_KEYS = {
    "frequency_hz",
    "duration_s",
    "pulses_per_cycle",
    "duty_cycle",
    "pulse_width_ms",
    "phase_deg",
}
WAVE_KEYS = {"wave", "row", "pins", "direction", "train", "soa_ms"}
ROW_WAVES = (WaveKind.RIGHTWARDS, WaveKind.LEFTWARDS, WaveKind.NONE)


def read_stimuli(
    reader: Reader, node: Node, device: Device | None
) -> tuple[tuple[Stimulus, ...], dict[str, Node]]:
    """The stimuli, and the node each name was declared at (broken ones included)."""
    stimuli: list[Stimulus] = []
    nodes: dict[str, Node] = {}
    none: list[tuple[Node, Node]] = []
    # Here, not at the top: patterns are read with this module's helpers.
    from pinarray.protocol.patterns import read_patterns

    pairs = reader.attempt(lambda: reader.items(node, "the stimuli"), none)
    trains: dict[str, Stimulus] = {}
    waves = []
    for key_node, value_node in pairs:
        name = reader.attempt(partial(reader.string, key_node, "a stimulus name"), None)
        if name is None:
            continue
        nodes[name] = value_node
        if stimulus_kind(value_node) is not TrainStimulus:
            waves.append((name, value_node))
            continue
        train = reader.attempt(partial(read_train, reader, value_node), None)
        if train is not None:
            trains[name] = TrainStimulus(name, train)
            stimuli.append(trains[name])
    declared_trains = {name: n for name, n in nodes.items()
                       if stimulus_kind(n) is TrainStimulus}
    for name, value_node in waves:
        if stimulus_kind(value_node) is not WaveStimulus:
            continue
        wave = reader.attempt(
            partial(read_wave, reader, value_node, device, trains, declared_trains), None
        )
        if wave is not None:
            stimuli.append(WaveStimulus(name, wave))
    stimuli.extend(read_patterns(reader, nodes, device, trains, declared_trains))
    if not pairs and not reader.errors:
        reader.error(node, "expected at least one stimulus, found none")
    return tuple(stimuli), nodes


def _has_key(node: Node, key: str) -> bool:
    return isinstance(node.value, list) and any(
        isinstance(pair, tuple) and getattr(pair[0], "value", None) == key for pair in node.value
    )


def is_wave(node: Node) -> bool:
    """A stimulus is a wave when its mapping has a ``wave`` key (trains have none)."""
    return _has_key(node, "wave")


def stimulus_kind(node: Node) -> type[Stimulus]:
    """What a stimulus's mapping declares: a wave (``wave:``), a pattern (``pattern:`` or
    ``frames:``) or else a pulse train."""
    if is_wave(node):
        return WaveStimulus
    if _has_key(node, "pattern") or _has_key(node, "frames"):
        return PatternStimulus
    return TrainStimulus


Kind = TypeVar("Kind", TrainStimulus, WaveStimulus, PatternStimulus)
KIND_NAMES = {TrainStimulus: "pulse train", WaveStimulus: "wave stimulus",
              PatternStimulus: "pattern"}


def stimulus_named(
    reader: Reader,
    node: Node,
    by_name: Mapping[str, Stimulus],
    declared: Mapping[str, Node],
    kind: type[Kind],
) -> Kind:
    """The pulse train (wave, pattern) named at ``node``; ``declared``: every name, broken
    ones too."""
    what = KIND_NAMES[kind]
    name = reader.string(node, f"the name of a {what}")
    stimulus = by_name.get(name)
    if stimulus is None and name in declared:
        raise Invalid(name)  # declared but broken: its own problem is already reported
    if not isinstance(stimulus, kind):
        # Those declared with problems of their own are still the names meant.
        names = sorted({s.name for s in by_name.values() if isinstance(s, kind)}
                       | {n for n, at in declared.items()
                          if n not in by_name and stimulus_kind(at) is kind})
        hint = close_match(name, names)
        known = (f"did you mean {hint[0]!r}?" if hint
                 else f"the stimuli section has {', '.join(names)}" if names
                 else "the stimuli section has none")
        raise reader.error(node, f"expected the name of a {what}, found {shown(name)}; {known}")
    return stimulus


def read_train(reader: Reader, node: Node) -> Train | TrainShape:
    """A train; one without ``frequency_hz`` is a shape a localisation design's frequencies
    complete (whether one does is checked with the design)."""
    required = {"duration_s"}
    # A key missing (or misspelt) still lets the rest of the train be checked in this pass.
    keys = reader.mapping(node, TRAIN_KEYS, required, "pulse train", stop_if_missing=False)
    with reader.section():
        frequency = reader.optional(
            keys, "frequency_hz",
            lambda n: reader.number(n, "the frequency", "Hz", maximum=MAX_FREQUENCY_HZ),
            Fraction(1),
        )
        duration = reader.optional(
            keys, "duration_s",
            lambda n: reader.number(n, "the signal length", "s", maximum=MAX_DURATION_S),
            Fraction(1),
        )
        per_cycle = reader.optional(
            keys, "pulses_per_cycle", lambda n: reader.integer(n, "pulses per cycle", 2, 1000), 10
        )
        duty = reader.optional(
            keys, "duty_cycle",
            lambda n: reader.number(n, "the duty cycle", "(fraction)", maximum=1),
            Fraction(1, 2),
        )
        up_ns, down_ns = reader.optional(
            keys, "pulse_width_ms", lambda n: _widths(reader, n), (2_000_000, 1_500_000)
        )
        phase_deg = reader.optional(
            keys, "phase_deg",
            lambda n: reader.number(
                n, "the phase", "deg", minimum=0, allow_zero=True, maximum=36000
            ),
            Fraction(0),
        )
    up_pulses = duty * per_cycle
    where = keys.get("duty_cycle", node)
    if up_pulses.denominator != 1:
        raise reader.error(
            where,
            f"expected a duty cycle that is a whole number of the {per_cycle} pulses per cycle, found {exact_words(duty)} ({exact_words(up_pulses)} pulses)",
        )
    if not 0 < up_pulses < per_cycle:
        raise reader.error(
            where,
            f"expected a duty cycle strictly between 0 and 1 (the pin must go up and come down), found {float(duty):g}",
        )
    if not required <= keys.keys():
        raise Invalid("a required key is missing (reported)")
    duration_ns = duration * NS_PER_S
    if duration_ns.denominator != 1:
        raise reader.error(
            keys["duration_s"],
            f"expected a signal length in whole nanoseconds, found {float(duration)} s",
        )
    shape = TrainShape(
        int(duration_ns), per_cycle, int(up_pulses), up_ns, down_ns, (phase_deg / 360) % 1
    )
    if "frequency_hz" not in keys:
        return shape
    train = shape.with_frequency(frequency)
    check_period(reader, keys.get("pulse_width_ms", keys["frequency_hz"]), keys["duration_s"],
                 train)
    return train


def check_period(reader: Reader, widths_node: Node, duration_node: Node, train: Train) -> None:
    """The train's pulses fit its pulse period, and its signal lasts at least one period."""
    check_widths_fit(reader, widths_node, train)
    if train.duration_ns < train.slot_ns:
        raise reader.error(
            duration_node,
            f"expected a signal length of at least one pulse period "
            f"({float(train.slot_ns) / 1e6:g} ms at {float(train.frequency_hz):g} Hz), "
            f"found {train.duration_ns / 1e6:g} ms",
        )
    if shortest_lift_ns(train) is None:  # the phase starts it down and it ends before a lift
        raise reader.error(
            duration_node,
            f"expected a signal that lifts the pin at least once, found none: its "
            f"{train.duration_ns / 1e6:g} ms end before its first up pulse (at "
            f"{float(train.frequency_hz):g} Hz, phase {float(train.phase * 360):g} deg)",
        )


def _widths(reader: Reader, node: Node) -> tuple[int, int]:
    widths = reader.mapping(node, {"up", "down"}, {"up", "down"}, "pulse widths")
    with reader.section():
        up_ns, down_ns = (reader.attempt(partial(read_width_ns, reader, widths[k]), 0)
                          for k in ("up", "down"))
    if up_ns == down_ns:  # one position: the pin would hold still, every trial "delivered"
        raise reader.error(node, "expected an up pulse width other than the down one (the pin "
                                 "must go up and come down), found both "
                                 f"{exact_words(Fraction(up_ns, 1_000_000))} ms")
    return up_ns, down_ns


def check_widths_fit(reader: Reader, node: Node, train: Train) -> None:
    """Both pulse widths fit the train's pulse period (a servo pulse cannot outlast its slot)."""
    slot_ns = train.slot_ns
    for label, width in (("up", train.up_width_ns), ("down", train.down_width_ns)):
        if width > slot_ns:
            raise reader.error(
                node,
                f"expected pulse widths within the pulse period, found the {label} pulse of "
                f"{width / 1e6:g} ms, which does not fit the {float(slot_ns) / 1e6:g} ms period of "
                f"{train.pulses_per_cycle} pulses per cycle at {float(train.frequency_hz):g} Hz",
            )


def check_train_on_pins(
    reader: Reader, node: Node, train: Train, pins: Collection[int], device: Device
) -> None:
    """``train`` fits its period and every pin of ``pins`` can follow it (or scales it).

    Whether a pin can follow is not judged on a device read with a misspelt key
    (`Reader.guessing`): the speed or stroke it would rest on may be a default.
    """
    check_widths_fit(reader, node, train)
    if reader.guessing:
        return
    for pin in pins:
        calibration = device.calibration(pin)
        try:
            check_stroke(reader, node, train, calibration, device)  # before its feasibility
            result = check_train(train, calibration, device)
        except PinArrayError as problem:  # a width the pin is not calibrated for, say
            raise reader.error(node, str(problem)) from None
        if not result.feasible and not device.scale_infeasible:
            raise reader.error(
                node,
                result.describe(device.servo, device.mm_per_step(pin))
                + "; lower the frequency or the stroke, or set device: feasibility: scale",
            )


def check_stroke(reader: Reader, node: Node, train: Train, calibration: PinCalibration,
                 device: Device) -> None:
    """The pin ``calibration`` describes moves under ``train``: its up and down widths at
    calibrated positions apart, on bus servos by at least `MIN_STROKE_STEPS` (a smaller stroke
    cannot be told from none in its read-back). Checked where a pin is used, not where it is
    calibrated: a pin no stimulus plays (a broken servo parked) may be calibrated flat."""
    up = calibration.position_for_width(train.up_width_ns)
    down = calibration.position_for_width(train.down_width_ns)
    bus = isinstance(device.servo, ServoSettings)
    least = MIN_STROKE_STEPS if bus else 1
    if abs(up - down) >= least:
        return
    unit = "steps" if bus else "us"
    why = (f"a pin counts as at its goal within {MIN_STROKE_STEPS - 1} steps: a smaller stroke "
           "cannot be told from none" if bus else "the pin must go up and come down")
    # Every pin calibrated alike: the device's calibration, said once for all of them.
    shared = all(p.positions_by_width_ns == calibration.positions_by_width_ns
                 for p in device.pins)
    whose = "the calibration" if shared else f"pin {calibration.pin}'s calibration"
    message = (f"expected a stroke of at least {least} {unit} ({why}), found "
               f"{abs(up - down)}: {whose} puts "
               f"{exact_words(Fraction(train.up_width_ns, 1_000_000))} ms at {up} {unit} and "
               f"{exact_words(Fraction(train.down_width_ns, 1_000_000))} ms at {down}; widen "
               "the pulse widths or the calibrated positions")
    if any(error.message == message for error in reader.errors):
        raise Invalid(message)  # one calibration's problem, said where it is first played
    raise reader.error(node, message)


def check_drives(reader: Reader, node: Node, drives: Sequence[PinDrive], device: Device,
                 what: str = "") -> None:
    """What one trial's ``drives`` ask of the device, reported at ``node`` (``what``: the
    stimulus, to begin the message): every train followed by its pins, no pin driven twice at
    once, and (bus servos) every frame of goal changes written and read back in time."""
    trains: dict[Train, list[int]] = {}
    for drive in drives:
        trains.setdefault(drive.train, []).append(drive.pin)
    for train, pins in trains.items():
        check_train_on_pins(reader, node, train, sorted(set(pins)), device)
    try:
        check_no_overlap(drives)
    except PinArrayError as problem:
        raise reader.error(node, what + str(problem)) from None
    check_bus(reader, node, drives, device, what)


def check_bus(reader: Reader, node: Node, drives: Sequence[PinDrive], device: Device,
              what: str = "") -> None:
    """On bus servos, every frame of the drives' goal changes is written and read back in
    time (`pinarray.protocol.bus`)."""
    if isinstance(device.servo, ServoSettings) and not reader.guessing:
        if _deliverable(_bus_shape(drives), device.servo, device.delivery_tolerance_ns):
            return
        problem = bus_problem(drives, device.servo, device.delivery_tolerance_ns)
        if problem is not None:
            raise reader.error(node, f"{what}the servo bus cannot deliver it: {problem}")


BusShape = tuple[tuple[Train, int, int], ...]


def _bus_shape(drives: Sequence[PinDrive]) -> BusShape:
    """What the bus check sees of ``drives``: each train, when it starts, and its pin by rank
    (which pins they are changes only the words of a problem, not whether there is one: the
    same train on each of a design's pins is checked once)."""
    rank = {pin: n for n, pin in enumerate(sorted({d.pin for d in drives}), start=1)}
    return tuple(sorted(((d.train, d.delay_ns, rank[d.pin]) for d in drives),
                        key=lambda item: (item[1], item[2])))


@lru_cache(maxsize=4096)
def _deliverable(shape: BusShape, servo: ServoSettings, tolerance_ns: int) -> bool:
    return bus_problem([PinDrive(pin, train, delay) for train, delay, pin in shape], servo,
                       tolerance_ns) is None


def read_wave(
    reader: Reader,
    node: Node,
    device: Device | None,
    trains: Mapping[str, Stimulus],
    declared_trains: Mapping[str, Node],
) -> AnyWave:
    keys = reader.mapping(node, WAVE_KEYS, {"wave", "train"}, "wave")
    kind = WaveKind(reader.string(keys["wave"], "the wave", tuple(k.value for k in WaveKind)))
    grid = device.grid if device else Grid()
    if kind in ROW_WAVES:
        if "direction" in keys:
            raise reader.error(
                keys["direction"],
                f"expected no 'direction' for a {kind.value} wave (it goes "
                f"{DIRECTION_OF_WAVE[kind].value}), found one; name a direction with 'wave: "
                "sequence'",
            )
        if "row" not in keys:
            raise reader.error(node, f"a {kind.value} wave runs along a row: expected a 'row' "
                                     "key, found none")
        pins, row = _row_pins(reader, keys, kind, grid)
    else:
        if "row" in keys:
            raise reader.error(
                keys["row"],
                f"expected no 'row' for a {kind.value} wave, found one: it visits its 'pins' in "
                "the order listed",
            )
        pins = _path_pins(reader, node, keys, kind, grid)
        direction = _path_direction(reader, node, keys, kind)
    stimulus = stimulus_named(reader, keys["train"], trains, declared_trains, TrainStimulus)
    train = stimulus.train
    if not isinstance(train, Train):
        raise reader.error(
            keys["train"],
            f"expected a train with a frequency_hz for a wave, found train {stimulus.name!r} "
            "without one (only a localisation design's frequencies_hz complete such a train)",
        )
    with reader.section():
        soa_ns = reader.optional(
            keys, "soa_ms",
            lambda n: whole_ns(reader, n, reader.number(
                n, "the SOA", "ms", maximum=60_000, minimum=0, allow_zero=True
            ), MS, "the SOA", "ms"),
            # Tactile Brush (Israr & Poupyrev): SOA = 0.32 x duration + 47.3 ms.
            round(Fraction(32, 100) * train.duration_ns + Fraction(473, 10) * MS),
        )
    wave: AnyWave = (Wave(kind, row, pins, train, soa_ns) if kind in ROW_WAVES
                     else PathWave(kind, direction, pins, train, soa_ns))
    if device is not None:
        # What a localisation train gets checked for, each pin of the wave gets too.
        check_train_on_pins(reader, keys["train"], train, pins, device)
    try:
        check_no_overlap(wave.drives())
    except PinArrayError as problem:
        raise reader.error(keys.get("soa_ms", node), str(problem)) from None
    if device is not None:
        check_bus(reader, keys.get("soa_ms", node), wave.drives(), device)
    return wave


def _row_pins(
    reader: Reader, keys: Mapping[str, Node], kind: WaveKind, grid: Grid
) -> tuple[tuple[int, ...], int]:
    """(pins left to right, row) of a wave along a row."""
    row = reader.integer(keys["row"], "the row (1 = bottom)", 1, grid.rows)
    row_pins = grid.row_pins(row - 1)
    pins = row_pins
    if "pins" in keys:
        pins = tuple(
            read_pin(reader, n, grid) for n in reader.sequence(keys["pins"], "the wave's pins", 2)
        )
        strangers = [p for p in pins if p not in row_pins]
        if strangers:
            raise reader.error(
                keys["pins"],
                f"expected pins of row {row} ({', '.join(map(str, row_pins))}), found {', '.join(map(str, strangers))}",
            )
        if list(pins) != sorted(set(pins)):
            raise reader.error(
                keys["pins"],
                f"expected the row's pins left to right without repeats, found {list(pins)}",
            )
    if len(pins) < 2:
        raise reader.error(
            keys["row"], f"expected a row of at least 2 pins for a wave, found {len(pins)}"
        )
    if kind is WaveKind.NONE and len(pins) % 2 == 0:
        raise reader.error(
            keys.get("pins", keys["row"]),
            f"a no-wave alternates a central pin with its two lateral ones: expected an odd number of pins, found {len(pins)}; list them with 'pins:'",
        )
    return pins, row


def _path_pins(
    reader: Reader, node: Node, keys: Mapping[str, Node], kind: WaveKind, grid: Grid
) -> tuple[int, ...]:
    """The pins a column or sequence wave visits, in order: distinct, on the grid, and for
    upwards and downwards one column's, each above (below) the one before."""
    if "pins" not in keys:
        raise reader.error(node, f"a {kind.value} wave visits the pins listed: expected a "
                                 "'pins' key, found none")
    pins = tuple(
        read_pin(reader, n, grid) for n in reader.sequence(keys["pins"], "the wave's pins", 2)
    )
    repeated = sorted({p for p in pins if pins.count(p) > 1})
    if repeated:
        raise reader.error(
            keys["pins"],
            f"expected each pin of a wave once, found {', '.join(map(str, repeated))} more than "
            f"once in {list(pins)}",
        )
    if kind is WaveKind.SEQUENCE:
        return pins
    up = kind is WaveKind.UPWARDS
    cells = [grid.cell(p) for p in pins]
    rows = [r for r, _ in cells]
    if len({c for _, c in cells}) == 1 and rows == sorted(rows, reverse=not up):
        return pins
    raise reader.error(
        keys["pins"],
        f"expected the pins of a{'n' if up else ''} {kind.value} wave to go {'up' if up else 'down'} one "
        f"column ({'bottom to top' if up else 'top to bottom'}), found {list(pins)}: "
        f"{path_text(grid, pins)}",
    )


def path_text(grid: Grid, pins: tuple[int, ...]) -> str:
    """What a sequence of pins does on the grid, as the lab would say it."""
    cells = [grid.cell(p) for p in pins]
    rows, columns = [r for r, _ in cells], [c for _, c in cells]
    if len(set(rows)) == 1:
        way = ("rightwards" if columns == sorted(columns)
               else "leftwards" if columns == sorted(columns, reverse=True) else "back and forth")
        return f"they run {way} along row {rows[0] + 1}"
    if len(set(columns)) == 1:
        way = ("go up" if rows == sorted(rows)
               else "go down" if rows == sorted(rows, reverse=True) else "go up and down")
        return f"they {way} column {columns[0] + 1}"
    stray = next(p for p, c in zip(pins, columns, strict=True) if c != columns[0])
    return (f"they leave column {columns[0] + 1} (pin {pins[0]}): pin {stray} is in column "
            f"{grid.cell(stray)[1] + 1}")


def _path_direction(
    reader: Reader, node: Node, keys: Mapping[str, Node], kind: WaveKind
) -> Direction:
    """The direction a subject names: up or down for a column, the declared one for a sequence."""
    if kind is not WaveKind.SEQUENCE:
        if "direction" in keys:
            raise reader.error(
                keys["direction"],
                f"expected no 'direction' for a {kind.value} wave (it goes "
                f"{DIRECTION_OF_WAVE[kind].value}), found one; name a direction with 'wave: "
                "sequence'",
            )
        return DIRECTION_OF_WAVE[kind]
    if "direction" not in keys:
        raise reader.error(node, "a sequence wave names the direction a subject would answer: "
                                 "expected a 'direction' key (e.g. up-right), found none")
    name = reader.string(keys["direction"], "the direction")
    reserved = RESERVED_DIRECTION_NAMES
    if (name in reserved or len(name) > MAX_DIRECTION_CHARS
            or DIRECTION_NAME.fullmatch(name) is None):
        raise reader.error(
            keys["direction"],
            f"expected a direction of lowercase words joined by hyphens (e.g. up-right), at most "
            f"{MAX_DIRECTION_CHARS} characters and neither none nor unsure (answers of their "
            f"own), found {shown(name)}",
        )
    return Direction(name)
