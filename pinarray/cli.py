"""The `pinarray` command: a composition root that turns user mistakes into one-line errors.

Subcommands import what they need inside their handler, so `pinarray validate` never pays
for Textual or matplotlib.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from pinarray import __version__
from pinarray.errors import PinArrayError
from pinarray.stop import Stopped

Handler = Callable[[argparse.Namespace], int]


def _grid_size(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, found {text!r}") from None
    if not 1 <= value <= 64:
        raise argparse.ArgumentTypeError(f"expected a number from 1 to 64, found {value}")
    return value


def _cmd_grid(args: argparse.Namespace) -> int:
    from pinarray.grid import ERROR_CLASS_MEANING, Grid, render_class_map, render_layout

    grid = Grid(args.rows, args.columns, args.pitch_mm)
    grid.check_pin(args.pin)
    print(
        f"Pin grid {grid.rows}x{grid.columns}, {grid.pitch_mm:g} mm pitch, as the subject feels it:"
    )
    print(render_layout(grid))
    print()
    print(f"Error classes when pin {args.pin} moves (* = correct):")
    print(render_class_map(grid, args.pin))
    print()
    for error_class, meaning in ERROR_CLASS_MEANING.items():
        print(f"  {error_class.value:>7}  {meaning}")
    if args.table:
        print()
        print("stimulated -> class of each reported pin")
        width = len(str(grid.pin_count))
        print(" " * (width + 3) + " ".join(f"{p:>{width}}" for p in grid.pins))
        for s in grid.pins:
            cells = (
                "*" if c.value == "correct" else c.value
                for c in (grid.classify(s, r) for r in grid.pins)
            )
            print(f"{s:>{width}} -> " + " ".join(f"{c:>{width}}" for c in cells))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pinarray",
        description="Drive a servo pin-array tactile stimulator and run experiments on it.",
    )
    parser.add_argument("--version", action="version", version=f"pinarray {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("grid", help="print the pin numbering and the localisation error classes")
    p.add_argument("--rows", type=_grid_size, default=4)
    p.add_argument("--columns", type=_grid_size, default=4)
    p.add_argument("--pitch-mm", type=float, default=2.0)
    p.add_argument("--pin", type=int, default=10, help="stimulated pin to classify around")
    p.add_argument("--table", action="store_true", help="also print the full class table")
    p.set_defaults(func=_cmd_grid)

    for register in _extra_commands():
        register(sub)
    return parser


# Subcommand groups live next to the code they drive; each module defines
# ``register(subparsers)`` and imports only argparse at module level.
COMMAND_MODULES = (
    "pinarray.protocol_commands",
    "pinarray.bus.commands",
    "pinarray.session_commands",
    "pinarray.analysis.commands",
    "pinarray.softness.commands",
    "pinarray.tui.commands",
)


def _extra_commands() -> list[Callable[[argparse._SubParsersAction], None]]:
    import importlib

    return [importlib.import_module(name).register for name in COMMAND_MODULES]


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
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
