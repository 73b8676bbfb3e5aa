"""Protocol files: YAML text -> a validated, frozen `Protocol`, or every problem at file:line:col.

The schema is documented for lab members in ``protocols/README.md``.
"""

from __future__ import annotations

import hashlib
from fractions import Fraction
from pathlib import Path

from pinarray.drives import check_no_overlap
from pinarray.errors import PinArrayError, ProtocolError, ProtocolErrors
from pinarray.feasibility import Feasibility, check_train
from pinarray.grid import Grid
from pinarray.protocol import (
    BAUD_RATES,
    NS_PER_S,
    Condition,
    Constraints,
    Design,
    Device,
    Ordering,
    Paradigm,
    PinCalibration,
    Protocol,
    ServoSettings,
    Stimulus,
    Train,
    Wave,
    WaveKind,
)
from pinarray.yaml_nodes import Invalid, Node, Reader

MS = Fraction(1_000_000)  # ns per ms
MAX_DURATION_S = 48 * 3600
MAX_FREQUENCY_HZ = 1000
CONDITION_ATTRIBUTES = ("pin", "frequency_hz", "stimulus", "direction")


def load_protocol(path: str | Path) -> Protocol:
    """Read and validate a protocol file; raise `ProtocolErrors` listing every problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PinArrayError(f"{path}: no such protocol file") from None
    except (OSError, UnicodeDecodeError) as problem:
        raise PinArrayError(f"{path}: cannot read the protocol: {problem}") from None
    return parse_protocol(text, str(path))


def parse_protocol(text: str, source: str = "<protocol>") -> Protocol:
    reader = Reader(source)
    root = reader.compose(text)
    top = reader.attempt(
        lambda: reader.mapping(
            root,
            {"protocol", "description", "device", "stimuli", "design"},
            {"protocol", "stimuli", "design"},
            "protocol",
        ),
        {},
    )
    name = (
        reader.attempt(lambda: reader.string(top["protocol"], "the protocol name"), "")
        if "protocol" in top
        else ""
    )
    description = (
        reader.attempt(lambda: reader.string(top["description"], "the description"), "")
        if "description" in top
        else ""
    )
    device = _device(reader, top.get("device"))
    stimuli, stimulus_nodes = (
        _stimuli(reader, top["stimuli"], device) if "stimuli" in top else ((), {})
    )
    design = (
        reader.attempt(lambda: _design(reader, top["design"], device, stimuli, stimulus_nodes))
        if "design" in top and device
        else None
    )
    reader.raise_if_errors()
    assert device is not None and design is not None
    return Protocol(
        name,
        description,
        device,
        stimuli,
        design,
        source,
        hashlib.sha256(text.encode("utf-8")).hexdigest(),
    )


# -- device ------------------------------------------------------------------------------------

DEFAULT_POSITIONS = ((1_500_000, 2048), (2_000_000, 2162))


def _device(reader: Reader, node: Node | None) -> Device | None:
    if node is None:
        return _pin_calibrations(reader, Grid(), ServoSettings(), {})
    keys = reader.attempt(
        lambda: reader.mapping(
            node,
            {"grid", "port", "servo", "calibration", "pins", "servo_ids", "feasibility",
             "delivery_tolerance_ms"},
            what="device section",
        ),
        None,
    )
    if keys is None:
        return None
    grid = reader.attempt(lambda: _grid(reader, keys["grid"]), None) if "grid" in keys else Grid()
    servo = (
        reader.attempt(lambda: _servo(reader, keys["servo"]), None)
        if "servo" in keys
        else ServoSettings()
    )
    if grid is None or servo is None:
        return None
    port = (
        reader.attempt(lambda: reader.string(keys["port"], "the port"), "sim://")
        if "port" in keys
        else "sim://"
    )
    scale = False
    if "feasibility" in keys:
        scale = (
            reader.attempt(
                lambda: reader.string(keys["feasibility"], "feasibility", ("reject", "scale")),
                "reject",
            )
            == "scale"
        )
    tolerance_ns = Device.delivery_tolerance_ns
    if "delivery_tolerance_ms" in keys:
        tolerance_ms = reader.attempt(
            lambda: reader.number(keys["delivery_tolerance_ms"], "the delivery tolerance", "ms",
                                  maximum=10_000),
            None,
        )
        if tolerance_ms is not None:
            tolerance_ns = round(tolerance_ms * 1_000_000)
    base = (
        reader.attempt(lambda: _calibration_fields(reader, keys["calibration"], "calibration"), {})
        if "calibration" in keys
        else {}
    )
    overrides: dict[int, dict] = {}
    if "pins" in keys:
        for key_node, value_node in reader.attempt(
            lambda: reader.items(keys["pins"], "the per-pin calibration"), []
        ):
            pin = reader.attempt(lambda k=key_node: _pin(reader, k, grid), None)
            fields = reader.attempt(
                lambda v=value_node: _calibration_fields(reader, v, "pin calibration"), None
            )
            if pin is not None and fields is not None:
                overrides[pin] = fields
    ids: dict[int, tuple[int, Node]] = {}
    if "servo_ids" in keys:
        for key_node, value_node in reader.attempt(
            lambda: reader.items(keys["servo_ids"], "servo_ids"), []
        ):
            pin = reader.attempt(lambda k=key_node: _pin(reader, k, grid), None)
            servo_id = reader.attempt(
                lambda v=value_node: reader.integer(v, "a servo id", 0, 253), None
            )
            if pin is not None and servo_id is not None:
                ids[pin] = (servo_id, value_node)
    device = _pin_calibrations(reader, grid, servo, base, overrides, ids, keys.get("servo_ids"))
    if device is None:
        return None
    return Device(device.grid, device.servo, device.pins, port, scale, tolerance_ns)


def _grid(reader: Reader, node: Node) -> Grid:
    keys = reader.mapping(node, {"rows", "columns", "pitch_mm"}, what="grid")
    rows = reader.integer(keys["rows"], "rows", 1, 64) if "rows" in keys else 4
    columns = reader.integer(keys["columns"], "columns", 1, 64) if "columns" in keys else 4
    pitch = (
        float(reader.number(keys["pitch_mm"], "the pitch", "mm", maximum=100))
        if "pitch_mm" in keys
        else 2.0
    )
    return Grid(rows, columns, pitch)


def _servo(reader: Reader, node: Node) -> ServoSettings:
    keys = reader.mapping(
        node,
        {"model", "baud_rate", "speed_steps_per_s", "acceleration", "steps_per_turn"},
        what="servo section",
    )
    d = ServoSettings()
    model = (
        reader.string(keys["model"], "the servo model", ("STS3215",))
        if "model" in keys
        else d.model
    )
    baud = d.baud_rate
    if "baud_rate" in keys:
        baud = reader.integer(keys["baud_rate"], "the baud rate")
        if baud not in BAUD_RATES:
            raise reader.error(
                keys["baud_rate"],
                f"expected a baud rate the servos support ({', '.join(map(str, BAUD_RATES))}), found {baud}",
            )
    speed = (
        reader.integer(keys["speed_steps_per_s"], "the servo speed (steps/s)", 1, 10_000)
        if "speed_steps_per_s" in keys
        else d.speed_steps_per_s
    )
    accel = (
        reader.integer(
            keys["acceleration"],
            "the acceleration register (100 step/s^2 units, 0 = maximum)",
            0,
            254,
        )
        if "acceleration" in keys
        else d.acceleration_register
    )
    steps = (
        reader.integer(keys["steps_per_turn"], "steps per turn", 1, 1 << 16)
        if "steps_per_turn" in keys
        else d.steps_per_turn
    )
    return ServoSettings(model, baud, speed, accel, steps)


def _calibration_fields(reader: Reader, node: Node, what: str) -> dict:
    keys = reader.mapping(node, {"rest_steps", "positions", "limits_steps", "lever_mm"}, what=what)
    fields: dict = {}
    if "rest_steps" in keys:
        fields["rest_steps"] = (
            reader.integer(keys["rest_steps"], "the rest position (steps)", 0, 4095),
            keys["rest_steps"],
        )
    if "positions" in keys:
        positions = []
        for width_node, position_node in reader.items(
            keys["positions"], "positions (pulse width in ms: steps)"
        ):
            width = reader.attempt(
                lambda w=width_node: reader.number(w, "a pulse width", "ms", maximum=100), None
            )
            position = reader.attempt(
                lambda p=position_node: reader.integer(p, "a position (steps)", 0, 4095), None
            )
            if width is not None and position is not None:
                width_ns = width * MS
                if width_ns.denominator != 1:
                    reader.error(
                        width_node,
                        f"expected a pulse width in whole nanoseconds, found {float(width)} ms",
                    )
                    continue
                positions.append((int(width_ns), position, position_node))
        fields["positions"] = tuple(positions)
    if "limits_steps" in keys:
        items = reader.sequence(keys["limits_steps"], "the limits [min, max] in steps", 2)
        if len(items) != 2:
            raise reader.error(
                keys["limits_steps"],
                f"expected two limits [min, max] in steps, found {len(items)} values",
            )
        low, high = (reader.integer(n, "a limit (steps)", 0, 4095) for n in items)
        if low >= high:
            raise reader.error(
                keys["limits_steps"],
                f"expected limits [min, max] with min < max, found [{low}, {high}]",
            )
        fields["limits"] = ((low, high), keys["limits_steps"])
    if "lever_mm" in keys:
        fields["lever_mm"] = float(
            reader.number(keys["lever_mm"], "the lever length", "mm", maximum=1000)
        )
    return fields


def _pin_calibrations(
    reader: Reader,
    grid: Grid,
    servo: ServoSettings,
    base: dict,
    overrides: dict | None = None,
    ids: dict | None = None,
    ids_node: Node | None = None,
) -> Device | None:
    """One calibration per pin: the shared one, overridden per pin; every position in limits."""
    overrides = overrides or {}
    ids = ids or {}
    pins = []
    ok = True
    for pin in grid.pins:
        fields = {**base, **overrides.get(pin, {})}
        positions = fields.get("positions") or tuple((w, p, None) for w, p in DEFAULT_POSITIONS)
        rest, rest_node = fields.get("rest_steps", (positions[0][1], None))
        # Without explicit limits a pin may go exactly where it is calibrated to go, no further.
        span = [p for _, p, _ in positions] + [rest]
        (low, high), limits_node = fields.get("limits", ((min(span), max(span)), None))
        checks = [(position, node, "position") for _, position, node in positions] + [
            (rest, rest_node, "rest position")
        ]
        for position, node, what in checks:
            if not low <= position <= high:
                reader.error(
                    node or limits_node,
                    f"pin {pin}: {what} {position} steps is outside its limits [{low}, {high}]",
                )
                ok = False
        servo_id = ids.get(pin, (pin, None))[0]
        pins.append(
            PinCalibration(
                pin,
                servo_id,
                rest,
                low,
                high,
                tuple((w, p) for w, p, _ in positions),
                fields.get("lever_mm", 6.0),
            )
        )
    seen: dict[int, int] = {}
    for calibration in pins:
        if calibration.servo_id in seen:
            node = ids.get(calibration.pin, (0, ids_node))[1]
            reader.error(
                node,
                f"servo id {calibration.servo_id} drives both pin {seen[calibration.servo_id]} and pin {calibration.pin}",
            )
            ok = False
        seen[calibration.servo_id] = calibration.pin
    return Device(grid, servo, tuple(pins)) if ok else None


def _pin(reader: Reader, node: Node, grid: Grid) -> int:
    pin = reader.integer(node, "a pin number")
    if not 1 <= pin <= grid.pin_count:
        raise reader.error(
            node,
            f"expected a pin from 1 to {grid.pin_count} on the {grid.rows}x{grid.columns} grid, found {pin}",
        )
    return pin


# -- stimuli -----------------------------------------------------------------------------------

TRAIN_KEYS = {
    "frequency_hz",
    "duration_s",
    "pulses_per_cycle",
    "duty_cycle",
    "pulse_width_ms",
    "phase_deg",
}
WAVE_KEYS = {"wave", "row", "pins", "train", "soa_ms"}


def _stimuli(reader: Reader, node: Node, device: Device | None):
    stimuli: list[Stimulus] = []
    nodes: dict[str, Node] = {}
    pairs = reader.attempt(lambda: reader.items(node, "the stimuli"), [])
    trains: dict[str, Train] = {}
    waves = []
    for key_node, value_node in pairs:
        name = reader.attempt(lambda k=key_node: reader.string(k, "a stimulus name"), None)
        if name is None:
            continue
        nodes[name] = value_node
        if _is_wave(value_node):
            waves.append((name, value_node))
            continue
        train = reader.attempt(lambda v=value_node: _train(reader, v))
        if train is not None:
            trains[name] = train
            stimuli.append(Stimulus(name, train=train))
    for name, value_node in waves:
        wave = reader.attempt(lambda v=value_node: _wave(reader, v, device, trains, nodes))
        if wave is not None:
            stimuli.append(Stimulus(name, wave=wave))
    if not pairs and not reader.errors:
        reader.error(node, "expected at least one stimulus, found none")
    return tuple(stimuli), nodes


def _is_wave(node: Node) -> bool:
    """A stimulus is a wave when its mapping has a ``wave`` key (trains have none)."""
    return isinstance(node.value, list) and any(
        isinstance(pair, tuple) and getattr(pair[0], "value", None) == "wave" for pair in node.value
    )


def _train(reader: Reader, node: Node) -> Train:
    keys = reader.mapping(node, TRAIN_KEYS, {"frequency_hz", "duration_s"}, "pulse train")
    frequency = reader.number(keys["frequency_hz"], "the frequency", "Hz", maximum=MAX_FREQUENCY_HZ)
    duration = reader.number(keys["duration_s"], "the signal length", "s", maximum=MAX_DURATION_S)
    per_cycle = (
        reader.integer(keys["pulses_per_cycle"], "pulses per cycle", 2, 1000)
        if "pulses_per_cycle" in keys
        else 10
    )
    duty = (
        reader.number(keys["duty_cycle"], "the duty cycle", "(fraction)", maximum=1)
        if "duty_cycle" in keys
        else Fraction(1, 2)
    )
    up_pulses = duty * per_cycle
    where = keys.get("duty_cycle", node)
    if up_pulses.denominator != 1:
        raise reader.error(
            where,
            f"expected a duty cycle that is a whole number of the {per_cycle} pulses per cycle, found {float(duty):g} ({float(up_pulses):g} pulses)",
        )
    if not 0 < up_pulses < per_cycle:
        raise reader.error(
            where,
            f"expected a duty cycle strictly between 0 and 1 (the pin must go up and come down), found {float(duty):g}",
        )
    up_ns, down_ns = 2_000_000, 1_500_000
    if "pulse_width_ms" in keys:
        widths = reader.mapping(
            keys["pulse_width_ms"], {"up", "down"}, {"up", "down"}, "pulse widths"
        )
        up_ns, down_ns = (_width_ns(reader, widths[k]) for k in ("up", "down"))
    phase_deg = (
        reader.number(
            keys["phase_deg"], "the phase", "deg", minimum=0, allow_zero=True, maximum=36000
        )
        if "phase_deg" in keys
        else Fraction(0)
    )
    duration_ns = duration * NS_PER_S
    if duration_ns.denominator != 1:
        raise reader.error(
            keys["duration_s"],
            f"expected a signal length in whole nanoseconds, found {float(duration)} s",
        )
    train = Train(
        frequency,
        int(duration_ns),
        per_cycle,
        int(up_pulses),
        up_ns,
        down_ns,
        (phase_deg / 360) % 1,
    )
    slot_ns = train.slot_ns
    for label, width in (("up", up_ns), ("down", down_ns)):
        if width > slot_ns:
            where = keys.get("pulse_width_ms", keys["frequency_hz"])
            raise reader.error(
                where,
                f"expected pulse widths within the pulse period: the {label} pulse of "
                f"{width / 1e6:g} ms does not fit the {float(slot_ns) / 1e6:g} ms period of "
                f"{per_cycle} pulses per cycle at {float(frequency):g} Hz",
            )
    if duration_ns < train.slot_ns:
        raise reader.error(
            keys["duration_s"],
            f"expected a signal length of at least one pulse period ({float(slot_ns) / 1e6:g} ms), found {float(duration) * 1e3:g} ms",
        )
    return train


def _width_ns(reader: Reader, node: Node) -> int:
    width_ns = reader.number(node, "a pulse width", "ms", maximum=100) * MS
    if width_ns.denominator != 1:
        raise reader.error(node, "expected a pulse width in whole nanoseconds")
    return int(width_ns)


def _wave(
    reader: Reader, node: Node, device: Device | None, trains: dict[str, Train], nodes
) -> Wave:
    keys = reader.mapping(node, WAVE_KEYS, {"wave", "row", "train"}, "wave")
    kind = WaveKind(reader.string(keys["wave"], "the wave", tuple(k.value for k in WaveKind)))
    grid = device.grid if device else Grid()
    row = reader.integer(keys["row"], "the row (1 = bottom)", 1, grid.rows)
    row_pins = grid.row_pins(row - 1)
    pins = row_pins
    if "pins" in keys:
        pins = tuple(
            reader.integer(n, "a pin", 1, grid.pin_count)
            for n in reader.sequence(keys["pins"], "the wave's pins", 2)
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
    if kind is WaveKind.NONE and len(pins) % 2 == 0:
        raise reader.error(
            keys.get("pins", keys["row"]),
            f"a no-wave alternates a central pin with its two lateral ones: expected an odd number of pins, found {len(pins)}; list them with 'pins:'",
        )
    train_name = reader.string(keys["train"], "the train each pin plays")
    if train_name not in trains and train_name in nodes and nodes[train_name] is not node:
        if not _is_wave(nodes[train_name]):
            raise Invalid(train_name)  # a broken train, already reported
    if train_name not in trains:
        known = ", ".join(sorted(trains)) or "none"
        raise reader.error(
            keys["train"],
            f"expected the name of a pulse train stimulus ({known}), found {train_name!r}",
        )
    train = trains[train_name]
    if "soa_ms" in keys:
        soa = (
            reader.number(
                keys["soa_ms"], "the SOA", "ms", maximum=60_000, minimum=0, allow_zero=True
            )
            * MS
        )
    else:
        # Tactile Brush (Israr & Poupyrev): SOA = 0.32 x duration + 47.3 ms.
        soa = Fraction(32, 100) * train.duration_ns + Fraction(473, 10) * MS
    wave = Wave(kind, row, pins, train, round(soa))
    if device is not None:
        # What a localisation train gets checked for, each pin of the wave gets too.
        _check_train_on_pins(reader, keys["train"], train, pins, device)
    try:
        check_no_overlap(wave.drives())
    except PinArrayError as problem:
        raise reader.error(keys.get("soa_ms", node), str(problem)) from None
    return wave


# -- design ------------------------------------------------------------------------------------

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
}


def _design(reader: Reader, node: Node, device: Device, stimuli, stimulus_nodes) -> Design:
    keys = reader.mapping(node, DESIGN_KEYS, {"paradigm"}, "design")
    paradigm = Paradigm(
        reader.string(keys["paradigm"], "the paradigm", tuple(p.value for p in Paradigm))
    )
    by_name = {s.name: s for s in stimuli}
    read_conditions = _localisation if paradigm is Paradigm.LOCALISATION else _motion
    conditions = reader.attempt(
        lambda: read_conditions(reader, node, keys, device, by_name, stimulus_nodes)
    )

    def optional(key, read, default):
        return reader.attempt(lambda: read(keys[key]), default) if key in keys else default

    repetitions = optional("repetitions", lambda n: reader.integer(n, "repetitions", 1, 1000), 1)
    blocks = optional("blocks", lambda n: reader.integer(n, "blocks", 1, 1000), 1)
    ordering = Ordering(
        optional(
            "order",
            lambda n: reader.string(n, "the order", tuple(o.value for o in Ordering)),
            Ordering.RANDOM.value,
        )
    )
    constraints = optional("constraints", lambda n: _constraints(reader, n), Constraints())
    seed = None
    if "seed" in keys and not keys["seed"].tag.endswith(":null"):
        seed = optional("seed", lambda n: reader.integer(n, "the seed", 0, 2**63 - 1), None)
    iti = optional(
        "inter_trial_interval_s",
        lambda n: reader.number(n, "the inter-trial interval", "s", allow_zero=True, maximum=3600),
        Fraction(2),
    )
    practice = optional(
        "practice_trials", lambda n: reader.integer(n, "practice trials", 0, 100), 0
    )
    if conditions is None:
        raise Invalid("conditions")  # their problems are already recorded
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
    )
    from pinarray.plan import ordering_problem

    problem = ordering_problem(design)
    if problem:
        raise reader.error(keys.get("constraints", node), problem)
    return design


def _localisation(reader, node, keys, device: Device, by_name, declared) -> tuple[Condition, ...]:
    for key in ("stimulus", "pins", "frequencies_hz"):
        if key not in keys:
            raise reader.error(node, f"a localisation design needs a {key!r} key, found none")
    pin_nodes = reader.sequence(keys["pins"], "the pins")
    pins = [reader.attempt(lambda n=n: _pin(reader, n, device.grid)) for n in pin_nodes]
    if len(set(pins)) != len(pins):
        raise reader.error(keys["pins"], f"expected each pin once, found {pins}")
    stimulus = _stimulus_named(reader, keys["stimulus"], by_name, declared, wave=False)
    name = stimulus.name
    conditions = []
    for frequency_node in reader.sequence(keys["frequencies_hz"], "the frequencies"):
        frequency = reader.number(frequency_node, "a frequency", "Hz", maximum=MAX_FREQUENCY_HZ)
        train = stimulus.train.with_frequency(frequency)
        _check_train_on_pins(reader, frequency_node, train, [p for p in pins if p], device)
        conditions.extend(Condition(name, pin, frequency) for pin in pins if pin)
    return tuple(conditions)


def _stimulus_named(reader: Reader, node: Node, by_name, declared, wave: bool) -> Stimulus:
    """The pulse train (or wave) a design names at ``node``."""
    what = "wave stimulus" if wave else "pulse train"
    name = reader.string(node, f"the name of a {what}")
    stimulus = by_name.get(name)
    if stimulus is None and name in declared:
        raise Invalid(name)  # declared but broken: its own problem is already reported
    if stimulus is None or (stimulus.wave is None) == wave:
        known = ", ".join(s.name for s in by_name.values() if (s.wave is None) != wave) or "none"
        raise reader.error(node, f"expected the name of a {what} ({known}), found {name!r}")
    return stimulus


def _check_train_on_pins(reader: Reader, node: Node, train: Train, pins, device: Device) -> None:
    slot_ns = train.slot_ns
    if max(train.up_width_ns, train.down_width_ns) > slot_ns:
        raise reader.error(
            node,
            f"at {float(train.frequency_hz):g} Hz the pulse period is {float(slot_ns) / 1e6:g} ms, "
            f"shorter than the {max(train.up_width_ns, train.down_width_ns) / 1e6:g} ms pulse width",
        )
    for pin in pins:
        calibration = device.calibration(pin)
        try:
            result: Feasibility = check_train(train, calibration, device.servo)
        except PinArrayError as problem:
            raise reader.error(node, str(problem)) from None
        if not result.feasible and not device.scale_infeasible:
            raise reader.error(
                node,
                result.describe(device.servo, calibration.lever_mm)
                + "; lower the frequency or the stroke, or set device: feasibility: scale",
            )


def _motion(reader, node, keys, device, by_name, declared) -> tuple[Condition, ...]:
    if "configurations" not in keys:
        raise reader.error(
            node,
            "an apparent_motion design needs a 'configurations' key (wave stimuli), found none",
        )
    conditions = []
    for item in reader.sequence(keys["configurations"], "the configurations"):
        stimulus = _stimulus_named(reader, item, by_name, declared, wave=True)
        conditions.append(Condition(stimulus.name, direction=stimulus.wave.kind, row=stimulus.wave.row))
    return tuple(conditions)


def _constraints(reader: Reader, node: Node) -> Constraints:
    keys = reader.mapping(node, {"no_repeat", "max_run"}, what="constraints")
    no_repeat: tuple[str, ...] = ()
    if "no_repeat" in keys:
        no_repeat = tuple(
            reader.string(n, "an attribute that may not repeat", CONDITION_ATTRIBUTES)
            for n in reader.sequence(keys["no_repeat"], "no_repeat")
        )
    max_run: list[tuple[str, int]] = []
    if "max_run" in keys:
        for key_node, value_node in reader.items(keys["max_run"], "max_run"):
            attribute = reader.string(key_node, "an attribute", CONDITION_ATTRIBUTES)
            max_run.append(
                (attribute, reader.integer(value_node, f"the longest run of equal {attribute}", 1))
            )
    return Constraints(no_repeat, tuple(max_run))


def protocol_warnings(protocol: Protocol) -> list[str]:
    """What a valid protocol may still get wrong, one line each (e.g. a duration cue)."""
    from pinarray.cues import duration_cues

    return duration_cues(protocol)


def validate_file(path: str | Path) -> tuple[Protocol | None, list[str]]:
    """(protocol, problem lines) for the CLI: problems are ``file:line:col: message`` lines."""
    try:
        return load_protocol(path), []
    except ProtocolErrors as problems:
        return None, [e.located() for e in problems.errors]
    except ProtocolError as problem:
        return None, [problem.located()]
