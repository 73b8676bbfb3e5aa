"""`pinarray validate`, `compile` and `preview`: protocols in, checks and schedules out.

Only argparse at import: `validate` must answer fast and never load Textual or matplotlib.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("validate", help="check protocol files; one line per problem")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.set_defaults(func=_validate)

    p = subparsers.add_parser(
        "compile", help="write every pulse of every trial as CSV or a numpy archive (.npz)"
    )
    p.add_argument("file", metavar="FILE")
    p.add_argument("--seed", type=int, help="plan seed (default: the protocol's, else a new one)")
    p.add_argument(
        "--out",
        required=True,
        help="trial,pin,start_ns,width_ns as CSV (- for stdout), or arrays in a .npz file",
    )
    p.add_argument(
        "--targets",
        help="also write servo target changes (trial,pin,time_ns,position_steps), CSV or .npz",
    )
    p.set_defaults(func=_compile)

    p = subparsers.add_parser("preview", help="a timeline of one trial's pins")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--trial", type=int, default=1, help="trial number in the plan (default 1)")
    p.add_argument("--seed", type=int)
    p.add_argument("--width", type=int, default=72, help="columns of the text timeline")
    p.add_argument("--png", help="also draw the timeline to this PNG file")
    p.set_defaults(func=_preview)


def _validate(args: argparse.Namespace) -> int:
    from pinarray.protocol_load import protocol_warnings, validate_file

    status = 0
    for path in args.files:
        protocol, problems = validate_file(path)
        if problems:
            status = 2
            for line in problems:
                print(line, file=sys.stderr)
        else:
            assert protocol is not None
            design = protocol.design
            print(
                f"{path}: ok ({design.paradigm.value}, {len(design.conditions) * design.repetitions * design.blocks}"
                f" trials in {design.blocks} block(s), {design.practice_trials} practice)"
            )
            for note in _scaled_notes(protocol):
                print(f"{path}: note: {note}")
            for warning in protocol_warnings(protocol):
                print(f"{path}: warning: {warning}", file=sys.stderr)
    return status


def _scaled_notes(protocol) -> list[str]:
    from pinarray.drives import trial_drives
    from pinarray.feasibility import check_train

    if not protocol.device.scale_infeasible:
        return []
    notes = []
    seen = set()
    for condition in protocol.design.conditions:
        for drive in trial_drives(protocol, condition):
            key = (drive.pin, drive.train)
            if key in seen:
                continue
            seen.add(key)
            calibration = protocol.device.calibration(drive.pin)
            result = check_train(drive.train, calibration, protocol.device.servo)
            if not result.feasible:
                notes.append(
                    f"scaled to {result.amplitude_fraction:.0%}: "
                    + result.describe(protocol.device.servo, calibration.lever_mm)
                )
    return notes


PULSE_COLUMNS = ("trial", "pin", "start_ns", "width_ns")
TARGET_COLUMNS = ("trial", "pin", "time_ns", "position_steps")


def _open_out(path: str, binary: bool = False):
    from pinarray.errors import PinArrayError

    if path == "-":
        return sys.stdout
    try:
        if binary:
            return open(path, "wb")
        return open(path, "w", newline="", encoding="utf-8")
    except OSError as problem:
        raise PinArrayError(f"{path}: cannot write: {problem.strerror}") from None


class _CsvTable:
    """A CSV file with a header row, written a trial at a time."""

    def __init__(self, path: str, columns: tuple[str, ...]) -> None:
        import csv

        self.stream = _open_out(path)
        self.writer = csv.writer(self.stream, lineterminator="\n")
        self.writer.writerow(columns)

    def add(self, trial: int, *columns) -> None:
        rows = zip([trial] * len(columns[0]), *(c.tolist() for c in columns), strict=True)
        self.writer.writerows(rows)

    def close(self, complete: bool) -> None:
        if self.stream is not sys.stdout:
            self.stream.close()


class _NpzTable:
    """A numpy archive of one array per column, written whole once every trial is compiled.

    Times stay int64 ns; the file is opened at once so that an unwritable path fails before
    the compile, and is removed again if the compile fails.
    """

    def __init__(self, path: str, columns: tuple[str, ...]) -> None:
        self.path, self.columns = path, columns
        self.stream = _open_out(path, binary=True)
        self.parts: list[tuple[int, tuple]] = []

    def add(self, trial: int, *columns) -> None:
        self.parts.append((trial, columns))

    def close(self, complete: bool) -> None:
        import os

        import numpy as np

        from pinarray.errors import PinArrayError

        try:
            if complete:
                arrays = {
                    self.columns[0]: np.concatenate(
                        [np.full(len(c[0]), t, np.int32) for t, c in self.parts]
                        or [np.empty(0, np.int32)]
                    )
                }
                for i, name in enumerate(self.columns[1:]):
                    arrays[name] = np.concatenate([c[i] for _, c in self.parts])
                savez: Callable[..., None] = np.savez  # its stubs type **arrays as its flags
                savez(self.stream, **arrays)
        except OSError as problem:
            raise PinArrayError(f"{self.path}: cannot write: {problem.strerror}") from None
        finally:
            self.stream.close()
            if not complete:
                os.remove(self.path)


def _table(path: str, columns: tuple[str, ...]) -> _CsvTable | _NpzTable:
    """The output for ``path``: a numpy archive for a ``.npz`` name, else CSV (``-``: stdout)."""
    if path.lower().endswith(".npz"):
        return _NpzTable(path, columns)
    return _CsvTable(path, columns)


def _compile(args: argparse.Namespace) -> int:
    from pinarray.plan import make_plan
    from pinarray.protocol_load import load_protocol
    from pinarray.schedule import compile_trial

    protocol = load_protocol(args.file)
    plan = make_plan(protocol, args.seed)
    tables = [_table(args.out, PULSE_COLUMNS)]
    pulses = 0
    complete = False
    try:
        if args.targets:
            tables.append(_table(args.targets, TARGET_COLUMNS))
        for planned in plan.trials:
            schedule = compile_trial(protocol, planned)
            p = schedule.pulses
            tables[0].add(planned.trial, p.pin, p.start_ns, p.width_ns)
            pulses += len(p)
            if args.targets:
                t = schedule.targets
                tables[1].add(planned.trial, t.pin, t.time_ns, t.position_steps)
        complete = True
    finally:
        for table in tables:
            table.close(complete)
    print(
        f"{args.file}: {len(plan)} trials, {pulses} pulses, seed {plan.seed} -> {args.out}",
        file=sys.stderr,
    )
    return 0


def _preview(args: argparse.Namespace) -> int:
    from pinarray.plan import make_plan
    from pinarray.preview import text_timeline
    from pinarray.protocol_load import load_protocol
    from pinarray.schedule import compile_trial

    protocol = load_protocol(args.file)
    plan = make_plan(protocol, args.seed)
    planned = plan.trial(args.trial)
    schedule = compile_trial(protocol, planned)
    print(text_timeline(protocol, planned, schedule, max(20, args.width)))
    if args.png:
        from pinarray.preview import draw_timeline

        draw_timeline(protocol, planned, schedule, args.png)
        print(f"timeline drawn to {args.png}")
    return 0
