"""`pinarray servos calibrate` (and `pwm calibrate`): jog one pin to rest and up, then write
them into its protocol.

The jogging is each family's (`pinarray.hardware.feetech.jog` here, `pinarray.hardware.pca9685.jog`
for `pwm calibrate`, through a `Jogger`); the file is edited by `pinarray.cli.calibration_file`,
which keeps its comments and layout. This module talks to the person: the line-by-line prompt, the
confirmation of what was written, and the pin made safe on every way out.
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Any, Protocol

from pinarray.cli.output import say
from pinarray.cli.servos import bus_options, open_bare

if TYPE_CHECKING:
    from pinarray.cli.calibration_file import NewCalibration
    from pinarray.hardware.feetech.feetech import FeetechBus
    from pinarray.hardware.feetech.jog import Jog, JogReading
    from pinarray.protocol import Device

CALIBRATE_EPILOG = """\
Holds the pin's servo where its horn is (torque on, at most 600 steps/s) and asks, on lines:
  +  / -       one step (--step, default 10 steps) up / down the servo's count
  +N / -N      N steps        =N   go to N steps        (empty line: where it is now)
  ok           this is the position (first rest, then up)
  q            stop without writing anything
Goals stay within the servo's own angle limits (EEPROM 9/11). Then the protocol file's
device: pins: N: entry gets rest_steps and positions (the narrowest pulse width at rest, the
widest up, any in between where they were relative to those); limits_steps too, widened, if
the file gives limits that the new positions leave. Only those values change: comments, key
order and line ends stay. The result is read back as a protocol (every stimulus must still be
feasible) before the file is replaced, in one step. On any exit the pin goes to rest and its
torque off.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``calibrate`` to the ``servos`` group."""
    from pinarray.cli import common

    p = subparsers.add_parser(
        "calibrate", help="jog one pin to rest and up, then write its calibration into the "
        "protocol", epilog=CALIBRATE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("protocol", metavar="PROTOCOL", help="protocol YAML file to update")
    p.add_argument("--pin", type=common.count(1, 4096), required=True, metavar="N",
                   help="the pin to calibrate")
    p.add_argument("--step", type=common.count(1, 500), default=10, metavar="STEPS",
                   help="steps per + or - (default 10)")
    bus_options(p, baud_default="the protocol's")
    p.set_defaults(func=_cmd_calibrate)


@dataclass(frozen=True)
class _By:
    steps: int


@dataclass(frozen=True)
class _To:
    steps: int


class JogWord(StrEnum):
    """A line that is a word, not a move."""

    OK = "ok"
    QUIT = "quit"
    SHOW = "show"  # an empty line: where the horn is now
    HELP = "help"


def jog_help(unit: str, shown: str = "where it is") -> str:
    """The jog commands in one line, in the family's unit (``steps`` or ``us``); ``shown``:
    what an empty line shows."""
    return (f"+ / - one step, +N / -N N {unit}, =N go to N {unit}, empty line: {shown}, "
            "ok: this is it, q: stop without writing")


def parse_jog(line: str, step: int) -> _By | _To | JogWord:
    """One line typed while jogging; `ValueError` with what was expected otherwise."""
    text = line.strip().lower()
    if not text:
        return JogWord.SHOW
    if text in ("?", "help", "h"):
        return JogWord.HELP
    if text in ("ok", "y", "yes"):
        return JogWord.OK
    if text in ("q", "quit", "exit"):
        return JogWord.QUIT
    if text in ("+", "-"):
        return _By(step if text == "+" else -step)
    sign, number = text[0], text[1:].strip()
    if sign in "+-=" and number.isascii() and number.isdigit() and len(number) <= 5:
        value = int(number)
        if sign == "=":
            return _To(value)
        return _By(value if sign == "+" else -value)
    raise ValueError(f"expected +, -, +N, -N, =N, ok or q, found {line.strip()[:40]!r}")


class Jogger(Protocol):
    """One pin held and moved while a person watches, as the calibration dialogue needs it:
    each call returns the line that says what happened (the families' readings differ)."""

    unit: str  # "steps" or "us"
    shown: str  # what an empty line shows

    @property
    def name(self) -> str: ...

    @property
    def goal(self) -> int: ...

    def start(self) -> str: ...

    def move_by(self, amount: int) -> str: ...

    def move_to(self, goal: int) -> str: ...

    def show(self) -> str: ...

    def release(self, rest: int) -> str:
        """The pin to ``rest``, then let go (torque off, or no pulses); never raises."""
        ...

    def refusal(self) -> str | None:
        """Why the goal cannot be taken as a position now (None: it can)."""
        ...


class JogDialogue:
    """What each family's `Jogger` shares: the pin's name and its moves, delegated to its
    jog (``jog``); each family says a reading its own way (``_said``)."""

    jog: Any

    @property
    def name(self) -> str:
        return self.jog.name

    def move_by(self, amount: int) -> str:
        return self._said(self.jog.move_by(amount))

    def move_to(self, goal: int) -> str:
        return self._said(self.jog.move_to(goal))

    def show(self) -> str:
        return self._said(self.jog.read())

    def _said(self, reading: Any) -> str:
        raise NotImplementedError


class _StsJogger(JogDialogue):
    """An STS servo's `pinarray.hardware.feetech.jog.Jog`: it says where the horn is."""

    unit = "steps"
    shown = "where it is"

    def __init__(self, jog: Jog, bus: FeetechBus, rest_steps: int, up_steps: int):
        self.jog, self.bus = jog, bus
        self.rest_steps, self.up_steps = rest_steps, up_steps

    @property
    def goal(self) -> int:
        assert self.jog.goal_steps is not None, "start() first"
        return self.jog.goal_steps

    def start(self) -> str:
        reading = self.jog.start()
        return (f"{self.name}: holding it at {reading.present_steps} steps (calibrated rest "
                f"{self.rest_steps}, up {self.up_steps}; the servo allows {self.jog.bounds[0]}.."
                f"{self.jog.bounds[1]}).")

    def _said(self, reading: JogReading) -> str:
        arrived = "" if reading.arrived else " (still on its way: watch it, or type again)"
        errors = "" if not reading.errors else f", error bits: {reading.errors.describe()}"
        return f"  goal {reading.goal_steps}, at {reading.present_steps} steps{arrived}{errors}"

    def release(self, rest: int) -> str:
        try:
            safe = self.jog.release(rest)
        finally:
            self.bus.close()
        where = f"at rest ({rest} steps)" if safe.at_rest_ids else "NOT confirmed at rest"
        torque = "torque off" if safe.released_ids else "torque NOT confirmed off"
        return f"{self.name}: {where}, {torque}"

    def refusal(self) -> str | None:
        return None  # where the horn is shows in each reading: the person watches it


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from pinarray.cli.bus import chosen_bus
    from pinarray.hardware.feetech.jog import Jog
    from pinarray.player.families import bus_setup, sts_servos
    from pinarray.stop import StoppableClock, StopRequest, stop_on_signals

    protocol, data = protocol_to_calibrate(args)
    device = protocol.device
    setup = bus_setup(device)
    servo = next(s for s in setup.servos if s.pin == args.pin)
    url = chosen_bus(args, "servos calibrate", setup.servo_ids)
    with stop_on_signals(StopRequest()) as stop:
        bus = open_bare(url, args.baud or sts_servos(device).baud_rate)
        jog = Jog(bus, servo, setup.model_number, setup.speed_steps_per_s,
                  clock=StoppableClock(bus.clock, stop))
        up = device.calibration(args.pin).positions_by_width_ns[-1][1]
        return calibrate_pin(args, protocol, data, _StsJogger(jog, bus, servo.rest_steps, up),
                             stop)


def protocol_to_calibrate(args: argparse.Namespace):
    """The protocol and its file's bytes, refused at once if the pin's calibration cannot be
    edited in the file."""
    from pinarray.cli.calibration_file import plan_calibration, rewrite_calibration
    from pinarray.errors import PinArrayError, ProtocolError
    from pinarray.protocol.load import MAX_PROTOCOL_BYTES, load_protocol

    protocol = load_protocol(args.protocol)
    data = _protocol_bytes(args.protocol, MAX_PROTOCOL_BYTES, protocol.sha256)
    calibration = protocol.device.calibration(args.pin)
    try:  # a file that cannot be edited: say so first
        new = plan_calibration(data, protocol, args.pin, calibration.rest_steps,
                               calibration.positions_by_width_ns[-1][1])
        rewrite_calibration(data, protocol, new)
    except ProtocolError:
        raise
    except PinArrayError:
        pass  # e.g. rest = up today: the new values decide
    return protocol, data


def calibrate_pin(args: argparse.Namespace, protocol, data: bytes, jogger: Jogger, stop) -> int:
    """Jog ``args.pin`` to rest, then up; write both into the protocol file; the pin let go
    at rest (the new one if found) however it ends."""
    from pinarray.cli.calibration_file import plan_calibration, rewrite_calibration
    from pinarray.errors import PinArrayError
    from pinarray.protocol.load import MAX_PROTOCOL_BYTES

    device = protocol.device

    def edited(rest: int, up: int) -> tuple[NewCalibration, bytes]:
        new = plan_calibration(data, protocol, args.pin, rest, up)
        return new, rewrite_calibration(data, protocol, new)

    result: tuple[NewCalibration, bytes] | None = None
    rest = device.calibration(args.pin).rest_steps
    try:
        say(jogger.start())
        say(f"Commands: {jog_help(jogger.unit, jogger.shown)}.")
        found_rest = _jog_until_ok(jogger, "rest", args.step, stop, lambda goal: None)
        if found_rest is not None:
            attempts: dict[int, tuple[NewCalibration, bytes]] = {}

            def check(up: int) -> str | None:
                if up == found_rest:
                    return f"up must differ from rest ({found_rest} {jogger.unit}): jog further"
                try:
                    attempts[up] = edited(found_rest, up)
                except PinArrayError as problem:
                    return f"{problem}; jog elsewhere, or q"
                return None

            found_up = _jog_until_ok(jogger, "up", args.step, stop, check)
            if found_up is not None:
                result = attempts[found_up]
                rest = found_rest
    finally:
        say(jogger.release(rest))
    if result is None:
        say(f"{args.protocol}: nothing written")
        return 0
    new, text = result
    # Whoever saved the file meanwhile keeps their version: refuse rather than overwrite it.
    _protocol_bytes(args.protocol, MAX_PROTOCOL_BYTES, protocol.sha256)
    _replace_file(args.protocol, text)
    say(f"{args.protocol}: {_describe(new, device, args.pin)}")
    return 0


def _describe(new: NewCalibration, device: Device, pin: int) -> str:
    """What was written, and the stroke it gives, in words."""
    unit = new.unit
    positions = ", ".join(f"{w / 1e6:g} ms: {p}" for w, p in new.positions)
    limits = (f", limits_{unit} [{new.limits_steps[0]}, {new.limits_steps[1]}] (widened)"
              if new.limits_widened else "")
    stroke = abs(new.up_steps - new.rest_steps)
    lever = device.calibration(pin).lever_mm
    degrees = device.servo.degrees(stroke)
    return (f"device: pins: {pin}: rest_{unit} {new.rest_steps}, positions {{{positions}}}"
            f"{limits}; stroke {stroke} {unit} ({degrees:.1f} deg, about "
            f"{stroke * device.mm_per_step(pin):.2f} mm on its {lever:g} mm lever)")


def _jog_until_ok(jogger: Jogger, what: str, step: int, stop, check) -> int | None:
    """Jog until ``ok`` where ``check(goal)`` finds no problem (the goal), or ``q`` (None)."""
    from pinarray.errors import BusError
    from pinarray.hardware.driver import GoalOutOfRange
    from pinarray.stop import raise_on_signals

    say(f"Jog {jogger.name} to {what.upper()}, then type ok.")
    while True:
        try:
            with raise_on_signals("calibration"):
                # Looked at inside the block: a signal taken just before it only set the
                # request, and the prompt would have waited on with the pin holding torque.
                stop.raise_if_requested()
                line = input(f"{what}> ")
        except EOFError:
            raise BusError(f"{jogger.name}: input ended before the {what} position was chosen; "
                           "nothing written") from None
        try:
            command = parse_jog(line, step)
        except ValueError as problem:
            say(f"  {problem}")
            continue
        try:
            match command:
                case _By(steps=amount):
                    said = jogger.move_by(amount)
                case _To(steps=goal):
                    said = jogger.move_to(goal)
                case JogWord.OK:
                    refused = jogger.refusal() or check(jogger.goal)
                    if refused is None:
                        say(f"  {what} = {jogger.goal} {jogger.unit}")
                        return jogger.goal
                    say(f"  {refused}")
                    continue
                case JogWord.QUIT:
                    return None
                case JogWord.HELP:
                    say(f"  {jog_help(jogger.unit, jogger.shown)}")
                    continue
                case JogWord.SHOW:
                    said = jogger.show()
        except GoalOutOfRange as problem:
            say(f"  {problem}")
            continue
        say(said)


def _protocol_bytes(path: str, limit: int, sha256: str) -> bytes:
    """The file's bytes, which must be the text that was loaded (its SHA-256)."""
    import hashlib

    from pinarray.errors import PinArrayError
    from pinarray.text_files import NotText, decode_text, read_bounded

    try:
        data = read_bounded(path, limit, "protocol")
        text = decode_text(data)
    except NotText as problem:
        raise PinArrayError(f"{path}: {problem.message}") from None
    if hashlib.sha256(text.encode("utf-8")).hexdigest() != sha256:
        raise PinArrayError(f"{path}: changed on disk since it was read; run the command again")
    return data


def _replace_file(path: str, data: bytes) -> None:
    """Put ``data`` in place of the file in one step (a failure leaves the file as it was)."""
    from pinarray.cli.common import OutputFile

    out = OutputFile(path, binary=True)
    try:
        out.stream.write(data)
        if out.temporary:
            mode = os.stat(out.final).st_mode & 0o7777
            os.chmod(out.temporary, mode)  # keep the file's permissions
        out.commit()
    except OSError as problem:
        out.discard()
        from pinarray.errors import PinArrayError

        raise PinArrayError(f"{path}: cannot write: {problem.strerror}") from None
