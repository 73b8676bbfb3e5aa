"""A servo's response measured on one pin (`pinarray servos response`): the protocol's train
played at each frequency and stroke, each pin's achieved stroke and lag read from the Present
Position samples the delivery verifier takes (`pinarray.hardware.motion`).

Each train plays ``cycles`` cycles from rest, as a trial would, and the pin rests for
`SETTLE_NS` before the next, so that every measurement starts from standstill.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import TYPE_CHECKING, TypeAlias

from pinarray.errors import PinArrayError
from pinarray.protocol import PinDrive
from pinarray.protocol.adapted import stroke_device
from pinarray.protocol.model import (
    Protocol,
    ServoSettings,
    Train,
    TrainShape,
    TrainStimulus,
    WaveStimulus,
)
from pinarray.protocol.response import MeasuredResponse, ResponsePoint
from pinarray.schedule import TrialSchedule, compile_drives
from pinarray.units import NS_PER_MS, NS_PER_S, duration_words

if TYPE_CHECKING:
    from pinarray.hardware.delivery import Presentation
    from pinarray.player.rig import Rig

DEFAULT_FREQUENCIES_HZ = (1, 2, 3, 5, 7, 10, 12, 15, 20)
DEFAULT_STROKE_SHARES = (Fraction(1, 4), Fraction(1, 2), Fraction(3, 4), Fraction(1))
DEFAULT_CYCLES = 10
SETTLE_NS = 300 * NS_PER_MS  # at rest between two trains: the pin back at standstill
# A measurement, not an endurance run: what the trains may play in all (and the simulator
# computes in virtual time, about 20 times faster here).
MAX_PLAYING_S = 3600


@dataclass(frozen=True)
class NotMeasured:
    """A train played that taught nothing: not delivered as scheduled, or the pin's position
    sampled too seldom to judge a cycle (``problem`` says which)."""

    frequency_hz: Fraction
    stroke_steps: int
    problem: str


Measured: TypeAlias = "ResponsePoint | NotMeasured"  # one train played


def protocol_train(protocol: Protocol, name: str | None) -> tuple[str, Train | TrainShape]:
    """The train the protocol's stimulus ``name`` plays (None: its first stimulus)."""
    stimuli = protocol.stimuli
    if not stimuli:
        raise PinArrayError(f"{protocol.source}: no stimulus to play")
    chosen = stimuli[0] if name is None else next((s for s in stimuli if s.name == name), None)
    if chosen is None:
        raise PinArrayError(f"--stimulus: expected one of {', '.join(s.name for s in stimuli)}, "
                            f"found {name!r}")
    match chosen:
        case TrainStimulus(train=train):
            return chosen.name, train
        case WaveStimulus(wave=wave):
            return chosen.name, wave.train
    raise AssertionError(chosen)


def default_strokes(protocol: Protocol, pin: int, train: Train | TrainShape) -> tuple[int, ...]:
    """A quarter, half, three quarters and all of the pin's calibrated stroke for ``train``."""
    calibration = protocol.device.calibration(pin)
    full = abs(calibration.position_for_width(train.up_width_ns)
               - calibration.position_for_width(train.down_width_ns))
    return tuple(sorted({max(1, round(full * share)) for share in DEFAULT_STROKE_SHARES}))


def playing_s(frequencies_hz: Sequence[Fraction], strokes: int, cycles: int) -> Fraction:
    """How long the trains play in all, s: ``cycles`` cycles at each frequency for each of
    ``strokes`` strokes, `SETTLE_NS` at rest after each."""
    settle = Fraction(SETTLE_NS, NS_PER_S)
    return strokes * sum((cycles / f + settle for f in frequencies_hz), Fraction(0))


