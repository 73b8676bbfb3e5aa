"""The ``device`` section: grid, servo settings and one calibration per pin, each problem located.

Past 400 lines on purpose: one section, read key by key, both servo families' settings and
their calibrations in one place so that each key is refused the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from fractions import Fraction
from functools import partial
from pathlib import Path

from pinarray.grid import Grid
from pinarray.protocol.model import (
    BAUD_RATES,
    DATASHEET,
    SIMULATED_PORT,
    Bandwidth,
    Device,
    HobbyServos,
    Pca9685Board,
    PinCalibration,
    Servos,
    ServoSettings,
    exact_words,
    is_simulated,
)
from pinarray.protocol.response import read_response
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader

MS = Fraction(1_000_000)  # ns per ms
# The seed's calibration: a 1.5 ms pulse holds the rest position, 2 ms lifts the pin.
DEFAULT_POSITIONS = ((1_500_000, 2048), (2_000_000, 2162))
# On a PWM board a pin's positions are its own pulse widths: the seed's, until calibrated.
DEFAULT_WIDTHS_US = ((1_500_000, 1500), (2_000_000, 2000))
# A PWM array plays on the simulated board unless the protocol names an I2C bus.
SIMULATED_BOARD_PORT = "sim://pca9685"
PCA9685_CHANNELS = 16
# A servo maps a handful of pulse widths to positions; the map is copied to every pin.
MAX_POSITIONS = 64
DEVICE_KEYS = {"grid", "port", "servo", "calibration", "pins", "servo_ids", "feasibility",
               "delivery_tolerance_ms", "board", "channels", "stroke_tolerance_percent",
               "response"}

# The STS ids a servo can take (the vendor SDK's MAX_ID; 254 is broadcast). The bus says the
# same in `pinarray.hardware.feetech.registers.MAX_SERVO_ID`, which the protocol may not import.
MAX_SERVO_ID = 252
# The most servos one bus carries: its start-up sets every servo's acceleration (3 bytes each,
# with its id 4) in one SYNC WRITE, and the servos take packets of at most 250 bytes (8 bytes
# of header, address and length) (`pinarray.hardware.feetech.packets.MAX_PACKET_BYTES`).
MAX_BUS_SERVOS = (250 - 8) // 4


@dataclass(frozen=True)
class _Unit:
    """How a family's positions are written: STS encoder steps, or PWM pulse widths in us."""

    suffix: str  # "steps" or "us": rest_steps / limits_us ...
    low: int
    high: int
    what: str  # "steps", "us of pulse width"
    default_positions: tuple[tuple[int, int], ...]


STEPS = _Unit("steps", 0, 4095, "steps", DEFAULT_POSITIONS)
# Hobby servos take roughly 500-2500 us; the bounds leave room for odd ones, never a period.
WIDTH_US = _Unit("us", 100, 3000, "us of pulse width", DEFAULT_WIDTHS_US)


@dataclass(frozen=True)
class _Given:
    """Calibration fields as one section writes them (the shared one, or a pin's own); None
    where the section does not say, so that a pin's own values override the shared ones."""

    rest: tuple[int, Node] | None = None
    positions: tuple[tuple[int, int, Node | None], ...] | None = None
    limits: tuple[tuple[int, int], Node] | None = None
    lever_mm: float | None = None

    def over(self, base: _Given) -> _Given:
        return replace(base, **{f.name: getattr(self, f.name) for f in fields(self)
                                if getattr(self, f.name) is not None})


