"""`pinarray tui`: the experimenter's terminal UI (Textual loads only when it runs)."""

import argparse

from pinarray.cli import common

TUI_EPILOG = """\
Opens the start screen: choose the protocol (FILE, or one from protocols/), the subject,
session and experimenter, the array (the simulator, or a serial port found on this machine)
and the plan seed; an unfinished run of the same subject, session and protocol can be
resumed. Pre-flight then connects and shows every servo; the run screen presents trials and
takes answers; the end screen shows the summary and where the files went.

q or Ctrl-C quit at any moment: a stimulus is cut short, pins go to rest with torque off,
and the run is left resumable. --time-scale speeds the simulator up (e.g. 20 for a quick
look); real servos always run in real time.

In the scanner (--trigger, or the protocol's sync: section) Begin run waits for the first
counted volume ("waiting for scanner", volumes seen; Esc stops waiting) and times the run from
it; a key trigger is a key pressed on that screen. --lsl sends LSL markers.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``tui`` to the `pinarray` parser."""
    from pinarray.cli.bus import add_bus_choice

    p = subparsers.add_parser(
        "tui", help="run subjects from the experimenter's terminal UI",
        epilog=TUI_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", nargs="?", metavar="FILE", help="protocol YAML file to preselect")
    add_bus_choice(p)
    p.add_argument("--results", default="results", metavar="DIR",
                   help="results folder (default results/)")
    p.add_argument("--time-scale", type=common.time_scale, default=1.0, metavar="X",
                   help="simulator only: real time sped up X times (default 1; 0 = virtual time)")
    p.add_argument("--seed", type=common.seed, help="plan seed shown on the start screen (default: new)")
    p.add_argument("--protocols", default="protocols", metavar="DIR",
                   help="folder the protocol list comes from (default protocols/)")
    common.add_sync_options(p, key=True)
    p.set_defaults(func=_cmd_tui)


def _cmd_tui(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pinarray.errors import PinArrayError
    from pinarray.rig import choose_clock
    from pinarray.tui.app import PinArrayApp, TuiOptions

    if args.file and not Path(args.file).is_file():
        raise PinArrayError(f"{args.file}: no such protocol file")
    choose_clock(args.port, args.time_scale)  # refuses --time-scale with real servos, up front
    from pinarray.protocol.sync import EmulatedTrigger, SyncOverrides

    sync = common.sync_overrides(args)  # put over the chosen protocol's sync: at Begin run
    if args.file and sync != SyncOverrides():  # checked now when the protocol is known
        from pinarray.protocol.load import load_protocol

        sync.over(load_protocol(args.file).sync)
    wall = [name for name, given in (("--lsl", args.lsl is not None),
                                     ("--trigger", sync.trigger is not None
                                      and not isinstance(sync.trigger, EmulatedTrigger)))
            if given]
    if wall and not args.port and args.time_scale != 1:
        raise PinArrayError(f"{' and '.join(wall)}: stamped on this machine's clock, which a "
                            "sped-up simulation is not: use --time-scale 1")
    options = TuiOptions(
        protocol_path=Path(args.file) if args.file else None,
        protocols_dir=Path(args.protocols), results_root=Path(args.results),
        port=args.port, sim_url=args.sim, time_scale=args.time_scale, seed=args.seed,
        sync=sync, lsl=args.lsl,
    )
    app = PinArrayApp(options)
    try:
        pins_left = app.run()
    finally:
        # However the app stopped (even a crash), the run is closed and the pins rest.
        safe = app.lab.finish()
    if safe is not None:
        from pinarray.player import describe

        pins_left = describe(safe)
    if pins_left:
        print(f"pinarray: pins: {pins_left}")
    return 0
