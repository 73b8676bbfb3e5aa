"""The `pinarray` command: a composition root that turns user mistakes into one-line errors.

Each subcommand group is a module of this package with ``register(subparsers)``; only argparse
is imported at module level and each handler imports what it needs when it runs, so
``pinarray validate`` never pays for numpy, Textual or matplotlib.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Sequence

from pinarray import __version__
from pinarray.cli import analysis, batch, bus, grid, protocols, servos, softness, tui
from pinarray.errors import PinArrayError
from pinarray.stop import Stopped

COMMANDS = (grid, protocols, bus, servos, batch, analysis, softness, tui)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pinarray",
        description="Drive a servo pin-array tactile stimulator and run experiments on it.",
    )
    parser.add_argument("--version", action="version", version=f"pinarray {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    for command in COMMANDS:
        command.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except Stopped as stopped:
        print(f"pinarray: {stopped}", file=sys.stderr)
        return stopped.exit_status
    except PinArrayError as error:
        for line in str(error).splitlines() or [type(error).__name__]:
            print(f"pinarray: {line}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pinarray: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (``pinarray play ... | head``): end as if by SIGPIPE, quietly.
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except OSError:
            pass
        return 128 + signal.SIGPIPE


if __name__ == "__main__":
    raise SystemExit(main())
