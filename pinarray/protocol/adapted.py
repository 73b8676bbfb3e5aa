"""A stimulus at one value of an adaptive design's parameter. Pure Python, exact numbers.

The protocol states each stimulus once; an adaptive design presents it at the value its
procedure chose: a wave's SOA, a train's frequency or signal length, or the stroke of the pins
it drives (how far each lifts from its down position, which the device's calibration then
holds for the trial). `adapted` makes the protocol and condition one trial presents; the
design's reader checks every value of the design through `adapted_drives` before a trial runs.
"""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction
from typing import TYPE_CHECKING

from pinarray.errors import PinArrayError
from pinarray.protocol.model import (
    Condition,
    Device,
    Frames,
    PathWave,
    Pattern,
    PatternStimulus,
    PinDrive,
    Protocol,
    Stimulus,
    Train,
    TrainShape,
    TrainStimulus,
    Wave,
    WaveStimulus,
)
from pinarray.protocol.procedures import Parameter
from pinarray.units import NS_PER_MS

if TYPE_CHECKING:
    from pinarray.protocol.seam import ParadigmDesign


def _train(train: Train | TrainShape, parameter: Parameter, value: Fraction) -> Train | TrainShape:
    match parameter:
        case Parameter.FREQUENCY_HZ:
            return train.with_frequency(value)
        case Parameter.DURATION_MS:
            return replace(train, duration_ns=round(value * NS_PER_MS))
    return train


def adapted_stimulus(stimulus: Stimulus, parameter: Parameter, value: Fraction) -> Stimulus:
    """``stimulus`` with ``parameter`` at ``value`` (a stroke leaves the stimulus as it is)."""
    match stimulus:
        case WaveStimulus(wave=Wave() | PathWave() as wave):
            if parameter is Parameter.SOA_MS:
                return replace(stimulus, wave=replace(wave, soa_ns=round(value * NS_PER_MS)))
            train = _train(wave.train, parameter, value)
            assert isinstance(train, Train)  # a wave's train has its frequency
            return replace(stimulus, wave=replace(wave, train=train))
        case TrainStimulus(train=train):
            if parameter is Parameter.SOA_MS:
                raise PinArrayError(f"expected a stimulus with an SOA (frames or a wave), found "
                                    f"{stimulus.name!r}, a pulse train")
            return replace(stimulus, train=_train(train, parameter, value))
        case PatternStimulus(shape=Frames() as frames) if parameter is Parameter.SOA_MS:
            return replace(stimulus, shape=replace(frames, soa_ns=round(value * NS_PER_MS)))
        case PatternStimulus(shape=Frames() as frames):
            return replace(stimulus, shape=replace(frames, frames=tuple(
                (name, _pattern(pattern, parameter, value)) for name, pattern in frames.frames)))
        case PatternStimulus(shape=Pattern() as pattern):
            if parameter is Parameter.SOA_MS:
                raise PinArrayError(f"expected a stimulus with an SOA (frames or a wave), found "
                                    f"{stimulus.name!r}, one pattern")
            return replace(stimulus, shape=_pattern(pattern, parameter, value))
    raise AssertionError(stimulus)


def _pattern(pattern: Pattern, parameter: Parameter, value: Fraction) -> Pattern:
    train = _train(pattern.train, parameter, value)
    assert isinstance(train, Train)  # a pattern's train has its frequency
    return replace(pattern, train=train)


def drives_of(stimulus: Stimulus) -> tuple[PinDrive, ...]:
    """What a stimulus with pins of its own plays (a pattern, a wave), as it is written."""
    match stimulus:
        case PatternStimulus(shape=shape):
            return shape.drives()
        case WaveStimulus(wave=wave):
            return wave.drives()
    raise PinArrayError(f"expected a stimulus with pins of its own (a pattern or a wave), found "
                        f"{stimulus.name!r}, a pulse train")


def stroke_device(device: Device, pins: set[int], train: Train, stroke: Fraction) -> Device:
    """``device`` with each of ``pins`` lifting ``stroke`` (steps, or us of width) from the
    position of ``train``'s down pulse when given its up pulse; a stroke past a pin's
    calibrated limits is refused, naming the pin."""
    if stroke.denominator != 1:
        raise PinArrayError(f"expected a stroke in whole {device.servo.position_unit}, found "
                            f"{float(stroke):g}")
    calibrations = list(device.pins)
    for pin in sorted(pins):
        calibration = device.calibration(pin)
        up = calibration.position_for_width(train.up_width_ns)
        down = calibration.position_for_width(train.down_width_ns)
        lifted = down + (1 if up >= down else -1) * int(stroke)
        if not calibration.min_steps <= lifted <= calibration.max_steps:
            raise PinArrayError(
                f"pin {pin}: expected a stroke within its calibrated limits "
                f"{calibration.min_steps}..{calibration.max_steps}, found {stroke} "
                f"{device.servo.position_unit}, which lifts it to {lifted}")
        positions = dict(calibration.positions_by_width_ns) | {train.up_width_ns: lifted}
        calibrations[pin - 1] = replace(calibration,
                                        positions_by_width_ns=tuple(sorted(positions.items())))
    return replace(device, pins=tuple(calibrations))


def adapted_drives(paradigm: ParadigmDesign, device: Device, stimulus: Stimulus,
                   condition: Condition, parameter: Parameter,
                   value: Fraction) -> tuple[Device, tuple[PinDrive, ...]]:
    """What one trial at ``value`` drives, and the device it plays on."""
    played = (stimulus if paradigm.adapts_condition(condition)
              else adapted_stimulus(stimulus, parameter, value))
    drives = paradigm.drives(played, paradigm.adapt(condition, parameter, value))
    if parameter.is_stroke:
        device = stroke_device(device, {d.pin for d in drives}, drives[0].train, value)
    return device, drives


def adapted(protocol: Protocol, condition: Condition, parameter: Parameter,
            value: Fraction) -> tuple[Protocol, Condition]:
    """The protocol and condition of a trial presenting ``condition`` at ``value``."""
    paradigm = protocol.design.paradigm
    stimulus = protocol.stimulus(condition.stimulus)
    device, _ = adapted_drives(paradigm, protocol.device, stimulus, condition, parameter, value)
    stimuli = tuple(adapted_stimulus(s, parameter, value)
                    if s is stimulus and not paradigm.adapts_condition(condition) else s
                    for s in protocol.stimuli)
    return (replace(protocol, device=device, stimuli=stimuli),
            paradigm.adapt(condition, parameter, value))
