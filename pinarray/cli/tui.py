"""`pinarray tui`: the experimenter's terminal UI (Textual loads only when it runs)."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from pinarray.cli import common

TUI_EPILOG = """\
Opens the start screen: choose the protocol (FILE, or one from protocols/), the subject,
session and experimenter, the array (the simulator, or a serial port found on this machine)
and the plan seed; an unfinished run of the same subject, session and protocol can be
resumed (--subject and --session fill the form in). Pre-flight then connects and shows
every servo; the run screen presents trials and takes answers; the end screen shows the
summary and where the files went.

q or Ctrl-C quit at any moment: a stimulus is cut short, pins go to rest with torque off,
and the run is left resumable. The last line printed says what happened and the command
that continues an unfinished run. --speed runs the simulator faster than real time (e.g. 20
for a quick look); real servos always run in real time.

Exit status: 0 every run opened was completed (or none was); 1 an error the UI could not
handle (the run is marked crashed, resumable; the line names the file with the details);
2 bad input on the command line; 4 quit with a run left unfinished (resumable);
128 + N stopped by signal N (Ctrl-C counts as SIGINT: 130).

In the scanner (--trigger, or the protocol's sync: section) Begin run waits for the first
counted volume ("waiting for scanner", volumes seen; Esc stops waiting) and times the run from
it; a key trigger is a key pressed on that screen. --lsl sends LSL markers.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``tui`` to the `pinarray` parser."""
    from pinarray.cli.bus import add_bus_choice
    from pinarray.journal.paths import DEFAULT_RESULTS_ROOT

    p = subparsers.add_parser(
        "tui", help="run subjects from the experimenter's terminal UI",
        epilog=TUI_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", nargs="?", metavar="FILE", help="protocol YAML file to preselect")
    add_bus_choice(p)
    p.add_argument("--results", default=str(DEFAULT_RESULTS_ROOT), metavar="DIR",
                   help="results folder (default results/)")
    common.add_speed(p, default=1.0,
                     help="simulator only: X times real time (default 1; 20 = twenty times "
                          "faster, 0.5 = half speed, 0 = no waiting at all)")
    p.add_argument("--seed", type=common.seed, help="plan seed shown on the start screen (default: new)")
    p.add_argument("--protocols", default="protocols", metavar="DIR",
                   help="folder the protocol list comes from (default protocols/)")
    p.add_argument("--subject", default="", metavar="ID",
                   help="fill in the subject (with --session: offers that run's Resume)")
    p.add_argument("--session", default="1", metavar="N", help="fill in the session (default 1)")
    common.add_sync_options(p, key=True)
    p.set_defaults(func=_cmd_tui)


def _cmd_tui(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pinarray.errors import PinArrayError
    from pinarray.player.rig import choose_clock

    if args.file and not Path(args.file).is_file():
        raise PinArrayError(f"{args.file}: no such protocol file")
    # What can never work is refused here, not on a screen the experimenter has to leave.
    from pinarray.cli.bus import check_bus_choice

    check_bus_choice(args)
    common.check_output_folder(args.results, ())
    choose_clock(args.port, args.time_scale, sim_url=args.sim)  # refuses --speed up front
    # with real servos, and with a simulated board kept in a state file
    from pinarray.protocol.imaging import EmulatedTrigger, SyncOverrides

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
                            "sped-up simulation is not: use --speed 1")
    # The UI loaded once the options are known to work: a refusal costs no Textual (0.2 s).
    from pinarray.tui.app import PinArrayApp, TuiOptions

    options = TuiOptions(
        protocol_path=Path(args.file) if args.file else None,
        protocols_dir=Path(args.protocols), results_root=Path(args.results),
        port=args.port, sim_url=args.sim, time_scale=args.time_scale, seed=args.seed,
        subject=args.subject, session=args.session,
        sync=sync, lsl=args.lsl,
    )
    from pinarray.stop import note_signals

    app = PinArrayApp(options)
    # A stop signal before the UI's own handlers are in place is noted, and acted on as they
    # are: its default action would end the UI with the terminal left in its hands.
    with on_the_terminal(), note_signals(app.sitting.stop):
        app.run()
    # However the app stopped (even an error Textual reported itself), the run is closed
    # and the pins rest before the line is said.
    status, line = app.outcome()
    print(line, file=sys.stdout if status in (0, 4) else sys.stderr)
    return status


@contextmanager
def on_the_terminal() -> Iterator[None]:
    """While the UI runs, standard output and error are the terminal.

    Textual draws on standard error and measures the terminal through standard output; with
    either going to a pipe or a file (``make run | tee log``) it would draw into the file or
    stay at 80x24 whatever the window. The terminal is the controlling one (``/dev/tty``);
    the line said on exit goes where output went.
    """
    redirected = [fd for fd in (1, 2) if not os.isatty(fd)]
    if not redirected:
        yield
        return
    from pinarray.errors import PinArrayError

    try:
        terminal = os.open("/dev/tty", os.O_RDWR)
    except OSError:
        raise PinArrayError("pinarray tui needs a terminal, and this process has none "
                            "(for sessions without one: pinarray batch)") from None
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in redirected}
    try:
        for fd in redirected:
            os.dup2(terminal, fd)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        for fd, original in saved.items():
            os.dup2(original, fd)
            os.close(original)
        os.close(terminal)
