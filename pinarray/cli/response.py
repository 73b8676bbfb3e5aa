"""`pinarray servos response PROTOCOL --pin N`: what one servo really does (the measuring is in
`pinarray.player.response`; the file it writes, in `pinarray.protocol.response`)."""

from __future__ import annotations

import argparse

from pinarray.cli.output import say

RESPONSE_EPILOG = """\
Plays the protocol's train (its first stimulus, or --stimulus) on one pin at each frequency
and stroke, CYCLES cycles each from rest, and reads the pin's Present Position between the
frames: for each, the stroke the pin achieved (the smallest peak-to-peak over the cycles), the
median, the lag from a goal change to the pin's arrival, and the cycles that fell short. It
prints a table, draws the response (FILE's .png and .pdf) and writes FILE (YAML). Name that file in the
protocol, device: response: FILE (relative to the protocol), and the feasibility check follows
the measured response instead of the datasheet's speed: a train the servo was measured not to
follow (below the protocol's stroke_tolerance_percent) is refused before it plays, and the
pre-flight says which basis it used. Measure again after changing the servo's speed or
acceleration settings, its supply or its load.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``response`` to the ``servos`` group."""
    from pinarray.cli import common
    from pinarray.cli.servos import bus_options

    p = subparsers.add_parser(
        "response", help="measure one servo's achieved stroke and lag over frequencies and "
        "strokes; write the response file feasibility can follow", epilog=RESPONSE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("protocol", metavar="PROTOCOL", help="protocol YAML: its device and train")
    p.add_argument("--pin", type=common.count(1, 4096), required=True, metavar="N",
                   help="the pin whose servo to measure")
    p.add_argument("--stimulus", metavar="NAME", help="the stimulus whose train to play "
                   "(default: the protocol's first)")
    p.add_argument("--frequencies", metavar="HZ,...", help="frequencies to play, in Hz "
                   "(default 1,2,3,5,7,10,12,15,20)")
    p.add_argument("--strokes", metavar="STEPS,...", help="strokes to play, in steps (default: "
                   "a quarter, half, three quarters and all of the pin's calibrated stroke)")
    p.add_argument("--cycles", type=common.count(2, 1000), default=10, metavar="N",
                   help="cycles each train plays (default 10)")
    p.add_argument("--out", metavar="FILE", help="the response file to write (default: "
                   "beside the protocol, PROTOCOL_response_pinN.yaml; the figure beside it)")
    bus_options(p, baud_default="the protocol's")
    p.set_defaults(func=_cmd_response)


def _numbers(text: str, option: str, integer: bool) -> list:
    """Comma-separated numbers above 0 (at most 1000 unless whole), each once, written as a
    protocol writes them (``0.5``, ``1/3``; ``1e-400`` is refused, not made 0 or exact)."""
    from pinarray.errors import PinArrayError
    from pinarray.protocol.yaml_nodes import exact_number

    values = []
    for part in text.split(","):
        try:
            value = exact_number(part)
            if integer and value.denominator != 1:
                raise ValueError(f"expected whole numbers, found {part.strip()!r}")
        except ValueError as problem:
            raise PinArrayError(f"{option}: {problem} (numbers separated by commas)") from None
        if value <= 0 or (not integer and value > 1000) or (integer and value > 10**6):
            raise PinArrayError(f"{option}: expected values above 0 and at most "
                                f"{'1000000' if integer else '1000'}, found {part.strip()}")
        if value in values:
            raise PinArrayError(f"{option}: {part.strip()} is given twice")
        values.append(int(value) if integer else value)
    return sorted(values)


def _cmd_response(args: argparse.Namespace) -> int:
    from datetime import datetime
    from fractions import Fraction
    from pathlib import Path

    from pinarray.analysis.plots import plot_response
    from pinarray.cli import common
    from pinarray.cli.bus import chosen_bus
    from pinarray.errors import PinArrayError
    from pinarray.journal.files import write_atomically
    from pinarray.player import response as measuring
    from pinarray.player.families import bus_setup
    from pinarray.player.rig import Rig, choose_clock
    from pinarray.protocol import HobbyServos
    from pinarray.protocol.load import load_protocol
    from pinarray.protocol.response import response_text
    from pinarray.stop import StopRequest, stop_on_signals

    protocol = load_protocol(args.protocol)
    device = protocol.device
    if isinstance(device.servo, HobbyServos):
        raise PinArrayError("servos response: hobby servos on a PWM board do not report their "
                            "position; it measures bus servos")
    device.calibration(args.pin)  # a pin the grid does not have: refused, naming it
    name, train = measuring.protocol_train(protocol, args.stimulus)
    frequencies = ([Fraction(f) for f in measuring.DEFAULT_FREQUENCIES_HZ]
                   if args.frequencies is None else _numbers(args.frequencies, "--frequencies",
                                                             integer=False))
    strokes = (measuring.default_strokes(protocol, args.pin, train) if args.strokes is None
               else _numbers(args.strokes, "--strokes", integer=True))
    playing = measuring.check_playing_time(frequencies, len(strokes), args.cycles)
    trains = measuring.response_trains(protocol, args.pin, train, frequencies, strokes,
                                       args.cycles)  # refused before anything moves
    out = Path(args.out) if args.out else Path(args.protocol).with_name(
        f"{Path(args.protocol).stem}_response_pin{args.pin}.yaml")
    if out.suffix.lower() not in (".yaml", ".yml"):  # the figure's .png and .pdf go beside it
        raise PinArrayError(f"--out: expected a response file ending in .yaml, found {out}")
    figure = out.with_suffix("")
    for written in (out, figure.with_suffix(".png"), figure.with_suffix(".pdf")):
        common.check_new_file(str(written))  # before measuring, not after
    url = chosen_bus(args, "servos response", bus_setup(device).servo_ids)
    port = args.port if args.port else None
    say(f"pin {args.pin}: {name}'s train at {len(frequencies)} frequencies x {len(strokes)} "
        f"strokes, {args.cycles} cycles each: about {playing} of playing, a line per train")
    say(f"{'Hz':>7} {'stroke':>7} {'achieved':>9} {'median':>7} {'share':>6} {'lag ms':>7} "
        f"{'short':>6}")

    def show(point: measuring.Measured) -> None:
        if isinstance(point, measuring.NotMeasured):
            say(f"{float(point.frequency_hz):7g} {point.stroke_steps:7d}  not measured: "
                f"{point.problem}")
            return
        lag = "-" if point.lag_ms is None else f"{point.lag_ms:.1f}"
        say(f"{point.frequency_hz:7g} {point.commanded_steps:7d} {point.achieved_steps:9d} "
            f"{point.median_steps:7g} {point.achieved_steps / point.commanded_steps:6.0%} "
            f"{lag:>7} {point.cycles_short:6d}")

    clock = choose_clock(port, None)
    with stop_on_signals(StopRequest()) as stop:
        rig = Rig(protocol, port, None if port else url, clock, stop)
        try:
            for warning in rig.warnings:
                say(f"pinarray: warning: {warning}", error=True)
            results = measuring.measure_response(rig, args.pin, trains, show)
        except BaseException:
            say(f"pinarray: pins after the stop: {rig.close().describe()}", error=True)
            raise
        safe = rig.close()
    say(f"{safe.describe()}, torque off")
    response = measuring.response_of(protocol, args.pin, train, url, results, args.cycles)
    if not response.points:
        raise PinArrayError(f"servos response: pin {args.pin}: no train could be measured "
                            "(see above); nothing written")
    write_atomically(out, response_text(response, datetime.now().astimezone().isoformat(
        timespec="seconds")))
    drawn = plot_response(response, figure, f"{protocol.name}: pin {args.pin}, {url}")
    say(f"wrote {out} and {', '.join(map(str, drawn))}")
    reference = Path(out).resolve()
    try:
        reference = reference.relative_to(Path(args.protocol).resolve().parent)
    except ValueError:
        pass
    say(f"to follow it: device: response: {reference} (in {args.protocol})")
    return 0
