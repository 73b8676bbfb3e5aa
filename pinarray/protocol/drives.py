"""Which pins a trial drives, and whether any pin is driven twice at once. Pure Python.

Kept apart from `pinarray.schedule` (numpy) so that `pinarray validate`, which needs only
these checks, starts without loading numpy.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

from pinarray.errors import PinArrayError
from pinarray.protocol.model import (
    Condition,
    LocalisationCondition,
    MotionCondition,
    PatternStimulus,
    PinDrive,
    Protocol,
    Stimulus,
    Train,
    TrainStimulus,
    WaveStimulus,
)
from pinarray.protocol.paradigms import (
    IdentificationCondition,
    TemporalOrderCondition,
    TwoIntervalCondition,
)


def check_no_overlap(drives: Sequence[PinDrive]) -> None:
    """Refuse drives that play two trains on one pin at the same time.

    A train may start at the very nanosecond the previous one on its pin ends.
    """
    by_pin: dict[int, list[PinDrive]] = {}
    for drive in drives:
        by_pin.setdefault(drive.pin, []).append(drive)
    for pin, pin_drives in by_pin.items():
        pin_drives.sort(key=lambda d: d.delay_ns)
        for before, after in itertools.pairwise(pin_drives):
            if before.delay_ns + before.train.duration_ns > after.delay_ns:
                raise PinArrayError(
                    f"pin {pin} is driven twice at once: a train from {before.delay_ns / 1e6:g} ms "
                    f"lasting {before.train.duration_ns / 1e6:g} ms overlaps one starting at "
                    f"{after.delay_ns / 1e6:g} ms; lengthen the SOA or shorten the train"
                )


def trial_drives(protocol: Protocol, condition: Condition) -> tuple[PinDrive, ...]:
    """The pin drives a design condition asks for."""
    try:
        return stimulus_drives(protocol.stimulus(condition.stimulus), condition)
    except PinArrayError as problem:
        raise PinArrayError(f"{protocol.source}: {problem}") from None


def stimulus_drives(stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
    """The pin drives ``stimulus`` plays for ``condition``."""
    match stimulus, condition:
        case WaveStimulus(wave=wave), MotionCondition():
            return wave.drives()
        case TrainStimulus(train=train), LocalisationCondition(pin=pin, frequency_hz=frequency_hz):
            return (PinDrive(pin, train.with_frequency(frequency_hz), 0),)
        case PatternStimulus(shape=shape), IdentificationCondition():
            return shape.drives()
        case PatternStimulus() | WaveStimulus(), TwoIntervalCondition():
            return _two_intervals(stimulus, condition)
        case TrainStimulus(train=Train() as train), TemporalOrderCondition(pins=(a, b)):
            first, second = condition.delays_ns
            return (PinDrive(a, train, first), PinDrive(b, train, second))
    raise PinArrayError(f"stimulus {stimulus.name!r} cannot present a {type(condition).__name__}")


def _two_intervals(stimulus: Stimulus, condition: TwoIntervalCondition) -> tuple[PinDrive, ...]:
    """The stimulus at the first interval's value, then, ``gap_ns`` after it ends, at the
    second's."""
    # Here, not at the top: a stimulus at a value is the adaptive designs' (which import this).
    from pinarray.protocol.adapted import adapted_stimulus

    first_value, second_value = condition.values_in_order
    first = _drives_of(adapted_stimulus(stimulus, condition.parameter, first_value))
    second = _drives_of(adapted_stimulus(stimulus, condition.parameter, second_value))
    start_ns = max(d.delay_ns + d.train.duration_ns for d in first) + condition.gap_ns
    return (*first, *(PinDrive(d.pin, d.train, start_ns + d.delay_ns) for d in second))


def _drives_of(stimulus: Stimulus) -> tuple[PinDrive, ...]:
    match stimulus:
        case PatternStimulus(shape=shape):
            return shape.drives()
        case WaveStimulus(wave=wave):
            return wave.drives()
    raise PinArrayError(f"stimulus {stimulus.name!r} has no pins of its own to play")


def pulse_slots(train: Train) -> int:
    """How many pulse slots start within the train's signal: what compiling it allocates.

    Counted as `pinarray.schedule` counts them (phase included); the pulses that also end
    within the signal may be one or two fewer.
    """
    offset_slots = train.phase * train.pulses_per_cycle
    first = -int(offset_slots)
    last = int(train.duration_ns / train.slot_ns - offset_slots)
    return max(0, last + 1 - first)
