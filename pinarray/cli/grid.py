"""`pinarray grid`: the pin numbering and the localisation error classes, printed."""

from __future__ import annotations

import argparse

from pinarray.cli import common

# The class table has a row and a column per pin: 32x32 pins print a million cells.
MAX_TABLE_PINS = 1024


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("grid", help="print the pin numbering and the localisation error classes")
    p.add_argument("--rows", type=common.count(1, 64), default=4)
    p.add_argument("--columns", type=common.count(1, 64), default=4)
    p.add_argument("--pitch-mm", type=common.number(0, 100, above_minimum=True), default=2.0)
    p.add_argument("--pin", type=int, default=10, help="stimulated pin to classify around")
    p.add_argument("--table", action="store_true", help="also print the full class table")
    p.set_defaults(func=_cmd_grid)


def _cmd_grid(args: argparse.Namespace) -> int:
    from pinarray.errors import PinArrayError
    from pinarray.grid import ERROR_CLASS_MEANING, Grid, render_class_map, render_layout

    grid = Grid(args.rows, args.columns, args.pitch_mm)
    grid.check_pin(args.pin)
    if args.table and grid.pin_count > MAX_TABLE_PINS:
        raise PinArrayError(
            f"--table: expected a grid of at most {MAX_TABLE_PINS} pins (a table of "
            f"{MAX_TABLE_PINS ** 2:,} cells), found {grid.pin_count}; use --pin for one pin's map"
        )
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