def read_device(reader: Reader, node: Node | None) -> Device | None:
    """The device a protocol describes (defaults when ``node`` is None); None if it is broken
    in a way that makes checking stimuli against it meaningless (grid, servo, calibration)."""
    if node is None:
        return _pin_calibrations(reader, Grid(), ServoSettings(), _Given())
    keys = reader.attempt(lambda: reader.mapping(node, DEVICE_KEYS, what="device section"), None)
    if keys is None:
        return None
    pwm = "board" in keys
    unit = WIDTH_US if pwm else STEPS
    ids_key = "channels" if pwm else "servo_ids"
    for wrong in ("channels", "servo_ids"):
        if wrong != ids_key and wrong in keys:
            reader.error(keys[wrong], f"expected {ids_key} for {'a PWM board' if pwm else 'bus servos'}"
                         f" (a device with{'' if pwm else 'out'} board:), found {wrong}")
    servo: Servos
    try:
        with reader.section():
            grid = reader.optional(keys, "grid", lambda n: _grid(reader, n), Grid())
            if pwm:
                board = _board(reader, keys["board"])
                servo = reader.optional(keys, "servo", lambda n: _hobby(reader, n, board),
                                        HobbyServos(board))
                if grid.pin_count > PCA9685_CHANNELS:
                    raise reader.error(keys["grid"], f"expected at most {PCA9685_CHANNELS} pins on "
                                       f"one PCA9685 board, found {grid.pin_count}")
            else:
                servo = reader.optional(keys, "servo", lambda n: _servo(reader, n), ServoSettings())
                if grid.pin_count > MAX_BUS_SERVOS:
                    raise reader.error(keys["grid"], f"expected a grid of at most "
                                       f"{MAX_BUS_SERVOS} pins on one servo bus (one SYNC WRITE "
                                       "sets them all, in a packet of at most 250 bytes), "
                                       f"found {grid.pin_count}")
    except Invalid:
        return None
    port = reader.optional(keys, "port", lambda n: reader.string(n, "the port"),
                           SIMULATED_BOARD_PORT if pwm else SIMULATED_PORT)
    scale = reader.optional(
        keys, "feasibility", lambda n: reader.string(n, "feasibility", ("reject", "scale")),
        "reject",
    ) == "scale"
    tolerance_ns = reader.optional(
        keys, "delivery_tolerance_ms",
        lambda n: whole_ns(reader, n, reader.number(n, "the delivery tolerance", "ms",
                                                    maximum=10_000), MS, "the delivery tolerance",
                           "ms"),
        Device.delivery_tolerance_ns,
    )
    stroke = reader.optional(
        keys, "stroke_tolerance_percent",
        # 0: no stroke checked (nor, then, whether every cycle was measured)
        lambda n: reader.number(n, "the stroke tolerance (the least share of a pin's commanded "
                                "stroke it must achieve)", "%", maximum=100,
                                allow_zero=True) / 100,
        Device.stroke_tolerance,
    )
    base = reader.optional(
        keys, "calibration", lambda n: _calibration(reader, n, "calibration", unit), _Given()
    )
    none: list[tuple[Node, Node]] = []
    overrides: dict[int, _Given] = {}
    for key_node, value_node in reader.optional(
        keys, "pins", lambda n: reader.items(n, "the per-pin calibration"), none
    ):
        pin = reader.attempt(partial(read_pin, reader, key_node, grid), None)
        given = reader.attempt(
            partial(_calibration, reader, value_node, "pin calibration", unit), None)
        if pin is not None and given is not None:
            overrides[pin] = given
    ids: dict[int, tuple[int, Node]] = {}
    for key_node, value_node in reader.optional(
        keys, ids_key, lambda n: reader.items(n, ids_key), none
    ):
        pin = reader.attempt(partial(read_pin, reader, key_node, grid), None)
        servo_id = reader.attempt(
            partial(reader.integer, value_node, "a channel" if pwm else "a servo id", 0,
                    PCA9685_CHANNELS - 1 if pwm else MAX_SERVO_ID), None)
        if pin is not None and servo_id is not None:
            ids[pin] = (servo_id, value_node)
    device = _pin_calibrations(reader, grid, servo, base, overrides, ids, keys.get(ids_key), unit)
    if device is None:
        return None
    datasheet: Bandwidth = DATASHEET
    bandwidth = reader.optional(keys, "response",
                                lambda n: _response(reader, n, servo, port, device.grid),
                                datasheet)
    return replace(device, port=port, scale_infeasible=scale, delivery_tolerance_ns=tolerance_ns,
                   stroke_tolerance=stroke, bandwidth=bandwidth)


