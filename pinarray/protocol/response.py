"""What one servo was measured to do: the file `pinarray servos response` writes, as the
feasibility check uses it when a protocol names it (``device: response: FILE``).

The file holds, for each frequency and commanded stroke played on one pin, the stroke the pin
achieved (the smallest peak-to-peak over the cycles), its median, the lag from a goal change
to the pin's arrival and the cycles that fell short. A servo that turns back before it
arrives makes about the same travel whatever it was asked for, so what a frequency allows is
read as a *reach*: the larger of the largest stroke made in full and the smallest stroke
achieved where a commanded stroke fell short (where none did, the reach is a lower bound).
The reach depends on how long the pin has to travel, the shorter half-cycle, so a train of
another duty cycle is judged at the frequency whose shorter half-cycle is as long; between two
measured frequencies the reach is interpolated linearly, below the slowest one it is the
slowest one's. A train faster than every measured one, or a stroke larger than every measured
one, is not judged at all: the feasibility check refuses it, asking for a measurement.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from pinarray.errors import ProtocolError, ProtocolErrors
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader
from pinarray.text_files import NotText, decode_text, read_bounded

MAX_RESPONSE_BYTES = 1_000_000
MAX_POINTS = 1000
MAX_PIN = 1024
RESPONSE_KEYS = {"pin", "servo", "port", "speed_steps_per_s", "acceleration", "duty_cycle",
                 "cycles", "points"}
POINT_KEYS = {"frequency_hz", "stroke_commanded_steps", "stroke_achieved_steps",
              "stroke_median_steps", "lag_ms", "cycles_short"}
# Steps within which a stroke counts as achieved in full (an encoder step either way).
FULL_WITHIN_STEPS = 1


@dataclass(frozen=True)
class ResponsePoint:
    """One train measured: its frequency and stroke, and what the pin did."""

    frequency_hz: float
    commanded_steps: int
    achieved_steps: int
    median_steps: float
    lag_ms: float | None  # None: the pin never arrived while sampled
    cycles_short: int

    @property
    def short(self) -> bool:
        return self.achieved_steps < self.commanded_steps - FULL_WITHIN_STEPS


@dataclass(frozen=True)
class MeasuredResponse:
    """A servo's measured response (see the module's docstring for how it is read)."""

    source: str
    pin: int
    servo: str
    port: str
    speed_steps_per_s: int
    acceleration_register: int
    duty_cycle: Fraction
    points: tuple[ResponsePoint, ...]
    cycles: int  # cycles each train played

    def describe(self) -> str:
        """Which measurement this is, for the pre-flight and the refusals."""
        return f"measured response of pin {self.pin} ({Path(self.source).name})"

    def _reach_by_half_cycle(self) -> list[tuple[float, float]]:
        """(shorter half-cycle in s, reach in steps), slowest first."""
        share = float(min(self.duty_cycle, 1 - self.duty_cycle))
        by_frequency: dict[float, list[ResponsePoint]] = {}
        for point in self.points:
            by_frequency.setdefault(point.frequency_hz, []).append(point)
        reach = []
        for frequency, points in by_frequency.items():
            full = max((p.commanded_steps for p in points if not p.short), default=0)
            short = min((p.achieved_steps for p in points if p.short), default=0)
            reach.append((share / frequency, float(max(full, short))))
        return sorted(reach, reverse=True)

    def reach_steps(self, half_cycle_s: float) -> float | None:
        """Steps a pin is measured to travel in a shorter half-cycle of ``half_cycle_s``;
        None when the train is faster than every measured one."""
        table = self._reach_by_half_cycle()
        if not table or half_cycle_s < table[-1][0]:
            return None
        if half_cycle_s >= table[0][0]:
            return table[0][1]
        for (slow_s, slow_reach), (fast_s, fast_reach) in zip(table, table[1:], strict=False):
            if fast_s <= half_cycle_s <= slow_s:
                share = (half_cycle_s - fast_s) / (slow_s - fast_s)
                return fast_reach + share * (slow_reach - fast_reach)
        raise AssertionError(half_cycle_s)

    def shortest_half_cycle_s(self, steps: float) -> float:
        """The shortest half-cycle in which ``steps`` are measured to be reachable (inf if
        none is)."""
        table = self._reach_by_half_cycle()
        fits = [t for t, reach in table if reach >= steps]
        if not fits:
            return math.inf
        fastest = min(fits)
        # Between the fastest that fits and the next faster one, the line crosses ``steps``.
        faster = [(t, r) for t, r in table if t < fastest]
        if faster:
            t_fast, r_fast = max(faster)
            r_fit = dict(table)[fastest]
            if r_fit > r_fast:
                return t_fast + (steps - r_fast) / (r_fit - r_fast) * (fastest - t_fast)
        return fastest

    @property
    def frequencies_hz(self) -> tuple[float, ...]:
        return tuple(sorted({p.frequency_hz for p in self.points}))


def read_response(path: Path, reader: Reader, node: Node,
                  pin_count: int = MAX_PIN) -> MeasuredResponse:
    """The response file at ``path``, of a pin among ``pin_count`` (the protocol's grid); its
    problems located in it (``FILE:LINE:COL``), and a file that cannot be read located at
    ``node`` of the protocol."""
    try:
        text = decode_text(read_bounded(path, MAX_RESPONSE_BYTES, "servo response"))
    except NotText as problem:
        if problem.line:  # not text, at a place in it
            reader.errors.append(ProtocolError(problem.message, str(path), problem.line,
                                               problem.col))
            raise Invalid("servo response") from None
        raise reader.error(node, f"{problem.message} ({path}; `pinarray servos response` "
                                 "writes one)") from None
    own = Reader(str(path))
    response = None
    try:
        response = _parse(own, text, pin_count)
    except ProtocolErrors as broken:  # not YAML at all
        own.errors.extend(broken.errors)
    except Invalid:
        pass
    reader.errors.extend(own.errors)
    if response is None or own.errors:
        raise Invalid("servo response")
    return response


def _parse(reader: Reader, text: str, pin_count: int) -> MeasuredResponse:
    root = reader.compose(text, "a servo response (`pinarray servos response` writes one)")
    keys = reader.mapping(root, RESPONSE_KEYS, RESPONSE_KEYS, "servo response")
    pin = reader.integer(keys["pin"], "a pin", 1)
    if pin > pin_count:
        raise reader.error(keys["pin"], f"expected a pin from 1 to {pin_count} (the protocol's "
                                        f"grid), found {pin}")
    servo = reader.string(keys["servo"], "the servo model")
    port = reader.string(keys["port"], "the port")
    speed = reader.integer(keys["speed_steps_per_s"], "the servo speed (steps/s)", 0, 32767)
    acceleration = reader.integer(keys["acceleration"], "the acceleration register", 0, 254)
    duty = reader.number(keys["duty_cycle"], "the duty cycle", "(fraction)", maximum=1)
    if duty == 1:
        raise reader.error(keys["duty_cycle"], "expected a duty cycle below 1, found 1")
    items = reader.sequence(keys["points"], "the measured points")
    if len(items) > MAX_POINTS:
        raise reader.error(keys["points"], f"expected at most {MAX_POINTS} measured points, "
                                           f"found {len(items)}")
    points = tuple(_point(reader, item) for item in items)
    seen: set[tuple[float, int]] = set()
    for item, point in zip(items, points, strict=True):
        key = (point.frequency_hz, point.commanded_steps)
        if key in seen:
            raise reader.error(item, f"expected one point per frequency and stroke, found a "
                                     f"second at {point.frequency_hz:g} Hz and "
                                     f"{point.commanded_steps} steps")
        seen.add(key)
    cycles = reader.integer(keys["cycles"], "cycles", 2, 1000)
    return MeasuredResponse(reader.source, pin, servo, port, speed, acceleration, duty, points,
                            cycles)


def _point(reader: Reader, node: Node) -> ResponsePoint:
    keys = reader.mapping(node, POINT_KEYS, POINT_KEYS - {"lag_ms"}, "measured point")
    frequency = reader.number(keys["frequency_hz"], "a frequency", "Hz", maximum=1000)
    commanded = reader.integer(keys["stroke_commanded_steps"], "a stroke (steps)", 1, 4095)
    # A servo may overshoot its goal a little; a stroke achieved well past the one commanded
    # was not measured (a typo, or another file's numbers).
    most = commanded + max(FULL_WITHIN_STEPS, commanded // 10)
    achieved = reader.integer(keys["stroke_achieved_steps"], "a stroke (steps)", 0, 4095)
    median = reader.number(keys["stroke_median_steps"], "a stroke", "steps", maximum=4095,
                           allow_zero=True)
    for key, value in (("stroke_achieved_steps", achieved), ("stroke_median_steps", median)):
        if value > most:
            raise reader.error(keys[key], f"expected a stroke achieved of at most {most} steps "
                                          f"({commanded} commanded, and a tenth of it for an "
                                          f"overshoot), found {float(value):g}")
    lag = reader.optional(keys, "lag_ms",
                          lambda n: float(reader.number(n, "a lag", "ms", maximum=10_000,
                                                        allow_zero=True)), None)
    short = reader.integer(keys["cycles_short"], "a count of cycles", 0, 1_000_000)
    return ResponsePoint(float(frequency), commanded, achieved, float(median), lag, short)


def response_text(response: MeasuredResponse, measured_at: str) -> str:
    """The response file's text (YAML, one point a line), as `read_response` reads it."""
    lines = [
        f"# pinarray servos response: pin {response.pin}, measured {measured_at}.",
        "# Name this file in a protocol (device: response: FILE, relative to the protocol) and",
        "# the feasibility check follows it instead of the datasheet's speed.",
        f"pin: {response.pin}",
        f"servo: {response.servo}",
        f"port: {json.dumps(response.port)}",
        f"speed_steps_per_s: {response.speed_steps_per_s}",
        f"acceleration: {response.acceleration_register}",
        f"duty_cycle: {response.duty_cycle.numerator}/{response.duty_cycle.denominator}"
        if response.duty_cycle.denominator != 1 else f"duty_cycle: {response.duty_cycle}",
        f"cycles: {response.cycles}",
        "points:",
    ]
    for p in response.points:
        lag = "" if p.lag_ms is None else f", lag_ms: {p.lag_ms:.3f}"
        lines.append(
            f"  - {{frequency_hz: {p.frequency_hz!r}, stroke_commanded_steps: {p.commanded_steps}, "
            f"stroke_achieved_steps: {p.achieved_steps}, stroke_median_steps: "
            f"{p.median_steps:g}{lag}, cycles_short: {p.cycles_short}}}")
    return "\n".join(lines) + "\n"
