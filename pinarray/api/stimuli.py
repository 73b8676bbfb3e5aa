"""Stimuli built in code: a pulse train, pins raised together, patterns in time, a travelling
wave, each what a protocol's ``stimuli`` section writes, made in a script without a file::

    tap = pinarray.Train(frequency_hz=5, duration_s=1)
    with pinarray.open_array() as array:
        delivery = array.present(pinarray.Pattern(pins=[6, 7, 10, 11], train=tap))

A train is read when it is made, by the protocol's own reader (`pinarray.protocol.in_code`):
the same fields, defaults and checks as a protocol's train, a wrong one named in one line. What
depends on the array (pins on its grid, each pin's calibrated stroke, the servos' speed, the
servo bus) is read when the stimulus meets an open array (`PinArray.present`, `arm`,
`prepare`), again by the protocol's readers, against that array's device, before anything
moves. Every value is exact (``0.1`` is 1/10, as a protocol reads it).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from pinarray.api import arguments
from pinarray.api.protocols import describe_condition
from pinarray.protocol import model
from pinarray.protocol.in_code import (
    CodeFrames,
    CodePattern,
    CodeStimulus,
    CodeWave,
    Number,
    Value,
    read_code_train,
)
from pinarray.protocol.model import Condition
from pinarray.units import NS_PER_MS, NS_PER_S

__all__ = ["Frames", "Pattern", "Train", "Wave"]

Real = float | Fraction
"""A number a stimulus takes: an int, a float or a `fractions.Fraction` (numpy's scalars too)."""


@dataclass(frozen=True, init=False, repr=False)
class Train:
    """A periodic pulse train, as a protocol's train writes it (the seed's per-channel
    parameters); it plays on the pins a `Pattern` or a `Wave` gives it.

    Each cycle of ``1 / frequency_hz`` holds ``pulses_per_cycle`` servo pulses; the first
    ``duty_cycle`` of them are ``pulse_width_ms["up"]`` wide (the pin lifted), the rest
    ``pulse_width_ms["down"]`` (at rest); ``phase_deg`` shifts the cycle circularly within the
    signal by that part of a cycle: the signal starts and lasts as written, its first up pulse
    comes that part of a period late, and the slots before it play the end of a cycle (at 180
    the seed's train begins with its five down pulses). The defaults are the seed's: 10 pulses a cycle, half of them up, 2 ms up and
    1.5 ms down. Each value is kept exact (a `fractions.Fraction`: 0.1 is 1/10) in the
    attribute of its name, the two widths as ``up_width_ms`` and ``down_width_ms``.

    Parameters
    ----------
    frequency_hz : float or Fraction
        Cycles a second, in Hz: above 0, at most 1000.
    duration_s : float or Fraction
        The signal's length, in s: above 0, whole nanoseconds, at least one pulse period.
    pulses_per_cycle : int
        Servo pulses in one cycle, 2 to 1000.
    duty_cycle : float or Fraction
        The share of a cycle's pulses that lift the pin: a whole number of its pulses,
        strictly between 0 and 1.
    pulse_width_ms : mapping or None
        ``{"up": 2.0, "down": 1.5}``: the two pulse widths, in ms (whole nanoseconds, each
        within the pulse period); None: the seed's.
    phase_deg : float or Fraction
        Where in its cycle the train starts, in degrees, 0 to 36000 (read modulo 360): the
        cycle shifted circularly within the signal, whose start and length do not move.

    Raises
    ------
    PinArrayError
        A wrong argument, named, with what was expected and found
        (``pinarray.Train: duty_cycle: expected a duty cycle strictly between 0 and 1 ...``).
    """

    frequency_hz: Fraction
    """Cycles a second, in Hz."""
    duration_s: Fraction
    """The signal's length, in s."""
    pulses_per_cycle: int
    """Servo pulses in one cycle."""
    duty_cycle: Fraction
    """The share of a cycle's pulses that lift the pin."""
    up_width_ms: Fraction
    """The width of a pulse that lifts the pin, in ms."""
    down_width_ms: Fraction
    """The width of a pulse at rest, in ms."""
    phase_deg: Fraction
    """Where in its cycle the train starts, in degrees, 0 up to 360 (the cycle shifted
    circularly within the signal)."""

    def __init__(self, *, frequency_hz: Real, duration_s: Real, pulses_per_cycle: int = 10,
                 duty_cycle: Real = Fraction(1, 2),
                 pulse_width_ms: Mapping[str, Real] | None = None,
                 phase_deg: Real = 0) -> None:
        call = "pinarray.Train"
        given: dict[str, Value] = {
            "frequency_hz": _number(call, "frequency_hz", frequency_hz),
            "duration_s": _number(call, "duration_s", duration_s),
            "pulses_per_cycle": _whole(call, "pulses_per_cycle", pulses_per_cycle),
            "duty_cycle": _number(call, "duty_cycle", duty_cycle),
            "pulse_width_ms": _widths(call, pulse_width_ms),
            "phase_deg": _number(call, "phase_deg", phase_deg),
        }
        train = read_code_train(call, given)
        values = {
            "frequency_hz": train.frequency_hz,
            "duration_s": Fraction(train.duration_ns, NS_PER_S),
            "pulses_per_cycle": train.pulses_per_cycle,
            "duty_cycle": train.duty_cycle,
            "up_width_ms": Fraction(train.up_width_ns, NS_PER_MS),
            "down_width_ms": Fraction(train.down_width_ns, NS_PER_MS),
            "phase_deg": train.phase * 360,
            "_train": train,
        }
        for name, value in values.items():
            object.__setattr__(self, name, value)

    @property
    def pulse_width_ms(self) -> dict[str, Fraction]:
        """``{"up": ..., "down": ...}``: the two pulse widths, in ms, as given."""
        return {"up": self.up_width_ms, "down": self.down_width_ms}

    def __repr__(self) -> str:
        widths = ", ".join(f"{key!r}: {_shown(value)}"
                           for key, value in self.pulse_width_ms.items())
        return (f"Train(frequency_hz={_shown(self.frequency_hz)}, "
                f"duration_s={_shown(self.duration_s)}, "
                f"pulses_per_cycle={self.pulses_per_cycle}, "
                f"duty_cycle={_shown(self.duty_cycle)}, pulse_width_ms={{{widths}}}, "
                f"phase_deg={_shown(self.phase_deg)})")

    if TYPE_CHECKING:  # not a field: what the protocol's model holds (set by __init__)
        _train: model.Train


@dataclass(frozen=True, init=False, repr=False)
class Pattern:
    """Pins raised together, each moving with ``train``: a protocol's pattern, made in code.

    Parameters
    ----------
    pins : sequence of int, or str
        The pins raised, numbered as the subject sees them on the array it is presented on
        (1 bottom-left), each once; or drawn as the subject feels the array, one line a row,
        the top row first (``"# . . .\\n# . . .\\n# . . .\\n# # # #"``: '#' raised, '.' at
        rest).
    train : Train
        The train every raised pin plays.
    phase_deg : float, Fraction or None
        Every raised pin at this phase of the train, in degrees (None: the train's own).

    Raises
    ------
    PinArrayError
        An argument of the wrong kind, named. The pins are read against the array's grid,
        and the whole pattern checked on its servos, when it is presented (`PinArray.present`).
    """

    pins: tuple[int, ...] | str
    """The pins raised, as given (numbers, or a drawing)."""
    train: Train
    """The train every raised pin plays."""
    phase_deg: Fraction | None
    """The phase every raised pin plays the train at, in degrees; None: the train's own."""

    def __init__(self, *, pins: Sequence[int] | str, train: Train,
                 phase_deg: Real | None = None) -> None:
        call = "pinarray.Pattern"
        object.__setattr__(self, "pins", _pins(call, "pins", pins))
        object.__setattr__(self, "train", _train(call, train))
        object.__setattr__(self, "phase_deg", None if phase_deg is None else
                           Fraction(_number(call, "phase_deg", phase_deg).text))

    def __repr__(self) -> str:
        phase = "" if self.phase_deg is None else f", phase_deg={_shown(self.phase_deg)}"
        return f"Pattern(pins={_shown_pins(self.pins)}, train={self.train!r}{phase})"


@dataclass(frozen=True, init=False, repr=False)
class Frames:
    """Patterns in time: frame ``i`` starts ``i * soa_ms`` after the stimulus's onset.

    Parameters
    ----------
    frames : sequence of Pattern
        The patterns in the order they play, 2 to 64.
    soa_ms : float or Fraction
        From one frame's onset to the next, in ms, above 0, at most 60 000.

    Raises
    ------
    PinArrayError
        An argument of the wrong kind, named; the frames are read against the array's grid
        and servos when presented (no pin may be driven twice at once).
    """

    frames: tuple[Pattern, ...]
    """The patterns in the order they play."""
    soa_ms: Fraction
    """From one frame's onset to the next, in ms."""

    def __init__(self, *, frames: Sequence[Pattern], soa_ms: Real) -> None:
        call = "pinarray.Frames"
        if isinstance(frames, str) or not isinstance(frames, Sequence):
            arguments.refuse(call, "frames", "a list of pinarray.Pattern", frames)
        for i, frame in enumerate(frames):
            if not isinstance(frame, Pattern):
                arguments.refuse(call, f"frames[{i}]", "a pinarray.Pattern", frame)
        object.__setattr__(self, "frames", tuple(frames))
        object.__setattr__(self, "soa_ms", Fraction(_number(call, "soa_ms", soa_ms).text))

    def __repr__(self) -> str:
        return (f"Frames(frames=[{', '.join(map(repr, self.frames))}], "
                f"soa_ms={_shown(self.soa_ms)})")


@dataclass(frozen=True, init=False, repr=False)
class Wave:
    """A travelling wave (or the seed's no-wave control), as a protocol's wave writes it:
    step ``i`` plays the train on its pin(s) ``i * soa_ms`` after onset.

    Parameters
    ----------
    wave : str
        ``"rightwards"`` or ``"leftwards"`` along a row, ``"none"`` (the central pin
        alternating with the two lateral ones), ``"upwards"`` or ``"downwards"`` along a
        column, or ``"sequence"``: any pins in the order listed.
    train : Train
        The train each pin plays.
    row : int or None
        The row of a row wave (1 = the bottom row); not for the others.
    pins : sequence of int or None
        The pins visited: a row wave's, left to right (None: the whole row); a column's, in
        the order visited; a sequence's, in order.
    direction : str or None
        The direction a subject would name for a sequence wave (``"up-right"``); not for the
        others.
    soa_ms : float, Fraction or None
        From one step's onset to the next, in ms, 0 to 60 000; None: 0.32 x the train's
        duration + 47.3 ms (Tactile Brush), as in a protocol.

    Raises
    ------
    PinArrayError
        An argument of the wrong kind, named; the wave is read against the array's grid and
        servos when presented.
    """

    wave: str
    """What kind of wave: rightwards, leftwards, none, upwards, downwards or sequence."""
    train: Train
    """The train each pin plays."""
    row: int | None
    """The row of a row wave (1 = the bottom row), or None."""
    pins: tuple[int, ...] | None
    """The pins visited, as given, or None."""
    direction: str | None
    """The direction a sequence wave names, or None."""
    soa_ms: Fraction | None
    """From one step's onset to the next, in ms; None: Tactile Brush's."""

    def __init__(self, wave: str, *, train: Train, row: int | None = None,
                 pins: Sequence[int] | None = None, direction: str | None = None,
                 soa_ms: Real | None = None) -> None:
        call = "pinarray.Wave"
        listed = None if pins is None else _pins(call, "pins", pins, drawn=False)
        assert not isinstance(listed, str)
        values = {
            "wave": arguments.text(call, "wave", wave),
            "train": _train(call, train),
            "row": None if row is None else _whole(call, "row", row),
            "pins": listed,
            "direction": arguments.optional_text(call, "direction", direction),
            "soa_ms": None if soa_ms is None else Fraction(_number(call, "soa_ms", soa_ms).text),
        }
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        given = [f"{self.wave!r}", f"train={self.train!r}"]
        if self.row is not None:
            given.append(f"row={self.row}")
        if self.pins is not None:
            given.append(f"pins={_shown_pins(self.pins)}")
        if self.direction is not None:
            given.append(f"direction={self.direction!r}")
        if self.soa_ms is not None:
            given.append(f"soa_ms={_shown(self.soa_ms)}")
        return f"Wave({', '.join(given)})"


Built = Pattern | Frames | Wave
"""A stimulus built in code, ready to be presented on an open array."""


def described(stimulus: Condition | Built) -> str:
    """What is presented, in full: a protocol's condition as its paradigm names it
    (``seed_train on pin 6 at 10 Hz``), a stimulus built in code as the code that builds it
    (every value, defaults included)."""
    return describe_condition(stimulus) if isinstance(stimulus, Condition) else repr(stimulus)


def code_stimulus(stimulus: Built) -> CodeStimulus:
    """What the protocol's readers read of ``stimulus`` on an array."""
    match stimulus:
        case Pattern():
            return _code_pattern(stimulus)
        case Frames(frames=frames, soa_ms=soa_ms):
            return CodeFrames(tuple(map(_code_pattern, frames)), _exact(soa_ms))
        case Wave():
            return CodeWave(stimulus.wave, stimulus.train._train, stimulus.row, stimulus.pins,
                            stimulus.direction,
                            None if stimulus.soa_ms is None else _exact(stimulus.soa_ms))


def _code_pattern(pattern: Pattern) -> CodePattern:
    return CodePattern(pattern.pins, pattern.train._train,
                       None if pattern.phase_deg is None else _exact(pattern.phase_deg))


# -- the door: each argument of the right kind, or a one-line error naming it -------------------


# No number a stimulus takes comes near this many bits (a protocol's are at most 40 characters);
# Python refuses to write an int past 4300 digits as text, so longer ones are refused first.
_MAX_BITS = 1000


def _number(call: str, name: str, value: object) -> Number:
    """A finite number, as the exact text a protocol would write for it (a float's shortest
    decimal: 0.1 is 1/10)."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return Number(str(_short(call, name, int(value))))
    if isinstance(value, Fraction):
        _short(call, name, value.numerator)
        _short(call, name, value.denominator)
        return _exact(value)
    if isinstance(value, numbers.Real) and not isinstance(value, bool) \
            and math.isfinite(float(value)):
        return Number(repr(float(value)))
    arguments.refuse(call, name, "a finite number (int, float or Fraction)", value)


def _exact(value: Fraction) -> Number:
    return Number(f"{value.numerator}/{value.denominator}" if value.denominator != 1
                  else str(value.numerator))


def _short(call: str, name: str, value: int) -> int:
    if value.bit_length() > _MAX_BITS:
        arguments.refuse(call, name, f"a number of at most {_MAX_BITS} bits", value)
    return value


def _whole(call: str, name: str, value: object) -> int:
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return _short(call, name, int(value))
    arguments.refuse(call, name, "a whole number (int)", value)


def _pins(call: str, name: str, value: object, *, drawn: bool = True) -> tuple[int, ...] | str:
    """Pin numbers (a list, tuple, range or numpy array of ints), or a drawing (a str)."""
    if drawn and isinstance(value, str):
        return value
    tolist = getattr(value, "tolist", None)  # a numpy array's pins, as Python ints
    items: Any = tolist() if callable(tolist) else value
    if isinstance(items, str | bytes) or not isinstance(items, Sequence):
        expected = "a list of pin numbers" + (" or a drawing (str)" if drawn else "")
        arguments.refuse(call, name, expected, value)
    return tuple(_whole(call, f"{name}[{i}]", pin) for i, pin in enumerate(items))


def _train(call: str, value: object) -> Train:
    if not isinstance(value, Train):
        arguments.refuse(call, "train", "a pinarray.Train", value)
    return value


def _widths(call: str, value: object) -> dict[str, Number] | None:
    if value is None:
        return None
    if not isinstance(value, Mapping):
        arguments.refuse(call, "pulse_width_ms", "a mapping such as {'up': 2.0, 'down': 1.5}",
                         value)
    widths = {}
    for key, width in value.items():
        if not isinstance(key, str):
            arguments.refuse(call, "pulse_width_ms", "the keys 'up' and 'down'", key)
        widths[key] = _number(call, f"pulse_width_ms[{key!r}]", width)
    return widths


# -- how a stimulus shows itself: the code that builds it, every value exact ----------------------


def _shown(value: Fraction) -> str:
    """An exact number as code writes it: ``5``, ``0.5``, ``Fraction(1, 3)``."""
    if value.denominator == 1:
        return str(value.numerator)
    denominator, digits = value.denominator, 0
    while denominator % 10 == 0 or denominator % 2 == 0 or denominator % 5 == 0:
        denominator //= 10 if denominator % 10 == 0 else 2 if denominator % 2 == 0 else 5
        digits += 1
    if denominator != 1 or digits > 12:
        return f"Fraction({value.numerator}, {value.denominator})"
    scaled = abs(value.numerator) * 10**digits // value.denominator
    whole, part = divmod(scaled, 10**digits)
    sign = "-" if value < 0 else ""
    return f"{sign}{whole}.{part:0{digits}d}".rstrip("0").rstrip(".")


def _shown_pins(pins: tuple[int, ...] | str) -> str:
    return repr(pins) if isinstance(pins, str) else f"[{', '.join(map(str, pins))}]"
