"""The validated protocol: device calibration, stimuli and experiment design as frozen values.

Built by `pinarray.protocol.load` from YAML; everything here is already checked, so the
compiler and the player never see a bad number. Frequencies and durations are exact
(`fractions.Fraction` or integer nanoseconds): a 0.1 s period is not a binary float.

Past 400 lines on purpose: the values every section of a protocol is made of, one frozen type
each, read together. What a trial presents and asks is its paradigm's (`Condition`: each
paradigm's room, `pinarray.paradigms`, defines its own).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from enum import StrEnum
from fractions import Fraction
from typing import TYPE_CHECKING, ClassVar, TypeAlias

from pinarray.errors import PinArrayError
from pinarray.grid import Grid
from pinarray.protocol.procedures import Adaptive
from pinarray.units import NS_PER_S

if TYPE_CHECKING:
    from pinarray.protocol.imaging import ScannerSync
    from pinarray.protocol.response import MeasuredResponse
    from pinarray.protocol.seam import ParadigmDesign

# Baud rates the STS servos (and the SDK's port handler) support, in bit/s.
BAUD_RATES = (38_400, 57_600, 115_200, 128_000, 250_000, 500_000, 1_000_000)

# The smallest stroke a bus servo's pin may be asked for, in steps: one more than the steps
# within which a sampled pin counts as at its goal (`pinarray.hardware.motion.ARRIVAL_STEPS`,
# 3), so that a pin that never moved can neither seem to arrive at its up goal nor, with a
# step of read-out jitter, measure the share of the stroke a delivered trial needs.
MIN_STROKE_STEPS = 4


@dataclass(frozen=True)
class ServoSettings:
    """What playback sets on every servo (RAM only, never EEPROM).

    ``acceleration_register`` is in the servo's units of 100 step/s^2; 0 means the servo's own
    maximum, which the feasibility check treats as unlimited (speed-limited motion).
    ``return_delay_us`` is how long each servo waits before it answers a read (the factory's
    500 us until `pinarray servos return-delay` lowers it): what the bus check counts for
    each read-back (`pinarray.protocol.bus`).
    """

    model: str = "STS3215"
    baud_rate: int = 1_000_000
    speed_steps_per_s: int = 3000
    acceleration_register: int = 0
    steps_per_turn: int = 4096
    return_delay_us: int = 500

    @property
    def acceleration_steps_per_s2(self) -> int | None:
        """Acceleration limit in step/s^2, or None for the servo's maximum."""
        return self.acceleration_register * 100 or None

    @property
    def position_unit(self) -> str:
        """What a pin's positions count: the servo's encoder steps."""
        return "steps"

    def degrees(self, steps: float) -> float:
        """A travel in steps as the horn's angle."""
        return steps * 360.0 / self.steps_per_turn


@dataclass(frozen=True)
class Pca9685Board:
    """A PCA9685 16-channel PWM board on an I2C bus (the device's ``port``).

    ``osc_hz`` is this board's oscillator as measured (nominally 25 MHz, boards are off by up
    to several percent; docs/rig/pwm.md: "Measuring a board's oscillator"); ``pwm_hz`` is the pulse
    rate used when a trial's pulses do not set one (trains of different rates at once).
    """

    address: int = 0x40
    osc_hz: int = 25_000_000
    pwm_hz: int = 50


@dataclass(frozen=True)
class HobbyServos:
    """Hobby PWM servos (the seed's kind) on a PCA9685 board: a pulse's width sets the angle.

    A pin's positions are pulse widths in microseconds. ``speed_us_per_s`` is how fast the
    servo follows a change of width (an SG90's 0.1 s per 60 deg, with 1000 us per 90 deg, is
    about 6667 us/s); ``degrees_per_us`` turns width into horn angle for the lab's reports.
    """

    board: Pca9685Board = Pca9685Board()
    model: str = "SG90"
    speed_us_per_s: int = 6667
    dead_band_us: int = 8
    degrees_per_us: Fraction = Fraction(9, 100)

    @property
    def speed_steps_per_s(self) -> int:
        """Speed in the pins' position unit (us of pulse width) per second."""
        return self.speed_us_per_s

    @property
    def acceleration_steps_per_s2(self) -> None:
        """Hobby servos state no acceleration: motion is speed-limited."""
        return None

    @property
    def position_unit(self) -> str:
        return "us"

    def degrees(self, width_us: float) -> float:
        return width_us * float(self.degrees_per_us)