def _response(reader: Reader, node: Node, servo: Servos, port: str, grid: Grid) -> Bandwidth:
    """The measured servo response a protocol names, a path relative to the protocol's file,
    refused when it was measured with other settings than the protocol's, or on the simulator
    for a protocol that drives real servos."""
    if not isinstance(servo, ServoSettings):
        raise reader.error(node, "expected no response: for hobby servos on a PWM board (their "
                                 "position is not read back), found one")
    name = reader.string(node, "the servo response file")
    response = read_response(Path(reader.source).parent / name, reader, node, grid.pin_count)
    if response.servo.lower() != servo.model.lower():
        raise reader.error(node, f"expected a response measured on {servo.model} servos, found "
                                 f"one of {response.servo} ({name})")
    measured = (response.speed_steps_per_s, response.acceleration_register)
    settings = (servo.speed_steps_per_s, servo.acceleration_register)
    if measured != settings:
        raise reader.error(
            node, f"expected a response measured at the protocol's speed {settings[0]} steps/s "
                  f"and acceleration {settings[1]}, found one at {measured[0]} steps/s and "
                  f"acceleration {measured[1]} ({name}): measure it again with "
                  "`pinarray servos response`")
    if is_simulated(response.port) and not is_simulated(port):
        raise reader.error(
            node, f"expected a response measured on the servos of {port}, found one measured on "
                  f"the simulator ({response.port}, {name}): measure the real servos with "
                  "`pinarray servos response --port`")
    return response


def read_pin(reader: Reader, node: Node, grid: Grid) -> int:
    """A pin number of ``grid``, 1-based as the lab counts."""
    pin = reader.integer(node, "a pin number")
    if not 1 <= pin <= grid.pin_count:
        raise reader.error(
            node,
            f"expected a pin from 1 to {grid.pin_count} on the {grid.rows}x{grid.columns} grid, found {pin}",
        )
    return pin


def read_width_ns(reader: Reader, node: Node) -> int:
    """A servo pulse width written in ms, as whole nanoseconds."""
    width = reader.number(node, "a pulse width", "ms", maximum=100)
    return whole_ns(reader, node, width, MS, "a pulse width", "ms")


def whole_ns(reader: Reader, node: Node, value: Fraction, ns_per_unit: Fraction | int,
             what: str, unit: str) -> int:
    """``value``, a time written in ``unit`` (``ns_per_unit`` ns each), as the whole
    nanoseconds every time inside the core is; a finer one is refused at ``node``: rounded, it
    would be played other than written, and two values could become one."""
    ns = value * ns_per_unit
    if ns.denominator != 1:
        raise reader.error(node, f"expected {what} in whole nanoseconds, found "
                                 f"{exact_words(value)} {unit}")
    return int(ns)


def _grid(reader: Reader, node: Node) -> Grid:
    keys = reader.mapping(node, {"rows", "columns", "pitch_mm"}, what="grid")
    with reader.section():
        rows = reader.optional(keys, "rows", lambda n: reader.integer(n, "rows", 1, 64), 4)
        columns = reader.optional(
            keys, "columns", lambda n: reader.integer(n, "columns", 1, 64), 4
        )
        pitch = reader.optional(
            keys, "pitch_mm",
            lambda n: float(reader.number(n, "the pitch", "mm", maximum=100)), 2.0,
        )
    return Grid(rows, columns, pitch)


def _servo(reader: Reader, node: Node) -> ServoSettings:
    keys = reader.mapping(
        node,
        {"model", "baud_rate", "speed_steps_per_s", "acceleration", "steps_per_turn",
         "return_delay_us"},
        what="servo section",
    )
    d = ServoSettings()
    with reader.section():
        model = reader.optional(
            keys, "model", lambda n: reader.string(n, "the servo model", ("STS3215",)), d.model
        )
        baud = reader.optional(keys, "baud_rate", lambda n: _baud_rate(reader, n), d.baud_rate)
        speed = reader.optional(
            keys, "speed_steps_per_s",
            lambda n: reader.integer(n, "the servo speed (steps/s)", 1, 10_000),
            d.speed_steps_per_s,
        )
        accel = reader.optional(
            keys, "acceleration",
            lambda n: reader.integer(
                n, "the acceleration register (100 step/s^2 units, 0 = maximum)", 0, 254
            ),
            d.acceleration_register,
        )
        steps = reader.optional(
            keys, "steps_per_turn", lambda n: reader.integer(n, "steps per turn", 1, 1 << 16),
            d.steps_per_turn,
        )
        # What `pinarray servos return-delay` set (2 us units, 0-508): the bus check's read-backs.
        delay = reader.optional(
            keys, "return_delay_us",
            lambda n: _return_delay_us(reader, n), d.return_delay_us,
        )
    return ServoSettings(model, baud, speed, accel, steps, delay)


