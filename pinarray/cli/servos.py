"""`pinarray servos ...`: bring-up of new servos from the shell (the work is in
`pinarray.hardware.feetech.bringup` and `pinarray.hardware.feetech.scan`).

Every command opens the bus without the playback handshake (which would switch torque on
everywhere), names servo ids and registers in its errors (exit status 2, one line), and leaves
nothing holding torque however it ends.

Past 400 lines: one job, the six `servos` subcommands, which share how a bus is chosen, how
servos that do not answer are named and how every way out leaves them safe.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from dataclasses import dataclass

from pinarray.cli.output import say

SERVOS_EPILOG = """\
The first hour with new servos (each ships answering at id 1, at 1000000 bit/s):
  1. connect ONE new servo and `pinarray servos scan --port /dev/ttyUSB0` (a broadcast ping finds
     it at once); `pinarray servos set-id 1 N --port /dev/ttyUSB0` gives it id N (saved in its
     EEPROM); repeat for each servo, one at a time, N = the pin it drives (or see servo_ids:).
  2. with all of them connected, `pinarray servos return-delay --port ...` lowers their return
     delay from the factory 500 us to 0 until power-off (`--save` keeps it).
  3. `pinarray servos calibrate PROTOCOL --pin N --port ...` for each pin: jog it to rest and
     up; the protocol's calibration is rewritten with its comments kept.
  4. `pinarray servos rest|torque-off [PROTOCOL] --port ...` whenever pins must let go.