# The family of servo a device is built of: STS bus servos, or hobby servos on a PWM board.
Servos = ServoSettings | HobbyServos


@dataclass(frozen=True)
class PinCalibration:
    """One pin's servo and calibrated positions, in servo steps.

    ``positions_by_width_ns`` maps a hobby-servo pulse width to the position it commands (the
    seed drove its servos with 1.5 ms and 2 ms pulses); ``min_steps``..``max_steps`` are the
    calibrated stroke limits no command may leave; ``lever_mm`` turns angle into pin travel.
    """

    pin: int
    servo_id: int
    rest_steps: int
    min_steps: int
    max_steps: int
    positions_by_width_ns: tuple[tuple[int, int], ...]
    lever_mm: float = 6.0

    def position_for_width(self, width_ns: int) -> int:
        for width, position in self.positions_by_width_ns:
            if width == width_ns:
                return position
        known = ", ".join(f"{exact_words(Fraction(w, 1_000_000))} ms"
                          for w, _ in self.positions_by_width_ns)
        raise PinArrayError(
            f"pin {self.pin}: expected a pulse width it is calibrated for ({known}), found "
            f"{exact_words(Fraction(width_ns, 1_000_000))} ms"
        )


def exact_words(value: Fraction) -> str:
    """A number for a message: short (``0.3``, ``2``) when that is the number exactly, else as
    many digits as tell it apart (``2.000001``, ``0.30000001192092896``; a float32's 0.3)."""
    short = f"{float(value):g}"
    if Fraction(short) == value:
        return short
    closest = repr(float(value))
    return closest if Fraction(closest) == value else f"{float(value):.17g}"


SIMULATED_PORT = "sim://"  # a protocol without a port plays on the simulated array


def is_simulated(port: str) -> bool:
    """Whether ``port`` names the in-process simulated array (``sim://``, with settings or
    not) rather than a serial device."""
    return port.startswith(SIMULATED_PORT)


@dataclass(frozen=True)
class Datasheet:
    """Whether a pin can follow a train is judged from the servo settings' speed and
    acceleration (the protocol names no measured response)."""


DATASHEET = Datasheet()
# What the feasibility check rests on: datasheet figures, or a servo's measured response.
Bandwidth: TypeAlias = "Datasheet | MeasuredResponse"


@dataclass(frozen=True)
class Device:
    """The stimulator: grid, servo settings and one calibration per pin.

    ``servo`` says the family: `ServoSettings` (Feetech STS bus servos; a pin's ``servo_id``
    is its bus id, positions in encoder steps) or `HobbyServos` (a PCA9685 board; a pin's
    ``servo_id`` is its channel 0-15, positions are pulse widths in microseconds).
    """

    grid: Grid
    servo: Servos
    pins: tuple[PinCalibration, ...]
    port: str = SIMULATED_PORT
    scale_infeasible: bool = False  # scale strokes the servo cannot follow instead of refusing
    # A trial counts as delivered when every goal change reached its servo within this.
    delivery_tolerance_ns: int = 10_000_000
    # ... and, where the servos report their position, every moving pin's achieved stroke
    # was at least this share of its commanded stroke (device: stroke_tolerance_percent).
    stroke_tolerance: Fraction = Fraction(8, 10)
    bandwidth: Bandwidth = DATASHEET  # device: response: names a measured one

    def feasibility_basis(self) -> str:
        """What the feasibility check rests on, as the pre-flight says it."""
        if isinstance(self.bandwidth, Datasheet):
            accel = self.servo.acceleration_steps_per_s2
            return (f"datasheet figures ({self.servo.speed_steps_per_s} {self.servo.position_unit}/s"
                    f", acceleration {'unlimited' if accel is None else f'{accel}/s^2'})")
        return self.bandwidth.describe()

    def calibration(self, pin: int) -> PinCalibration:
        self.grid.check_pin(pin)
        return self.pins[pin - 1]

    def mm_per_step(self, pin: int) -> float:
        """How far ``pin`` travels for one position unit (a step; us on a PWM board), mm:
        the horn's angle on its lever, as the feasibility check describes a stroke."""
        return self.calibration(pin).lever_mm * math.radians(self.servo.degrees(1))