def _return_delay_us(reader: Reader, node: Node) -> int:
    delay = reader.integer(node, "the servos' return delay (us)", 0, 508)
    if delay % 2:
        raise reader.error(node, f"expected a return delay in steps of 2 us (the register "
                                 f"counts 2 us), found {delay}")
    return delay


def _board(reader: Reader, node: Node) -> Pca9685Board:
    keys = reader.mapping(node, {"chip", "address", "osc_hz", "pwm_hz"}, what="board section")
    d = Pca9685Board()
    with reader.section():
        reader.optional(keys, "chip", lambda n: reader.string(n, "the board's chip", ("PCA9685",)),
                        "PCA9685")
        address = reader.optional(keys, "address", lambda n: _address(reader, n), d.address)
        osc_hz = reader.optional(
            keys, "osc_hz",
            lambda n: reader.integer(n, "the board's oscillator (Hz; 25000000 nominal, up to "
                                     "50000000 on EXTCLK)", 1_000_000, 50_000_000), d.osc_hz)
        pwm_hz = reader.optional(
            keys, "pwm_hz", lambda n: reader.integer(n, "the PWM rate (Hz)", 24, 1526), d.pwm_hz)
    return Pca9685Board(address, osc_hz, pwm_hz)


def _address(reader: Reader, node: Node) -> int:
    # Written as a quoted "0x40" (YAML 1.2 reads bare hex as a string; we refuse YAML 1.1 hex).
    text = reader.string(node, 'the board\'s I2C address ("0x40" to "0x7f")')
    try:
        if not text.isascii():  # int() reads other scripts' digits (０x４０)
            raise ValueError(text)
        address = int(text, 16) if text.lower().startswith("0x") else int(text)
    except ValueError:
        raise reader.error(node, f'expected an I2C address such as "0x40", found {text!r}') from None
    if not 0x40 <= address <= 0x7F or address == 0x70:
        raise reader.error(node, "expected a PCA9685 address from 0x40 to 0x7f other than the "
                           f"all-call 0x70, found {text!r}")
    return address


def _hobby(reader: Reader, node: Node, board: Pca9685Board) -> HobbyServos:
    keys = reader.mapping(node, {"model", "speed_us_per_s", "dead_band_us", "degrees_per_us"},
                          what="servo section (hobby servos)")
    d = HobbyServos(board)
    with reader.section():
        model = reader.optional(keys, "model", lambda n: reader.string(n, "the servo model"),
                                d.model)
        speed = reader.optional(
            keys, "speed_us_per_s",
            lambda n: reader.integer(n, "how fast the servo follows a width change (us/s)", 1,
                                     1_000_000), d.speed_us_per_s)
        dead_band = reader.optional(
            keys, "dead_band_us", lambda n: reader.integer(n, "the dead band (us)", 0, 100),
            d.dead_band_us)
        degrees = reader.optional(
            keys, "degrees_per_us",
            lambda n: reader.number(n, "the horn's angle per us of width", "deg/us", maximum=1),
            d.degrees_per_us)
    return HobbyServos(board, model, speed, dead_band, degrees)


def _baud_rate(reader: Reader, node: Node) -> int:
    baud = reader.integer(node, "the baud rate")
    if baud not in BAUD_RATES:
        raise reader.error(
            node,
            f"expected a baud rate the servos support ({', '.join(map(str, BAUD_RATES))}), found {baud}",
        )
    return baud


def _calibration(reader: Reader, node: Node, what: str, unit: _Unit = STEPS) -> _Given:
    rest_key, limits_key = f"rest_{unit.suffix}", f"limits_{unit.suffix}"
    keys = reader.mapping(node, {rest_key, "positions", limits_key, "lever_mm"}, what=what)
    with reader.section():
        rest = reader.optional(
            keys, rest_key,
            lambda n: (reader.integer(n, f"the rest position ({unit.what})", unit.low, unit.high),
                       n), None,
        )
        positions = reader.optional(keys, "positions", lambda n: _positions(reader, n, unit),
                                    None)
        limits = reader.optional(keys, limits_key, lambda n: _limits(reader, n, unit), None)
        lever_mm = reader.optional(
            keys, "lever_mm",
            lambda n: float(reader.number(n, "the lever length", "mm", maximum=1000)), None,
        )
    return _Given(rest, positions, limits, lever_mm)


