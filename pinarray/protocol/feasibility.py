"""Can the servo follow a train? Travel reachable in each half-cycle: measured, when the
protocol names a servo response (`pinarray.protocol.response`), else from the datasheet's speed
and acceleration.

From the datasheet, a servo that must stop at each end of its stroke covers, in time ``T`` from standstill to
standstill, ``v*T`` steps when acceleration is unlimited, ``a*T^2/4`` when it never reaches
top speed (``T <= 2v/a``), and ``v*T - v^2/a`` otherwise (trapezoidal profile).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from fractions import Fraction
from functools import lru_cache

from pinarray.errors import PinArrayError
from pinarray.protocol.model import NS_PER_S, Datasheet, Device, PinCalibration, Servos, Train


def reachable_steps(
    duration_ns: float, speed_steps_per_s: float, accel_steps_per_s2: float | None
) -> float:
    """Steps a servo can travel in ``duration_ns``, starting and ending at rest."""
    t_s = duration_ns / NS_PER_S
    v = speed_steps_per_s
    if accel_steps_per_s2 is None:
        return v * t_s
    a = accel_steps_per_s2
    if t_s <= 2 * v / a:
        return a * t_s * t_s / 4
    return v * t_s - v * v / a


def travel_time_s(
    steps: float, speed_steps_per_s: float, accel_steps_per_s2: float | None
) -> float:
    """Shortest time to travel ``steps`` from standstill to standstill, in seconds."""
    v = speed_steps_per_s
    if accel_steps_per_s2 is None:
        return steps / v
    a = accel_steps_per_s2
    if steps <= v * v / a:
        return 2 * math.sqrt(steps / a)
    return steps / v + v / a


# Asked for each pin and condition a train plays (681 times for the 18 trains of the shipped
# protocols): worked out once per train.
@lru_cache(maxsize=4096)
def shortest_lift_ns(train: Train) -> int | None:
    """The shortest time ``train`` holds a pin up, as it plays: an up half-cycle
    (``duty / frequency``), or less where its phase starts the first cycle inside one or the
    signal's end cuts the last (the pin then goes to rest); None when it never lifts.

    Slot ``k`` starts at ``(k + phase * pulses_per_cycle) * slot``, rounded to the ns (halves
    up), and plays only if it ends within the signal, as `pinarray.schedule` plays it.
    """
    per_cycle, up = train.pulses_per_cycle, train.up_pulses
    if up == 0:
        return None
    slot, offset = train.slot_ns, train.phase * per_cycle
    widths = (train.up_width_ns, train.down_width_ns)

    def start(k: int) -> int:
        return math.floor((k + offset) * slot + Fraction(1, 2))

    first = -int(offset)
    last = int(train.duration_ns / slot - offset)
    while last >= first and start(last) + widths[last % per_cycle >= up] > train.duration_ns:
        last -= 1

    def lift(a: int, b: int) -> int:  # up slots a..b; then a down slot, or rest
        return (start(b + 1) if b < last else train.duration_ns) - start(a)

    k = first if first % per_cycle < up else first - first % per_cycle + per_cycle
    j = last if last % per_cycle < up else last - last % per_cycle + up - 1
    if last < first or k > j:
        return None  # no pulse, or none up
    # The first lift (the phase may start it inside its run), the last (the signal's end may
    # cut it), and whole ones between them.
    lifts = [lift(k, min(k - k % per_cycle + up - 1, last)), lift(max(first, j - j % per_cycle), j)]
    if j // per_cycle - k // per_cycle >= 2:
        lifts.append(math.floor(up * slot))  # to the ns, as the rounded starts give it at least
    return min(lifts)


@dataclass(frozen=True)
class Feasibility:
    """How much of a pin's calibrated stroke a train can really produce."""

    pin: int
    frequency_hz: float
    stroke_steps: int  # |up - down| as calibrated
    reachable_steps: float  # in the shorter half-cycle, or the shortest lift if shorter
    max_frequency_hz: float  # highest frequency at which ``needed_steps`` are reachable
    needed_steps: float  # the least travel that follows the train (see `check_train`)
    basis: str  # what the reach rests on: datasheet figures or a measured response
    # A lift shorter than every half-cycle (a phase or a signal's end cutting a cycle), ms:
    # what the reach was judged in; None when the half-cycles are the shortest.
    cut_lift_ms: float | None = None

    @property
    def feasible(self) -> bool:
        return self.reachable_steps >= self.needed_steps

    @property
    def amplitude_fraction(self) -> float:
        return 1.0 if self.feasible else self.reachable_steps / self.stroke_steps

    def describe(self, servo: Servos, mm_per_step: float) -> str:
        """Why the pin cannot follow, in position units, degrees and mm (``mm_per_step``:
        `Device.mm_per_step`)."""
        unit = servo.position_unit

        def angle(steps: float) -> float:
            return servo.degrees(steps)

        def travel_mm(steps: float) -> float:
            return steps * mm_per_step

        if self.cut_lift_ms is not None:
            return (
                f"pin {self.pin} cannot follow its train at {self.frequency_hz:g} Hz "
                f"({self.basis}): the signal's length (or its phase) cuts a cycle, leaving a "
                f"lift of {self.cut_lift_ms:.1f} ms, in which only {self.reachable_steps:.0f} "
                f"of the {self.needed_steps:.0f} {unit} it needs of its stroke of "
                f"{self.stroke_steps} {unit} ({travel_mm(self.stroke_steps):.2f} mm) are "
                "reachable (a signal of whole cycles from phase 0 cuts none)"
            )
        return (
            f"pin {self.pin} cannot follow {self.frequency_hz:g} Hz ({self.basis}): its stroke of "
            f"{self.stroke_steps} {unit} ({angle(self.stroke_steps):.1f} deg, "
            f"{travel_mm(self.stroke_steps):.2f} mm) {self._needs()} at most "
            f"{self.max_frequency_hz:.2f} Hz; "
            f"at {self.frequency_hz:g} Hz only {self.reachable_steps:.0f} {unit} "
            f"({angle(self.reachable_steps):.1f} deg, {travel_mm(self.reachable_steps):.2f} mm, "
            f"{self.amplitude_fraction:.0%} of the stroke) are reachable"
        )


    def _needs(self) -> str:
        if self.needed_steps >= self.stroke_steps:
            return "needs"
        return f"needs, to move {self.needed_steps:.0f} of them (the stroke tolerance),"