@dataclass(frozen=True)
class Train:
    """A periodic pulse train for one pin: the seed's per-channel parameters.

    Each cycle of ``1/frequency_hz`` holds ``pulses_per_cycle`` servo pulses in equal slots; the
    first ``up_pulses`` have width ``up_width_ns`` (pin lifted), the rest ``down_width_ns``.
    The seed's train is 10 pulses a cycle, 5 up (2 ms) and 5 down (1.5 ms).
    ``phase``, a fraction of a cycle in [0, 1), shifts the cycle circularly within the signal:
    pulse ``k`` of the endless train (``k = 0`` the first up pulse of a cycle) starts
    ``(k + phase * pulses_per_cycle)`` slots after the signal starts, and those that start at
    or after that and end within ``duration_ns`` play. The signal's start and length do not
    move: the first up pulse comes ``phase`` of a period late, the slots before it playing the
    end of a cycle (at phase 1/2, the seed's train begins with its five down pulses), and
    where ``phase * pulses_per_cycle`` is not whole every pulse is off the slot grid by its
    remainder, the signal's first fraction of a slot left without a pulse.
    """

    frequency_hz: Fraction
    duration_ns: int
    pulses_per_cycle: int = 10
    up_pulses: int = 5
    up_width_ns: int = 2_000_000
    down_width_ns: int = 1_500_000
    phase: Fraction = Fraction(0)

    @property
    def duty_cycle(self) -> Fraction:
        return Fraction(self.up_pulses, self.pulses_per_cycle)

    @property
    def slot_ns(self) -> Fraction:
        """Exact time between pulse starts, in nanoseconds."""
        return NS_PER_S / (self.frequency_hz * self.pulses_per_cycle)

    def with_frequency(self, frequency_hz: Fraction) -> Train:
        return replace(self, frequency_hz=frequency_hz)


@dataclass(frozen=True)
class TrainShape:
    """A pulse train without its frequency: a localisation design's ``frequencies_hz`` give it.

    The fields mean what `Train`'s do; only `with_frequency` makes a train that can play.
    """

    duration_ns: int
    pulses_per_cycle: int = 10
    up_pulses: int = 5
    up_width_ns: int = 2_000_000
    down_width_ns: int = 1_500_000
    phase: Fraction = Fraction(0)

    def with_frequency(self, frequency_hz: Fraction) -> Train:
        return Train(frequency_hz, self.duration_ns, self.pulses_per_cycle, self.up_pulses,
                     self.up_width_ns, self.down_width_ns, self.phase)


class WaveKind(StrEnum):
    RIGHTWARDS = "rightwards"  # along a row, left to right
    LEFTWARDS = "leftwards"  # along a row, right to left
    NONE = "none"  # the seed's "no wave": the central pin alternates with the lateral ones
    UPWARDS = "upwards"  # up a column, its pins listed bottom to top
    DOWNWARDS = "downwards"  # down a column, its pins listed top to bottom
    SEQUENCE = "sequence"  # any pins, in the order listed, going the direction it names


class Direction(str):
    """Which way a travelling wave goes, as a subject would name it.

    left, right (rows), up, down (columns), none (the no-wave control), or a name a sequence
    wave declares (``up-right``): lowercase words joined by hyphens.
    """

    LEFT: ClassVar[Direction]
    RIGHT: ClassVar[Direction]
    UP: ClassVar[Direction]
    DOWN: ClassVar[Direction]
    NONE: ClassVar[Direction]

    @property
    def value(self) -> str:
        return str(self)


Direction.LEFT, Direction.RIGHT = Direction("left"), Direction("right")
Direction.UP, Direction.DOWN = Direction("up"), Direction("down")
Direction.NONE = Direction("none")  # the no-wave control: no direction to name
DIRECTION_NAME = re.compile(r"[a-z]+(-[a-z]+)*")
MAX_DIRECTION_CHARS = 24

DIRECTION_OF_WAVE = {WaveKind.RIGHTWARDS: Direction.RIGHT, WaveKind.LEFTWARDS: Direction.LEFT,
                     WaveKind.NONE: Direction.NONE, WaveKind.UPWARDS: Direction.UP,
                     WaveKind.DOWNWARDS: Direction.DOWN}


# Words a sequence wave may not take for its direction: answers of their own ("none": felt
# nothing move; "unsure": felt something move, could not say which way).
RESERVED_DIRECTION_NAMES = ("none", "unsure")


