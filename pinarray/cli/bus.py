"""`pinarray play`, `timing`, `scan` (an alias of `servos scan`) and `sim-serve`: the servo bus
from the shell."""

import argparse

from pinarray.cli.output import say
from pinarray.hardware.feetech.faults import SIM_DEFAULT, is_sim_url, parse_sim_url

# Exit status of `play` when a trial's stimulus was not delivered as scheduled.
EXIT_NOT_DELIVERED = 3
# The smallest protocol: the default 4x4 device, for commands that need only a device.
DEFAULT_DEVICE_TEXT = """\
protocol: default-device
stimuli: {buzz: {frequency_hz: 1, duration_s: 1}}
design: {paradigm: localisation, stimulus: buzz, pins: [1], frequencies_hz: [1]}
"""

PLAY_EPILOG = """\
Bus choice: --port PATH drives real servos (a device such as /dev/ttyUSB0 or a pyserial URL);
--sim [URL] (the default) drives simulated ones, e.g. --sim 'sim://?drop=0.01&corrupt=0.01'
(see `pinarray sim-serve --help` for the URL keys); the simulated ids default to the
protocol's servo ids.

Time: with the simulator, --speed 0 (the default) runs in virtual time: nothing sleeps, the
report shows what the schedule and the wire allow. --speed X > 0 runs at X times real time
(1 = real time, 20 = twenty times faster, 0.5 = half speed). Real servos always run at
--speed 1. (--time-scale is the old name of --speed.)

Real servos (and simulated ones behind a pseudo-terminal) are played by a player process of
its own at real-time priority when the OS grants it. Every goal change is read back from its
servo and re-sent if lost; a trial not delivered as scheduled (device: delivery_tolerance_ms,
default 10 ms) is reported and the exit status is 3.

Ctrl-C, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1/2, SIGPIPE and every other signal sent to end it
(SIGALRM, SIGXCPU, a real-time signal, ...; not SIGKILL) stop playback cleanly: pins go to rest and torque
off before exit (status 128 + the signal's number). Started with nohup, a command plays on
through the hang-up of the session it was started from.
"""

TIMING_EPILOG = """\
Starts a player process as play, batch and the UI do (real-time priority when the OS grants
it), measures how late it wakes for deadlines every millisecond, times a read-back of a goal
on the bus, and says whether a goal lost on the wire and written again still reaches its
servo within the protocol's delivery tolerance (device: delivery_tolerance_ms, default 10 ms),
and what to change if not. Exit status 0 when it does, 3 when it does not. It needs --port PATH,
or --sim [URL] to rehearse (then its first line says SIMULATED): never simulated by default.
"""