def check_playing_time(frequencies_hz: Sequence[Fraction], strokes: int, cycles: int) -> str:
    """The trains' playing time in words; refused above `MAX_PLAYING_S`, with what to change,
    before anything is compiled or moves."""
    total = playing_s(frequencies_hz, strokes, cycles)
    if total <= MAX_PLAYING_S:
        return duration_words(float(total))
    lowest = min(frequencies_hz)
    raise PinArrayError(
        f"servos response: {len(frequencies_hz) * strokes} trains would play for about "
        f"{duration_words(float(total))} ({cycles} cycles each; the lowest frequency, "
        f"{float(lowest):g} Hz, alone {duration_words(float(strokes * cycles / lowest))}); at "
        f"most {duration_words(MAX_PLAYING_S)}: raise the lowest --frequencies, or play fewer "
        "--cycles or --strokes")


@dataclass(frozen=True)
class ResponseTrain:
    """One train of a measurement, compiled before anything moves."""

    frequency_hz: Fraction
    stroke_steps: int
    schedule: TrialSchedule


def response_trains(protocol: Protocol, pin: int, train: Train | TrainShape,
                    frequencies_hz: Sequence[Fraction], strokes_steps: Sequence[int],
                    cycles: int) -> list[ResponseTrain]:
    """``train`` on ``pin`` at each frequency and stroke, ``cycles`` cycles each, compiled; a
    stroke outside the pin's calibrated limits is refused, naming the pin."""
    device = replace(protocol.device, scale_infeasible=False)  # measure, never shrink
    if not isinstance(device.servo, ServoSettings):
        raise PinArrayError("servos response: hobby servos on a PWM board do not report their "
                            "position; it measures bus servos")
    devices = {stroke: stroke_device(device, {pin}, train.with_frequency(Fraction(1)),
                                     Fraction(stroke)) for stroke in strokes_steps}
    trains = []
    for frequency in frequencies_hz:
        duration_ns = -(-cycles * NS_PER_S // frequency)  # whole cycles, ceiling to the ns
        played = replace(train.with_frequency(frequency), duration_ns=int(duration_ns))
        for stroke in strokes_steps:
            trains.append(ResponseTrain(frequency, stroke,
                                        compile_drives([PinDrive(pin, played)], devices[stroke])))
    return trains


def measure_response(rig: Rig, pin: int, trains: Sequence[ResponseTrain],
                     measured: Callable[[Measured], object] = lambda m: None) -> list[Measured]:
    """Play each of ``trains`` on ``rig`` and measure what ``pin`` did, resting `SETTLE_NS`
    between two; ``measured`` hears of each as it comes."""
    results = []
    for train in trains:
        presentation = rig.present(train.schedule)
        rig.clock.sleep_until_ns(rig.clock.now_ns() + SETTLE_NS)
        results.append(_measured(pin, train.frequency_hz, train.stroke_steps, presentation))
        measured(results[-1])
    return results


def _measured(pin: int, frequency: Fraction, stroke: int, presentation: Presentation) -> Measured:
    delivery = presentation.delivery
    if delivery.missing or delivery.worst_lateness_ns > delivery.tolerance_ns:
        # The servo was not told what the schedule says: nothing to learn of its response.
        return NotMeasured(frequency, stroke, delivery.problem)
    strokes = delivery.strokes
    mine = None if strokes is None else next((p for p in strokes.pins if p.pin == pin), None)
    if mine is None or mine.achieved_steps is None or mine.median_steps is None:
        return NotMeasured(frequency, stroke,
                           "too few position samples to judge a cycle (the adapter's latency "
                           "timer: see `pinarray timing --help`)")
    lag_ms = None if mine.lag_ns is None else mine.lag_ns / NS_PER_MS
    return ResponsePoint(float(frequency), stroke, mine.achieved_steps, mine.median_steps,
                         lag_ms, mine.short_cycles)


def response_of(protocol: Protocol, pin: int, train: Train | TrainShape, port: str,
                results: Sequence[Measured], cycles: int) -> MeasuredResponse:
    """What the response file holds."""
    servo = protocol.device.servo
    assert isinstance(servo, ServoSettings)
    duty = Fraction(train.up_pulses, train.pulses_per_cycle)
    return MeasuredResponse("", pin, servo.model, port, servo.speed_steps_per_s,
                            servo.acceleration_register, duty,
                            tuple(m for m in results if isinstance(m, ResponsePoint)), cycles)