@dataclass(frozen=True)
class PinDrive:
    """One train played on one pin, starting ``delay_ns`` after the trial's stimulus onset."""

    pin: int
    train: Train
    delay_ns: int = 0


@dataclass(frozen=True)
class Wave:
    """A travelling wave (or the seed's no-wave control) along pins of one row.

    Step ``i`` starts at ``i * soa_ns``; a sweep visits the pins left to right (rightwards) or
    right to left (leftwards); the no-wave alternates the central pin and the two lateral ones
    for the same number of steps.
    """

    kind: WaveKind
    row: int  # 1 = bottom row, as the lab counts
    pins: tuple[int, ...]  # left to right
    train: Train
    soa_ns: int

    @property
    def direction(self) -> Direction:
        return DIRECTION_OF_WAVE[self.kind]

    def drives(self) -> tuple[PinDrive, ...]:
        if self.kind is WaveKind.NONE:
            centre = len(self.pins) // 2
            laterals = (self.pins[centre - 1], self.pins[centre + 1])
            steps = [
                (self.pins[centre],) if i % 2 == 0 else laterals for i in range(len(self.pins))
            ]
        else:
            order = self.pins if self.kind is WaveKind.RIGHTWARDS else self.pins[::-1]
            steps = [(pin,) for pin in order]
        return tuple(
            PinDrive(pin, self.train, i * self.soa_ns)
            for i, group in enumerate(steps)
            for pin in group
        )


@dataclass(frozen=True)
class PathWave:
    """A travelling wave visiting its pins in the order listed: up or down a column, or any
    sequence going the direction it names. Step ``i`` (pin ``pins[i]``) starts at ``i * soa_ns``.
    """

    kind: WaveKind  # upwards, downwards or sequence
    direction: Direction
    pins: tuple[int, ...]  # in the order visited
    train: Train
    soa_ns: int

    def drives(self) -> tuple[PinDrive, ...]:
        return tuple(PinDrive(pin, self.train, i * self.soa_ns) for i, pin in enumerate(self.pins))


AnyWave = Wave | PathWave


@dataclass(frozen=True)
class Pattern:
    """Pins raised together: each moves with ``train`` (the pattern's, at its phase)."""

    pins: tuple[int, ...]  # ascending
    train: Train

    def drives(self) -> tuple[PinDrive, ...]:
        return tuple(PinDrive(pin, self.train) for pin in self.pins)


@dataclass(frozen=True)
class Frames:
    """Patterns in time: frame ``i`` (a named pattern) starts ``i * soa_ns`` after onset."""

    frames: tuple[tuple[str, Pattern], ...]
    soa_ns: int

    def drives(self) -> tuple[PinDrive, ...]:
        return tuple(PinDrive(pin, pattern.train, i * self.soa_ns)
                     for i, (_, pattern) in enumerate(self.frames) for pin in pattern.pins)


@dataclass(frozen=True)
class PatternStimulus:
    """A named pattern on the grid, or a sequence of patterns in time (``frames``)."""

    name: str
    shape: Pattern | Frames

    @property
    def pins(self) -> tuple[int, ...]:
        """Every pin it raises, ascending."""
        return tuple(sorted({drive.pin for drive in self.shape.drives()}))


@dataclass(frozen=True)
class TrainStimulus:
    """A named pulse train; the design chooses the pin (and may change the frequency).

    A `TrainShape` (no ``frequency_hz``) plays only at a localisation design's frequencies.
    """

    name: str
    train: Train | TrainShape


@dataclass(frozen=True)
class WaveStimulus:
    """A named travelling wave (or no-wave control): its pins are its own."""

    name: str
    wave: AnyWave


Stimulus = TrainStimulus | WaveStimulus | PatternStimulus


class Ordering(StrEnum):
    SEQUENTIAL = "sequential"  # conditions as listed, every block
    RANDOM = "random"  # shuffled within each block
    FULL_RANDOM = "full_random"  # shuffled across all blocks
    LATIN_SQUARE = "latin_square"  # balanced Latin square rows, one per block


@dataclass(frozen=True)
class Condition:
    """What one trial presents and asks: a stimulus of the protocol, as a paradigm presents it.

    Each paradigm's conditions are a frozen subclass of its own (its room in
    `pinarray.paradigms` says what they hold and how they play: `ParadigmDesign.drives`),
    which names the paradigm (``paradigm``, as a design's ``paradigm:`` does).
    """

    paradigm: ClassVar[str] = ""
    stimulus: str

    @property
    def key(self) -> tuple:
        """What tells the conditions of a design apart (and orders them alike in every plan)."""
        raise NotImplementedError


