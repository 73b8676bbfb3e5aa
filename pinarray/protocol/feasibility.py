"""Can the servo follow a train? Travel reachable in each half-cycle: measured, when the
protocol names a servo response (`pinarray.protocol.response`), else from the datasheet's speed
and acceleration.

From the datasheet, a servo that must stop at each end of its stroke covers, in time ``T`` from standstill to
standstill, ``v*T`` steps when acceleration is unlimited, ``a*T^2/4`` when it never reaches
top speed (``T <= 2v/a``), and ``v*T - v^2/a`` otherwise (trapezoidal profile).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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


@dataclass(frozen=True)
class Feasibility:
    """How much of a pin's calibrated stroke a train can really produce."""

    pin: int
    frequency_hz: float
    stroke_steps: int  # |up - down| as calibrated
    reachable_steps: float  # in the shorter half-cycle
    max_frequency_hz: float  # highest frequency at which ``needed_steps`` are reachable
    needed_steps: float  # the least travel that follows the train (see `check_train`)
    basis: str  # what the reach rests on: datasheet figures or a measured response

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
    bandwidth = device.bandwidth
    if isinstance(bandwidth, Datasheet):
        return _from_datasheet(calibration.pin, train, stroke, half_s, float(shorter_share),
                               device.servo)
    needed = math.ceil(stroke * device.stroke_tolerance)
    pin, frequency_hz = calibration.pin, float(train.frequency_hz)
    reach = bandwidth.reach_steps(half_s)
    if reach is None:
        fastest_s = min(float(min(bandwidth.duty_cycle, 1 - bandwidth.duty_cycle)) / f
                        for f in bandwidth.frequencies_hz)
        raise NotMeasured(
            f"pin {pin}: {frequency_hz:g} Hz is faster than every train of the "
            f"{bandwidth.describe()}: its shorter half-cycle of {half_s * 1e3:.1f} ms is below "
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