SERVE_EPILOG = """\
URL keys (also usable in --sim URLs of play/scan), given to --faults in URL query style:
  wire and servos: baud=RATE (an STS rate; default 1000000, the factory setting),
    return_delay_us=US (0-508), model=sts3215|sts3215-12v|sts3250, supply_v=V,
    backlash_deg=DEG, load=F (-1 to 1 of stall torque), speed=STEPS_PER_S (the horns' top
    speed, 1-10000: a worn, hot or under-volted servo)
  faults: drop=P, drop_writes=P (only WRITE/REG_WRITE/SYNC_WRITE lost), corrupt=P,
    late=P with late_ms=MS (status packets that arrive MS ms late), missing=IDS, extra=IDS,
    overload=IDS, overheat=IDS, voltage=IDS, angle=IDS, overcurrent=IDS,
    vanish_after=N (instruction packets before the port disappears), seed=S
Answers leave when the wire would deliver them: the instruction's bytes at the port's baud
rate, then each servo's return delay and its answer's bytes. A client at another speed than
the servos' baud-rate register gets no answer.
--arrivals PATH writes, on stop, one TSV row per instruction packet: arrival_ns
(time.monotonic_ns() when its last byte was read), servo_id, instruction, address, data_hex
(the parameters after the address; for SYNC_WRITE the length, then id + data per servo),
delivered (0 when a fault lost it).
Example: pinarray sim-serve --ids 1-16 --faults 'drop_writes=0.1&late=0.05&seed=3'
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``play``, ``timing``, ``scan`` and ``sim-serve`` to the `pinarray` parser."""
    from pinarray.cli import common  # here, not at the top: the cli package imports this module
    p = subparsers.add_parser(
        "play",
        help="play a protocol's trials on real or simulated servos",
        epilog=PLAY_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", help="protocol YAML file")
    p.add_argument("--trial", type=int, metavar="N", help="play only trial N of the plan")
    add_bus_choice(p)
    common.add_speed(p, default=None,
                     help="simulator only: X times real time (default 0: virtual time, "
                          "nothing waits; 1 = real time, 20 = twenty times faster)")
    p.add_argument("--seed", type=common.seed, default=None, help="seed of the trial order")
    p.add_argument("--i2c-log", metavar="FILE", type=common.new_file,
                   help="PWM boards: write every I2C message to FILE as a logic analyser "
                        "decodes it, one line each: t_ns addr rw data_hex ack (t_ns: when the "
                        "message's STOP ended, ns from its trial's onset on the player's clock)")
    p.set_defaults(func=_cmd_play)

    p = subparsers.add_parser(
        "timing",
        help="check whether this machine can deliver a protocol's stimuli in time",
        epilog=TIMING_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", nargs="?", help="protocol YAML file (default: the built-in device)")
    add_bus_choice(p, simulated_by_default=False)
    p.add_argument("--seconds", type=float, metavar="S",
                   help="how long to measure wake-ups (default: as long as the protocol's "
                   "trials need for a verdict that holds, 2 to 15 s)")
    p.set_defaults(func=_cmd_timing)

    from pinarray.cli import servos
    p = subparsers.add_parser(
        "scan",
        help="list the servos that answer: model, voltage, temperature, error bits "
             "(= servos scan)",
        epilog=servos.SCAN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    servos.add_scan_options(p)

    p = subparsers.add_parser(
        "sim-serve",
        help="serve simulated servos on a pseudo-terminal and print its path",
        epilog=SERVE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--ids", default="1-16", help="servo ids (default 1-16)")
    p.add_argument("--faults", default="", metavar="QUERY",
                   help="URL keys (faults, wire, physics), URL query style")
    p.add_argument("--arrivals", metavar="PATH",
                   help="on stop, write every instruction packet's arrival time as TSV")
    p.set_defaults(func=_cmd_sim_serve)


def add_bus_choice(parser: argparse.ArgumentParser, simulated_by_default: bool = True) -> None:
    """--port PATH (real servos) or --sim [URL], never both; neither means simulated servos,
    unless not ``simulated_by_default`` (a command that changes or inspects servos: then
    `chosen_bus` refuses to run without one of them)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--port", metavar="PATH", type=port_path,
                       help="serial device of real servos")
    group.add_argument(
        "--sim", nargs="?", const=SIM_DEFAULT, metavar="URL",
        help="simulated servos (default), optionally a sim:// URL with faults"
        if simulated_by_default else
        "simulated servos, to rehearse (this or --port is needed), optionally a sim:// URL "
        "with faults, e.g. 'sim://?ids=1' for one factory-fresh servo",
    )


def port_path(text: str) -> str:
    """--port's argument: a device or URL, never nothing (an unset shell variable), which would
    have meant the simulated array (or, for a PWM command, no bus)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a device such as /dev/ttyUSB0 or "
                                         "/dev/i2c-1, found nothing (an unset variable?)")
    return text


def check_bus_choice(args: argparse.Namespace) -> None:
    """Refuse, before anything loads, a --port or --sim that names no bus: a path that does not
    exist or is not a device (a pyserial URL such as ``socket://`` is left to opening, as is a
    device that is not a serial port: /dev/null), or a --sim that is not a sim:// URL or that
    the simulated servos cannot read (a key unknown, a value out of range)."""
    import os
    import stat

    from pinarray.errors import PinArrayError
    from pinarray.hardware.pca9685.sim import is_pca9685_url

    if args.sim is not None and not is_sim_url(args.sim):
        raise PinArrayError(f"--sim expects a sim:// URL, found {args.sim!r}")
    if args.sim is not None and not is_pca9685_url(args.sim):
        parse_sim_url(args.sim)  # its keys and values, as opening the servos reads them
        # (a board's URL is read as it opens: its state file with it)
    if not args.port or "://" in args.port:
        return
    try:
        mode = os.stat(args.port).st_mode
    except FileNotFoundError:
        raise PinArrayError(f"--port {args.port}: no such device (is the adapter plugged in?)"
                            ) from None
    except OSError as error:
        raise PinArrayError(f"--port {args.port}: {error.strerror}") from None
    if not stat.S_ISCHR(mode):
        raise PinArrayError(f"--port {args.port}: not a serial device, expected one such as "
                            "/dev/ttyUSB0")
    terminals = {os.fstat(fd).st_rdev for fd in (0, 1, 2) if os.isatty(fd)}
    if os.path.realpath(args.port) == "/dev/tty" or os.stat(args.port).st_rdev in terminals:
        raise PinArrayError(f"--port {args.port}: the terminal this command runs in, not the "
                            "servos' serial device (the UI draws on it)")


def chosen_bus(args: argparse.Namespace, command: str,
               servo_ids: tuple[int, ...] | None = None) -> str:
    """The servos a command that changes or inspects them opens: ``--port``, or ``--sim``
    given explicitly, never simulated ones by default (a scan of servos that do not exist
    reads as a scan of the real bus). Simulated ones are said, as the command's first line.

    ``servo_ids``: the ids a ``--sim`` URL that names none simulates (default: its own).
    """
    from pinarray.errors import PinArrayError

    if args.port:
        return args.port  # real servos: nothing of the simulator's (nor the protocol) loaded
    from pinarray.hardware.feetech.faults import parse_sim_url
    from pinarray.player.families import sim_url_for

    if args.sim is None:
        raise PinArrayError(
            f"{command}: which servos? add --port PATH for real ones (e.g. --port /dev/ttyUSB0), "
            "or --sim to rehearse on simulated ones")
    url = sim_url_for(args.sim, servo_ids) if servo_ids else args.sim
    parse_sim_url(url)  # a URL that cannot be opened is refused before anything is said
    say(f"SIMULATED servos ({url}): no real servo is touched")
    return url


def _cmd_play(args: argparse.Namespace) -> int:

    from pinarray.plan import make_plan
    from pinarray.player.playback import PlaybackReport
    from pinarray.player.rig import Rig, choose_clock
    from pinarray.player.simulators import simulation_level
    from pinarray.protocol.load import load_protocol
    from pinarray.schedule import compile_trial
    from pinarray.stop import StopRequest, stop_on_signals

    protocol = load_protocol(args.file)
    plan = make_plan(protocol, seed=args.seed)
    trials = (plan.trial(args.trial),) if args.trial is not None else plan.trials
    clock = choose_clock(args.port, args.time_scale, paced=True, sim_url=args.sim)
    with stop_on_signals(StopRequest()) as stop:
        rig = Rig(protocol, args.port, args.sim, clock, stop, wire_log=args.i2c_log)
        try:
            for warning in rig.warnings:
                say(f"pinarray: warning: {warning}", error=True)
            where = "a player process" if rig.isolated else "this process"
            level = simulation_level(rig.bus)
            servos = rig.url
            if is_sim_url(rig.url):
                servos = f"SIMULATED servos ({rig.url}{f'; {level}' if level else ''})"
            say(f"{protocol.name}: {len(trials)} trial(s) on {servos}, played by {where} "
                f"(seed {plan.seed})")
            undelivered = []
            for planned in trials:
                schedule = compile_trial(protocol, planned)
                presentation = rig.present(schedule)
                kind = "practice" if planned.practice else f"block {planned.block}"
                say(f"trial {planned.trial} ({kind}): {rig.reports[-1].summary()}")
                horns = _simulated_horns(rig, schedule, presentation.onset_ns)
                if horns:
                    say(f"  {horns}")
                if not presentation.delivery.delivered:
                    undelivered.append(planned.trial)
        except BaseException:
            say(f"pinarray: pins after the stop: {rig.close().describe()}", error=True)
            raise
        safe = rig.close()
    total = PlaybackReport.merged(rig.reports)
    say(f"played {len(rig.reports)} trial(s): {total.summary()}, {total.retries} retries; "
        f"{safe.describe()}, torque off")
    if undelivered:
        say(f"pinarray: trial(s) {', '.join(map(str, undelivered))} NOT delivered as scheduled "
            "(see above)", error=True)
        return EXIT_NOT_DELIVERED
    return 0


def _simulated_horns(rig, schedule, onset_ns: int) -> str:
    """On a simulated PWM board: how far each driven pin's simulated hobby servo swung (its
    speed and dead band the protocol's), beside the stroke commanded; empty otherwise."""
    import sys
    from fractions import Fraction

    # A simulated board's link is of the simulator's module, loaded by now if it is one:
    # real servos' runs do not import the simulator to find out they are not simulated.
    simulator = sys.modules.get("pinarray.hardware.pca9685.sim")
    link = getattr(rig.bus, "link", None)
    if simulator is None or not isinstance(link, simulator.SimI2cLink):
        return ""
    from pinarray.hardware.pca9685.servo_sim import HobbyServo, swing_us

    servos = rig.protocol.device.servo
    model = HobbyServo(Fraction(servos.dead_band_us), Fraction(servos.speed_us_per_s))
    board = link.board(rig.bus.setup.address)
    targets = schedule.targets
    parts = []
    for servo in rig.setup.servos:
        mine = targets.position_steps[targets.pin == servo.pin]
        if not len(mine):
            continue
        low, high = (min(int(mine.min()), servo.rest_steps), max(int(mine.max()), servo.rest_steps))
        pulses = board.pulses(servo.servo_id, onset_ns, onset_ns + targets.end_ns)
        reached_low, reached_high = swing_us(model, pulses, Fraction(servo.rest_steps))
        reached = float(reached_high - reached_low)
        short = "" if reached >= high - low - float(model.dead_band_us) else " (SHORT)"
        parts.append(f"pin {servo.pin} {reached:.0f} of {high - low} us{short}")
    return (f"simulated hobby servos ({servos.speed_us_per_s} us/s): swung "
            + ", ".join(parts)) if parts else ""


def chosen_array(args: argparse.Namespace, command: str, device) -> str:
    """`chosen_bus` for a protocol's device, whichever family it is."""
    from pinarray.errors import PinArrayError
    from pinarray.player.families import board_sim_url, bus_setup
    from pinarray.protocol import HobbyServos

    if not isinstance(device.servo, HobbyServos):
        return chosen_bus(args, command, bus_setup(device).servo_ids)
    if args.port:
        return args.port
    if args.sim is None:
        raise PinArrayError(
            f"{command}: which board? add --port PATH for a real one (its I2C bus, e.g. "
            "--port /dev/i2c-1), or --sim to rehearse on a simulated one")
    url = board_sim_url(args.sim, device.servo.board)
    say(f"SIMULATED board ({url}): no real servo is touched")
    return url


def _cmd_timing(args: argparse.Namespace) -> int:

    from pinarray.errors import PinArrayError
    from pinarray.player.rig import Rig, choose_clock
    from pinarray.protocol.load import load_protocol, parse_protocol
    from pinarray.stop import StopRequest, stop_on_signals

    if args.seconds is not None and not 0.1 <= args.seconds <= 600:
        raise PinArrayError(f"--seconds: expected 0.1 to 600, found {args.seconds:g}")
    protocol = load_protocol(args.file) if args.file else parse_protocol(DEFAULT_DEVICE_TEXT, "<default>")
    chosen_array(args, "timing", protocol.device)
    with stop_on_signals(StopRequest()) as stop:
        rig = Rig(protocol, args.port, args.sim, choose_clock(args.port, None), stop)
        try:
            for warning in rig.warnings:
                say(f"pinarray: warning: {warning}", error=True)
            verdict = rig.check_timing(
                None if args.seconds is None else round(args.seconds * 1e9))
        finally:
            rig.close()
    say("\n".join(verdict.lines))
    return 0 if verdict.deliverable else EXIT_NOT_DELIVERED


def _cmd_sim_serve(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pinarray.cli import common
    from pinarray.errors import PinArrayError
    from pinarray.hardware.feetech.faults import parse_sim_url
    from pinarray.hardware.feetech.serve import PtyServer
    from pinarray.stop import StopRequest, stop_on_signals

    common.servo_ids(args.ids)  # refused here, naming the option, rather than inside the URL
    query = f"ids={args.ids}" + (f"&{args.faults.lstrip('?&')}" if args.faults else "")
    config = parse_sim_url(f"sim://?{query}")
    arrivals = None
    if args.arrivals is not None:
        # Opened now, so that a log that could not be written is refused before serving
        # rather than lost at the stop; an earlier log of that name stays until then.
        folder = Path(args.arrivals).parent
        if not folder.is_dir():
            raise PinArrayError(f"--arrivals {args.arrivals}: no folder {folder}")
        try:
            arrivals = common.OutputFile(args.arrivals)
        except PinArrayError as problem:
            raise PinArrayError(f"--arrivals {problem}") from None
    try:
        server = PtyServer(config, record_arrivals=arrivals is not None)
        with stop_on_signals(StopRequest()) as stop:
            stop.when_requested(server.request_stop)
            say(f"simulated servos {args.ids} on {server.path}  (Ctrl-C, SIGTERM or SIGHUP to stop)")
            server.serve_forever()
        if arrivals is not None:
            try:
                rows = server.write_arrivals(arrivals.stream)
            except OSError as problem:
                raise PinArrayError(f"{arrivals.path}: cannot write the arrivals log: "
                                    f"{problem.strerror}") from None
            arrivals.commit()
            say(f"{rows} instruction packet(s) logged to {arrivals.path}")
    finally:
        if arrivals is not None:
            arrivals.discard()
    say("sim-serve stopped")
    return 0