def condition_value(condition: Condition, attribute: str) -> object:
    """A condition's value of an attribute an order constraint names (``pin``, ``direction``...).

    A constraint may name an attribute the paradigm's conditions lack (a localisation design
    that may not repeat a direction): all of them then share the value None.
    """
    return getattr(condition, attribute, None)


@dataclass(frozen=True)
class Constraints:
    """Ordering constraints on consecutive trials.

    ``no_repeat`` names condition attributes that may not repeat on consecutive trials
    (e.g. ``pin``); ``max_run`` caps how many consecutive trials may share an attribute value.
    """

    no_repeat: tuple[str, ...] = ()
    max_run: tuple[tuple[str, int], ...] = ()

    def limits(self) -> dict[str, int]:
        limits = {attribute: 1 for attribute in self.no_repeat}
        for attribute, length in self.max_run:
            limits[attribute] = min(length, limits.get(attribute, length))
        return limits


@dataclass(frozen=True)
class Design:
    """Blocks of trials for one paradigm, how they are ordered, and the pauses between them.

    ``paradigm`` is the paradigm's room (`pinarray.protocol.seam.ParadigmDesign`): it read the
    conditions and ``judgement`` (what the subject judges, in its own terms; None where the
    conditions say it all) and says what a trial of the design asks.
    """

    paradigm: ParadigmDesign
    conditions: tuple[Condition, ...]  # one block's worth, before repetitions
    repetitions: int  # each condition this many times per block
    blocks: int
    ordering: Ordering
    constraints: Constraints
    seed: int | None
    inter_trial_interval_ns: int
    practice_trials: int
    # An adaptive design: each trial's value of one parameter is chosen by its procedures
    # (``conditions`` are then what a trial draws from at random); None: a fixed design.
    adaptive: Adaptive | None = None
    judgement: object = None

    def answers(self, pin_count: int) -> tuple[str, ...]:
        """Every answer a trial of this design takes, as the results write it (``pin_count``:
        the grid's pins, which an answer may name)."""
        return self.paradigm.answers(self, pin_count)

    @property
    def trial_count(self) -> int:
        """Trials in every plan of this design, practice included (numbered 1..this); an
        adaptive design's, the most its procedures can take (they may finish earlier)."""
        if self.adaptive is not None:
            return (self.adaptive.procedure_trials + self.adaptive.catch.count
                    + self.practice_trials)
        return len(self.conditions) * self.repetitions * self.blocks + self.practice_trials


@dataclass(frozen=True)
class Protocol:
    """A validated protocol file: the device, the named stimuli and the design, frozen.

    Attributes
    ----------
    name, description : str
        As the file gives them (the name is the results' task label, letters and digits kept).
    device : Device
        The pins' servos, calibration, limits and tolerances.
    stimuli : tuple of TrainStimulus, WaveStimulus or PatternStimulus
        The named pulse trains, travelling waves and patterns.
    design : Design
        The paradigm, its conditions, blocks, order, seed and adaptive procedures, if any.
    source : str
        The file it was read from (every located error names it).
    sha256 : str
        The file's SHA-256: a resumed run must have started with the same file.
    sync : ScannerSync or None
        The scanner section (``sync:``), if the protocol has one.
    """

    name: str
    description: str
    device: Device
    stimuli: tuple[Stimulus, ...]
    design: Design
    source: str = "<protocol>"
    sha256: str = ""
    sync: ScannerSync | None = None  # the scanner section, if the protocol has one

    def stimulus(self, name: str) -> Stimulus:
        """The stimulus called ``name`` (a `PinArrayError` naming the file if none is)."""
        for stimulus in self.stimuli:
            if stimulus.name == name:
                return stimulus
        raise PinArrayError(f"{self.source}: no stimulus named {name!r}")

    def wave(self, name: str) -> AnyWave:
        """The wave of the wave stimulus ``name``."""
        stimulus = self.stimulus(name)
        if not isinstance(stimulus, WaveStimulus):
            raise PinArrayError(f"{self.source}: expected a wave stimulus, found pulse train {name!r}")
        return stimulus.wave