Each command needs --port PATH (real servos) or --sim [URL] (simulated ones, said as the first
line of its output; e.g. 'sim://?ids=1' for one factory-fresh servo): never simulated by default.
"""

SCAN_EPILOG = """\
Without --ids: one PING to every servo at once (the broadcast id). A lone servo (a new one)
answers it and is found at once (asked twice: a late answer must not hide another servo);
several answering together collide on the wire, and then every id 0-252 is pinged in turn,
with progress on stderr. Each id waits at most --timeout-ms
for its answer (default: the USB adapter's latency timer + 2 ms, or 10 ms when it has none
that can be read, e.g. a CH340 or a pseudo-terminal); an FTDI adapter left at its 16 ms
latency timer needs more (see `pinarray timing --help` to lower it). The silent ids among and
beside those found are then looked at again, in rounds, each four times longer, while a round
finds someone, saying how far it has got; in all at most twice as long as the sweep (a full
scan: at most three sweeps' time). Exit status 2 when no servo could be read, saying what was
heard (nothing, garbled answers, or servos that answer a PING but cannot be read). Servos
listen at one speed only: try --baud when nothing answers.
"""

SET_ID_EPILOG = """\
Writes the servo's EEPROM on purpose: torque off, LOCK (address 55) = 0, ID (address 5) = NEW,
LOCK = 1; then checks that the servo answers at NEW, reads back its ID and LOCK, and that
nothing answers at OLD any more. Refused before anything is written when a servo already
answers at NEW (two servos on one id garble each other's answers). Connect new servos one at
a time: they all answer at id 1.
"""

RETURN_DELAY_EPILOG = """\
A servo waits its return delay (RETURN_DELAY_TIME, EEPROM address 7, 2 us units; factory 500 us)
before answering. Delivery verification reads every changed goal back between two frames, so
a low return delay makes it faster: 16 read-backs at 500 us each cost 8 ms of waiting, at 0 us
none.

By default the new value is in force at once and lost at power-off: LOCK (address 55) is set
to 1 first, and an STS servo keeps EEPROM values written while locked only until then. --save
keeps it across power cycles (LOCK 0, write, LOCK 1), after a confirmation: type y, or pass
--yes.
"""

WHO_ANSWERS_EPILOG = """\
Without --ids every servo of the device is tried; those that answer no PING (not connected,
not powered) are named and left as they are. Exit status 0 when every servo that answers did
its part; 2 when one of them did not, or when no servo answered at all. With --ids each
named servo must answer and do its part, else exit status 2.
"""

def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``servos`` and its subcommands to the `pinarray` parser."""
    from pinarray.cli import calibrate, common, response

    group = subparsers.add_parser(
        "servos", help="bring-up: find, renumber, tune and calibrate new servos",
        epilog=SERVOS_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    commands = group.add_subparsers(dest="servos_command", metavar="COMMAND")
    group.set_defaults(func=lambda args: group.print_help() or 0)

    p = commands.add_parser("scan", help="find the servos that answer (broadcast ping, else a "
                            "sweep of ids)", epilog=SCAN_EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scan_options(p)

    p = commands.add_parser("set-id", help="renumber one servo (EEPROM), checked",
                            epilog=SET_ID_EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("old", type=common.count(0, 252), metavar="OLD", help="its id now")
    p.add_argument("new", type=common.count(0, 252), metavar="NEW", help="the id to give it")
    bus_options(p)
    p.set_defaults(func=_cmd_set_id)

    p = commands.add_parser("return-delay", help="lower the servos' return delay (until "
                            "power-off unless --save)",
                            epilog=RETURN_DELAY_EPILOG + "\n" + WHO_ANSWERS_EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    _which_servos(p)
    p.add_argument("--us", type=common.count(0, 508), default=0, metavar="US",
                   help="the new return delay in microseconds, even, 0-508 (default 0)")
    p.add_argument("--save", action="store_true",
                   help="write it to EEPROM for good (asks first)")
    p.add_argument("--yes", action="store_true", help="confirm --save without asking")
    p.set_defaults(func=_cmd_return_delay)

    calibrate.register(commands)
    response.register(commands)

    p = commands.add_parser("torque-off", help="switch torque off on every servo of a device, "
                            "saying which answered", epilog=WHO_ANSWERS_EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    _which_servos(p)
    p.set_defaults(func=_cmd_torque_off)

    p = commands.add_parser("rest", help="every pin of a device to rest, then torque off, "
                            "saying which answered", epilog=WHO_ANSWERS_EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    _which_servos(p)
    p.set_defaults(func=_cmd_rest)


def add_scan_options(parser: argparse.ArgumentParser) -> None:
    """The options of `servos scan` (and of `pinarray scan`, its older name)."""
    from pinarray.cli import common

    parser.add_argument("--ids", metavar="IDS",
                        help="sweep exactly these ids, e.g. 1-16 (default: broadcast ping, "
                             "else 0-252)")
    parser.add_argument("--timeout-ms", type=common.count(1, 1000), metavar="MS",
                        help="longest wait for each id's answer in a sweep")
    bus_options(parser)
    parser.set_defaults(func=cmd_scan)


def bus_options(parser: argparse.ArgumentParser, baud_default: str = "1000000") -> None:
    from pinarray.cli import common
    from pinarray.cli.bus import add_bus_choice

    add_bus_choice(parser, simulated_by_default=False)
    parser.add_argument("--baud", type=common.baud_rate, metavar="BAUD",
                        help=f"bit/s the servos listen at (default {baud_default})")


def _which_servos(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("protocol", nargs="?", metavar="PROTOCOL",
                        help="protocol YAML whose device names the servos (default: the "
                             "built-in 4x4 device, servos 1-16)")
    parser.add_argument("--ids", metavar="IDS", help="only these servo ids, e.g. 1-4,9, each "
                        "of which must answer (default: the device's, those that answer)")
    bus_options(parser, baud_default="the protocol's")


# -- helpers ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Target:
    """The servos a device command works on, and where they are."""

    protocol: object  # pinarray.protocol.Protocol (imported when a command runs)
    servo_ids: tuple[int, ...]
    url: str
    baud_rate: int
    named: bool  # the ids were given (--ids): each must answer, not only those connected


def _target(args: argparse.Namespace, command: str) -> Target:
    from pinarray.cli import common
    from pinarray.cli.bus import DEFAULT_DEVICE_TEXT, chosen_bus
    from pinarray.errors import PinArrayError
    from pinarray.player.families import bus_setup, sts_servos
    from pinarray.protocol.load import load_protocol, parse_protocol

    protocol = (load_protocol(args.protocol) if args.protocol
                else parse_protocol(DEFAULT_DEVICE_TEXT, "<default device>"))
    device_ids = bus_setup(protocol.device).servo_ids
    ids = device_ids
    if args.ids is not None:
        ids = common.servo_ids(args.ids)
        strangers = [i for i in ids if i not in device_ids]
        if strangers:
            raise PinArrayError(
                f"--ids: servo id(s) {', '.join(map(str, strangers))} are not part of the "
                f"device of {protocol.source} (its servos: {_ranges(device_ids)})")
    url = chosen_bus(args, f"servos {command}", device_ids)
    return Target(protocol, ids, url, args.baud or sts_servos(protocol.device).baud_rate,
                  args.ids is not None)


def open_bare(url: str, baud_rate: int):
    from pinarray.hardware.feetech.transport import open_bus
    from pinarray.hardware.port_lock import hold_port

    # One owner per port: refused while an array drives it (naming it), held until this
    # command's process ends.
    hold_port(url, "a pinarray servos command")
    bus = open_bus(url, baud_rate=baud_rate)
    for warning in bus.warnings:
        say(f"pinarray: warning: {warning}", error=True)
    return bus


def _ranges(ids) -> str:
    """``1-4, 7`` for ids 1, 2, 3, 4, 7."""
    parts: list[str] = []
    ordered = sorted(ids)
    start = previous = None
    for servo_id in [*ordered, None]:
        if previous is not None and servo_id == previous + 1:
            previous = servo_id
            continue
        if start is not None:
            parts.append(str(start) if start == previous else f"{start}-{previous}")
        start = previous = servo_id
    return ", ".join(parts) or "none"


def _absent(bus, target: Target) -> tuple[int, ...]:
    """The device's servos that answer no PING: not connected, so left out of the command.

    Asked only when the device's servos were meant (no --ids): servos named by --ids must
    answer, so there each of them that does not is a failure like any other.
    """
    from pinarray.hardware.feetech import bringup

    if target.named:
        return ()
    return bringup.silent_ids(bus, target.servo_ids, bringup.sweep_timeout_ns(bus))


def _present(target: Target, absent: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(i for i in target.servo_ids if i not in absent)


def _failures(failures, what: str, target: Target, absent: tuple[int, ...]) -> None:
    """Name the servos that are not connected (``absent``: left alone, not an error unless
    none answered), then one error line naming every other servo that did not do its part
    (and the first reason)."""
    from pinarray.errors import BusError

    if absent and len(absent) == len(target.servo_ids):
        raise BusError(f"{what}: no servo answered on {target.url} (servo id(s) "
                       f"{_ranges(absent)}): check power, cables and --baud")
    if absent:
        say(f"no answer from servo(s) {_ranges(absent)} (not connected?): left as they are")
    failures = [f for f in failures if f.servo_id not in absent]
    if failures:
        ids = ", ".join(str(f.servo_id) for f in failures)
        raise BusError(f"{what}: no success on servo id(s) {ids} (first: {failures[0].problem})")


# -- scan ------------------------------------------------------------------------------------


def cmd_scan(args: argparse.Namespace) -> int:
    from pinarray.cli import common
    from pinarray.cli.bus import chosen_bus
    from pinarray.hardware.feetech import bringup, scan
    from pinarray.hardware.feetech.registers import STS3215_MODEL_NUMBER
    from pinarray.stop import StopRequest, stop_on_signals

    ids = common.servo_ids(args.ids) if args.ids is not None else None
    url = chosen_bus(args, "scan" if args.command == "scan" else "servos scan")
    with stop_on_signals(StopRequest()) as stop:
        bus = open_bare(url, args.baud or 1_000_000)
        try:
            timeout_ns = (args.timeout_ms * 1_000_000 if args.timeout_ms
                          else bringup.sweep_timeout_ns(bus))
            progress = _Progress(stop, timeout_ns)
            result = scan.scan(bus, ids, timeout_ns, progress,
                               still_wanted=stop.raise_if_requested, looking_again=progress.again)
            progress.done()
        finally:
            bus.close()
    if result.found or result.unreadable:
        say(f"{'id':>3}  {'model':<14} {'firmware':>8} {'return delay':>12} {'position':>8} "
            f"{'voltage':>8} {'temp':>6}  errors")
    for servo in result.found:
        name = (f"{servo.model_number} (STS3215)" if servo.model_number == STS3215_MODEL_NUMBER
                else str(servo.model_number))
        t = servo.telemetry
        say(f"{servo.servo_id:>3}  {name:<14} {'{}.{}'.format(*servo.firmware):>8} "
            f"{servo.return_delay_us:>9} us {t.position_steps:>8} {t.voltage_v:>7.1f}V "
            f"{t.temperature_c:>4}°C  {t.errors.describe()}")
    for unreadable in result.unreadable:
        say(f"{unreadable.servo_id:>3}  {unreadable.problem}")
    count = len(result.servo_ids)
    if result.method is scan.ScanMethod.BROADCAST:
        say(f"{count} servo(s) answered a broadcast ping on {url}")
    else:
        why = f"; {result.sweep_reason}" if result.sweep_reason else ""
        say(f"{count} servo(s) answered on {url} (ids {_ranges(result.swept_ids)} pinged, "
            f"up to {timeout_ns / 1e6:g} ms each{why})")
    if result.found:
        return 0
    # Nothing usable answered: not a scan that went well (exit status 2, as the other servos
    # commands when no servo answers), saying what was heard.
    if result.unreadable:
        say(f"pinarray: no servo could be read: servo(s) {_ranges(result.servo_ids)} answered, "
            "but not as asked (above): check cables and connectors", error=True)
    elif result.sweep_reason is scan.SweepReason.GARBLED:
        say("pinarray: no servo answered a PING of its id, though garbled answers came back to "
            "the broadcast ping: a servo is there whose answers arrive damaged; check cables "
            "and connectors, and --baud", error=True)
    else:
        say("pinarray: nothing answered: check power and cables, and --baud (servos answer "
            "only at their own speed; new ones at 1000000)", error=True)
    return 2


class _Progress:
    """A scan's progress on stderr: one line rewritten on a terminal; else a line per 32 ids of
    the sweep, and while looking again at silent ids, a line at least every 32 first waits
    (a round of looking again may last seconds). The sweep's last line is said last."""

    def __init__(self, stop, timeout_ns: int):
        self.stop = stop
        self.timeout_ns = timeout_ns
        self.tty = sys.stderr.isatty()
        self.shown = False
        self.last_word = ""  # the sweep's last line, said again after looking again
        self.again_said = False

    def __call__(self, servo_id: int, last_id: int, found: tuple[int, ...]) -> None:
        self.stop.raise_if_requested()
        text = f"sweeping: id {servo_id} of {last_id}, found so far: {_ranges(found)}"
        if servo_id == last_id:
            self.last_word, self.again_said = text, False
        self._say(text, servo_id % 32 == 31 or servo_id == last_id)

    def again(self, step) -> None:
        """Before each PING of a look again (a `scan.LookingAgain`)."""
        self.stop.raise_if_requested()
        every = max(1, 32 * self.timeout_ns // step.wait_ns)
        self._say(f"looking again, up to {step.wait_ns / 1e6:g} ms each: id {step.servo_id} "
                  f"({step.done + 1} of {step.count}), found so far: "
                  f"{_ranges(step.found_ids)}", step.done % every == 0)
        self.again_said = True

    def _say(self, text: str, on_a_line_of_its_own: bool) -> None:
        if self.tty:
            width = shutil.get_terminal_size().columns
            try:
                sys.stderr.write("\r" + text[:max(1, width - 1)] + "\x1b[K")
                sys.stderr.flush()
            except OSError:
                pass
            self.shown = True
        elif on_a_line_of_its_own:
            say(text, error=True)

    def done(self) -> None:
        if self.again_said and self.last_word:
            self._say(self.last_word, True)
        if self.shown:
            say("", error=True)


# -- set-id ----------------------------------------------------------------------------------


def _cmd_set_id(args: argparse.Namespace) -> int:
    from pinarray.cli.bus import chosen_bus
    from pinarray.hardware.feetech import bringup
    from pinarray.stop import StopRequest, stop_on_signals

    url = chosen_bus(args, "servos set-id")
    with stop_on_signals(StopRequest()) as stop:
        bus = open_bare(url, args.baud or 1_000_000)
        try:
            done = bringup.set_id(bus, args.old, args.new)
        finally:
            bus.close()
        stop.raise_if_requested()
    note = "" if done.acknowledged else " (the ID write was not acknowledged at the old id)"
    say(f"servo {done.old_id} is now servo {done.new_id} (model {done.model_number}): torque "
        f"off, LOCK (address 55) = 0, ID (EEPROM address 5) = {done.new_id}, LOCK = 1; it "
        f"answers at id {done.new_id} and nothing answers at id {done.old_id}{note}")
    return 0


# -- return delay ----------------------------------------------------------------------------


def _cmd_return_delay(args: argparse.Namespace) -> int:
    from pinarray.errors import PinArrayError
    from pinarray.hardware.feetech import bringup
    from pinarray.stop import StopRequest, stop_on_signals

    bringup.check_return_delay_us(args.us)
    target = _target(args, "return-delay")
    ids = _ranges(target.servo_ids)
    if args.save and not args.yes:
        question = (f"Save RETURN_DELAY_TIME (EEPROM address 7) = {args.us} us in the EEPROM of "
                    f"servo(s) {ids}, so that it survives power-off? [y/N] ")
        if not _confirmed(question):
            raise PinArrayError("return-delay --save not confirmed: nothing written")
    with stop_on_signals(StopRequest()) as stop:
        bus = open_bare(target.url, target.baud_rate)
        try:
            absent = _absent(bus, target)
            changes, failures = bringup.set_return_delay(bus, _present(target, absent), args.us,
                                                         args.save)
        finally:
            bus.close()
        stop.raise_if_requested()
    lasting = "saved in EEPROM" if args.save else "until power-off"
    for change in changes:
        say(f"servo {change.servo_id}: RETURN_DELAY_TIME (address 7) {change.before_us} us -> "
            f"{change.after_us} us, {lasting}")
    _failures(failures, "return-delay", target, absent)
    return 0


def _confirmed(question: str) -> bool:
    from pinarray.errors import PinArrayError

    if not sys.stdin.isatty():
        raise PinArrayError("--save writes EEPROM: confirm it with --yes (there is no terminal "
                            "to ask on)")
    try:
        return input(question).strip().lower() in ("y", "yes")
    except EOFError:
        return False


# -- torque-off, rest ------------------------------------------------------------------------


def _cmd_torque_off(args: argparse.Namespace) -> int:
    from pinarray.hardware.feetech import bringup
    from pinarray.stop import StopRequest, deferred_signals, stop_on_signals

    target = _target(args, "torque-off")
    with stop_on_signals(StopRequest()) as stop:
        bus = open_bare(target.url, target.baud_rate)
        try:
            absent = _absent(bus, target)
            with deferred_signals():
                released, failures = bringup.torque_off(bus, _present(target, absent))
        finally:
            bus.close()
        stop.raise_if_requested()
    if released:
        say(f"torque off on servo(s) {_ranges(released)}")
    elif len(absent) < len(target.servo_ids):
        say("torque off: no servo acknowledged")
    _failures(failures, "torque-off (TORQUE_ENABLE, address 40)", target, absent)
    return 0


def _cmd_rest(args: argparse.Namespace) -> int:
    from pinarray.errors import BusError
    from pinarray.hardware.feetech import bringup
    from pinarray.player.families import bus_setup
    from pinarray.stop import StopRequest, stop_on_signals

    target = _target(args, "rest")
    full = bus_setup(target.protocol.device)  # type: ignore[attr-defined]
    with stop_on_signals(StopRequest()) as stop:
        bus = open_bare(target.url, target.baud_rate)
        try:
            absent = _absent(bus, target)
            present = _present(target, absent)
            setup = type(full)(tuple(s for s in full.servos if s.servo_id in present),
                               full.model_number, full.speed_steps_per_s,
                               full.acceleration_register)
            safe = bringup.rest(bus, setup)
        finally:
            bus.close()
        stop.raise_if_requested()
    if len(absent) < len(target.servo_ids):
        say(f"at rest: servo(s) {_ranges(safe.at_rest_ids)}; torque off: servo(s) "
            f"{_ranges(safe.released_ids)}")
    if safe.port_lost:
        raise BusError(f"rest: servo port {target.url} lost; cut servo power")
    _failures((), "rest", target, absent)
    if safe.silent_ids:
        raise BusError(f"rest: servo id(s) {', '.join(map(str, safe.silent_ids))} not "
                       "confirmed at rest with torque off (GOAL_POSITION 42, TORQUE_ENABLE 40)")
    return 0
