"""Stimuli built in code, read by the protocol's own readers.

A script's ``pinarray.Train(frequency_hz=5, duration_s=1)`` is not checked by a second
validator: each argument becomes the YAML node a protocol file would hold (``frequency_hz:
5``), marked with the argument's name instead of a line and column, and is read by the very
functions that read a protocol's stimuli section (`read_train`, `read_pattern`,
`read_frames`, `read_wave`: the same fields, ranges, pins on the grid, trains each pin can
follow, no pin driven twice at once, the servo bus, a trial's pulses). A problem is then said
at the argument (``pinarray.Train: duty_cycle: expected a duty cycle ...``) rather than at
``file:line:col``, in one line.

The values given here are already of the right Python kinds (`pinarray.api.stimuli` checks
them at the door): ints, exact numbers written as text (``0.1``, ``1/3``), strs, lists and
mappings of them. Pure Python, like the rest of the protocol.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeAlias

from yaml import MappingNode, Mark, Node, ScalarNode, SequenceNode

from pinarray.errors import PinArrayError, ProtocolError
from pinarray.protocol.design import LONGER_IN_CODE, check_trial_pulses
from pinarray.protocol.drives import pulse_slots
from pinarray.protocol.model import (
    AnyWave,
    Device,
    Frames,
    Pattern,
    PatternStimulus,
    PinDrive,
    Stimulus,
    Train,
    TrainStimulus,
)
from pinarray.protocol.patterns import read_frames, read_pattern
from pinarray.protocol.stimuli import read_train, read_wave
from pinarray.protocol.yaml_nodes import Invalid, Reader

_TAG = "tag:yaml.org,2002:"


@dataclass(frozen=True)
class Number:
    """An exact number as a protocol writes it (``5``, ``0.1``, ``1/3``): the reader reads it."""

    text: str


# What an argument is, as the reader sees it: a whole number, an exact number, text, a list
# or a mapping of them (None: the argument was not given, the key is left out).
Value: TypeAlias = "int | Number | str | Sequence[Value] | Mapping[str, Value] | None"


class ArgumentReader(Reader):
    """A `Reader` whose problems are said at the argument a node stands for (its mark's name),
    not at a line and column: ``pinarray.Train: duty_cycle: expected ...``."""

    def error(self, node: Node | None, message: str) -> Invalid:
        where = node.start_mark.name if node is not None else ""
        self.errors.append(ProtocolError(message, f"{self.source}: {where}" if where
                                         else self.source))
        return Invalid(message)

    def raise_first(self) -> None:
        """The first problem as one line (how many more there are, if any)."""
        if self.errors:
            more = len(self.errors) - 1
            raise PinArrayError(self.errors[0].located()
                                + (f" (and {more} more problem{'s' * (more > 1)})" if more else ""))


def node(value: Value, at: str) -> Node:
    """The YAML node a protocol would hold for ``value``, marked as the argument ``at``."""
    mark = Mark(at, 0, 0, 0, None, None)
    match value:
        case bool():
            raise TypeError(f"{at}: {value!r}")  # refused at the door: never a number here
        case int():
            return ScalarNode(f"{_TAG}int", str(value), mark, mark)
        case Number(text=text) | str(text):
            return ScalarNode(f"{_TAG}str", text, mark, mark)
        case Mapping():
            pairs = [(ScalarNode(f"{_TAG}str", key, mark, mark), node(item, f"{at}[{key!r}]"))
                     for key, item in value.items() if item is not None]
            return MappingNode(f"{_TAG}map", pairs, mark, mark)
        case Sequence():
            return SequenceNode(f"{_TAG}seq", [node(item, f"{at}[{i}]")
                                               for i, item in enumerate(value)], mark, mark)
    raise TypeError(f"{at}: {value!r}")


def _fields(arguments: Mapping[str, Value], at: str) -> Node:
    """A stimulus's arguments as the mapping a protocol's stimulus is, each value marked with
    its argument's name (``at``: where the stimulus itself is, for problems of the whole)."""
    mark = Mark(at, 0, 0, 0, None, None)
    pairs = [(ScalarNode(f"{_TAG}str", key, mark, mark), node(value, _joined(at, key)))
             for key, value in arguments.items() if value is not None]
    return MappingNode(f"{_TAG}map", pairs, mark, mark)


def _joined(at: str, key: str) -> str:
    return f"{at}.{key}" if at else key


def read_code_train(what: str, arguments: Mapping[str, Value]) -> Train:
    """A train from its arguments (named as in a protocol's train), read as a protocol's
    train is; a `PinArrayError` naming the first argument that is wrong (``what``: the call)."""
    reader = ArgumentReader(what)
    train = reader.attempt(lambda: read_train(reader, _fields(arguments, "")), None)
    reader.raise_first()
    if not isinstance(train, Train):  # read_train said why, unless the frequency is missing
        raise PinArrayError(f"{what}: frequency_hz: expected a frequency in Hz, found none")
    return train


@dataclass(frozen=True)
class CodePattern:
    """A pattern's arguments: pins (numbers, or a drawing), its train, a phase or None."""

    pins: Sequence[int] | str
    train: Train
    phase_deg: Number | None = None


@dataclass(frozen=True)
class CodeFrames:
    """Frames' arguments: their patterns in order and the time between them."""

    frames: tuple[CodePattern, ...]
    soa_ms: Number


@dataclass(frozen=True)
class CodeWave:
    """A wave's arguments, as a protocol's wave names them (None: not given)."""

    wave: str
    train: Train
    row: int | None = None
    pins: Sequence[int] | None = None
    direction: str | None = None
    soa_ms: Number | None = None


CodeStimulus = CodePattern | CodeFrames | CodeWave

# The name a code-built stimulus's train goes by while it is read (a protocol names its trains).
_TRAIN = "train"


def drives_on(device: Device, what: str, stimulus: CodeStimulus) -> tuple[PinDrive, ...]:
    """What ``stimulus`` drives on ``device``, checked as a protocol's stimulus is there: pins
    on its grid, trains each pin can follow, no pin driven twice at once, the servo bus, the
    pulses one trial may hold; a `PinArrayError` (``what``: the call and the stimulus's kind)
    naming the argument at fault, before anything is played."""
    reader = ArgumentReader(what)
    shape = reader.attempt(lambda: _shape(reader, device, stimulus), None)
    reader.raise_first()
    assert shape is not None  # a shape not read has its problem in the reader
    drives = shape.drives()
    where = _fields({}, "")
    reader.attempt(lambda: check_trial_pulses(
        reader, where, sum(pulse_slots(d.train) for d in drives), long_trials=False,
        longer=LONGER_IN_CODE), None)
    reader.raise_first()
    return drives


def _shape(reader: Reader, device: Device, stimulus: CodeStimulus) -> Pattern | Frames | AnyWave:
    match stimulus:
        case CodePattern():
            return _pattern(reader, device, stimulus, "")
        case CodeFrames(frames=frames, soa_ms=soa_ms):
            patterns: dict[str, Stimulus] = {}
            for i, pattern in enumerate(frames):
                name = f"frames[{i}]"
                patterns[name] = PatternStimulus(name, _pattern(reader, device, pattern, name))
            return read_frames(reader, _fields({"frames": list(patterns), "soa_ms": soa_ms}, ""),
                               device, patterns, {})
        case CodeWave(wave=wave, train=train, row=row, pins=pins, direction=direction,
                      soa_ms=soa_ms):
            arguments = {"wave": wave, "row": row, "pins": pins, "direction": direction,
                         "train": _TRAIN, "soa_ms": soa_ms}
            return read_wave(reader, _fields(arguments, ""), device, _trains(train), {})


def _pattern(reader: Reader, device: Device, pattern: CodePattern, at: str) -> Pattern:
    # A protocol's pattern names its pins under ``pattern:``; here the argument is ``pins``.
    fields = _fields({"train": _TRAIN, "phase_deg": pattern.phase_deg}, at)
    pins = node(pattern.pins if isinstance(pattern.pins, str) else list(pattern.pins),
                _joined(at, "pins"))
    fields.value.append((ScalarNode(f"{_TAG}str", "pattern", pins.start_mark, pins.end_mark),
                         pins))
    return read_pattern(reader, fields, device, _trains(pattern.train), {})


def _trains(train: Train) -> Mapping[str, Stimulus]:
    return {_TRAIN: TrainStimulus(_TRAIN, train)}