def _positions(reader: Reader, node: Node,
               unit: _Unit) -> tuple[tuple[int, int, Node | None], ...]:
    pairs = reader.items(node, f"positions (pulse width in ms: {unit.what})")
    if len(pairs) > MAX_POSITIONS:
        raise reader.error(
            node, f"expected at most {MAX_POSITIONS} calibrated positions, found {len(pairs)}"
        )
    positions: list[tuple[int, int, Node | None]] = []
    for width_node, position_node in pairs:
        width_ns = reader.attempt(partial(read_width_ns, reader, width_node), None)
        position = reader.attempt(
            partial(reader.integer, position_node, f"a position ({unit.what})", unit.low,
                    unit.high), None
        )
        if width_ns is None or position is None:
            continue
        # Two widths at one position are checked where a stimulus plays them on the pin
        # (`pinarray.protocol.stimuli.check_stroke`): a pin nothing plays may be calibrated flat.
        positions.append((width_ns, position, position_node))
    return tuple(positions)


def _limits(reader: Reader, node: Node, unit: _Unit) -> tuple[tuple[int, int], Node]:
    items = reader.sequence(node, f"the limits [min, max] in {unit.suffix}", 2)
    if len(items) != 2:
        raise reader.error(
            node, f"expected two limits [min, max] in {unit.suffix}, found {len(items)} values"
        )
    low, high = (reader.integer(n, f"a limit ({unit.what})", unit.low, unit.high)
                 for n in items)
    if low >= high:
        raise reader.error(
            node, f"expected limits [min, max] with min < max, found [{low}, {high}]"
        )
    return (low, high), node


def _pin_calibrations(
    reader: Reader,
    grid: Grid,
    servo: Servos,
    base: _Given,
    overrides: dict[int, _Given] | None = None,
    ids: dict[int, tuple[int, Node]] | None = None,
    ids_node: Node | None = None,
    unit: _Unit = STEPS,
) -> Device | None:
    """One calibration per pin: the shared one, overridden per pin; every position in limits."""
    overrides = overrides or {}
    ids = ids or {}
    pins = []
    ok = True
    for pin in grid.pins:
        given = overrides[pin].over(base) if pin in overrides else base
        positions = given.positions or tuple((w, p, None) for w, p in unit.default_positions)
        rest, rest_node = given.rest or (positions[0][1], None)
        # Without explicit limits a pin may go exactly where it is calibrated to go, no further.
        span = [p for _, p, _ in positions] + [rest]
        (low, high), limits_node = given.limits or ((min(span), max(span)), None)
        checks = [(position, node, "position") for _, position, node in positions] + [
            (rest, rest_node, "rest position")
        ]
        for position, node, what in checks:
            if not low <= position <= high:
                reader.error(
                    node or limits_node,
                    f"pin {pin}: expected its {what} within its limits [{low}, {high}] "
                    f"{unit.suffix}, found {position}",
                )
                ok = False
        # STS ids default to the pin's number; board channels count from 0.
        servo_id = ids.get(pin, (pin - 1 if unit is WIDTH_US else pin, None))[0]
        pins.append(
            PinCalibration(
                pin,
                servo_id,
                rest,
                low,
                high,
                tuple((w, p) for w, p, _ in positions),
                6.0 if given.lever_mm is None else given.lever_mm,
            )
        )
    seen: dict[int, int] = {}
    for calibration in pins:
        if calibration.servo_id in seen:
            node = ids[calibration.pin][1] if calibration.pin in ids else ids_node
            reader.error(
                node,
                f"expected one pin for each {'channel' if unit is WIDTH_US else 'servo id'}, "
                f"found {calibration.servo_id} driving both pin {seen[calibration.servo_id]} "
                f"and pin {calibration.pin}",
            )
            ok = False
        seen[calibration.servo_id] = calibration.pin
    return Device(grid, servo, tuple(pins)) if ok else None