def check_train(train: Train, calibration: PinCalibration, device: Device) -> Feasibility:
    """Feasibility of ``train`` on the pin ``calibration`` describes, on ``device``.

    From the datasheet the whole stroke must be reachable; from a measured response, the
    share of it the protocol's stroke tolerance asks of a delivered trial (what a played trial
    is judged by).
    """
    up = calibration.position_for_width(train.up_width_ns)
    down = calibration.position_for_width(train.down_width_ns)
    stroke = abs(up - down)
    shorter_share = min(train.duty_cycle, 1 - train.duty_cycle)
    half_s = float(shorter_share / train.frequency_hz)
    lift_ns = shortest_lift_ns(train)
    cut_s = None if lift_ns is None or lift_ns >= half_s * NS_PER_S else float(lift_ns) / NS_PER_S
    if cut_s is None:
        return _check_half(train, calibration.pin, stroke, half_s, shorter_share, device,
                           "its shorter half-cycle of")
    return replace(_check_half(train, calibration.pin, stroke, cut_s, shorter_share, device,
                               "a lift its signal's length or phase cuts to"),
                   cut_lift_ms=cut_s * 1e3)


def _check_half(train: Train, pin: int, stroke: int, half_s: float, shorter_share: Fraction,
                device: Device, what: str) -> Feasibility:
    """`check_train` for the shortest time the pin has to travel, ``half_s`` (``what`` it is,
    for a refusal)."""
    bandwidth = device.bandwidth
    if isinstance(bandwidth, Datasheet):
        return _from_datasheet(pin, train, stroke, half_s, float(shorter_share), device.servo)
    needed = math.ceil(stroke * device.stroke_tolerance)
    frequency_hz = float(train.frequency_hz)
    reach = bandwidth.reach_steps(half_s)
    if reach is None:
        fastest_s = min(float(min(bandwidth.duty_cycle, 1 - bandwidth.duty_cycle)) / f
                        for f in bandwidth.frequencies_hz)
        raise NotMeasured(
            f"pin {pin}: {frequency_hz:g} Hz is faster than every train of the "
            f"{bandwidth.describe()}: {what} {half_s * 1e3:.1f} ms is below "
            f"the {fastest_s * 1e3:.1f} ms measured; measure it (`pinarray servos response "
            f"--frequencies`) or lower the frequency")
    largest = max(p.commanded_steps for p in bandwidth.points)
    if needed > largest:
        raise NotMeasured(
            f"pin {pin}: a stroke of {stroke} steps is larger than every stroke of the "
            f"{bandwidth.describe()} (largest {largest} steps); measure it (`pinarray servos "
            f"response --strokes`)")
    shortest_s = bandwidth.shortest_half_cycle_s(needed)
    max_hz = float(shorter_share) / shortest_s if needed > 0 else math.inf
    return Feasibility(pin, frequency_hz, stroke, reach, max_hz, needed, bandwidth.describe())


class NotMeasured(PinArrayError):
    """A train the protocol's measured response says nothing about (faster, or a larger
    stroke, than every train measured): refused, ``device: feasibility: scale`` or not."""


def _from_datasheet(pin: int, train: Train, stroke: int, half_s: float, shorter_share: float,
                    servo: Servos) -> Feasibility:
    accel = servo.acceleration_steps_per_s2
    reachable = reachable_steps(half_s * NS_PER_S, servo.speed_steps_per_s, accel)
    needed_s = travel_time_s(stroke, servo.speed_steps_per_s, accel)
    max_hz = shorter_share / needed_s if needed_s > 0 else math.inf
    return Feasibility(pin, float(train.frequency_hz), stroke, reachable, max_hz, stroke,
                       "datasheet figures")
