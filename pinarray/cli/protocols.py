"""`pinarray validate`, `compile`, `preview` and `plan`: protocols in, checks and schedules out.

Only argparse at import: `validate` must answer fast and never load Textual or matplotlib.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING

from pinarray.cli import common

if TYPE_CHECKING:
    from pinarray.player.rehearsal import Rehearsal
    from pinarray.protocol import Protocol
    from pinarray.protocol.model import Device, PinDrive
    from pinarray.protocol.seam import Rehearse

# Plans hold at most 20 000 trials (`pinarray.protocol.design.MAX_TRIALS`); a number past
# them is refused by the plan with the plan's own range.
MAX_TRIAL_NUMBER = 1_000_000

# `compile --daq-rate`: whole Hz, so that every sample instant is exact in integer ns
# arithmetic; NI's X-series cards time digital output at up to 10 MHz; a servo pulse needs far less (1 MHz puts each
# edge within 1 us).
MAX_DAQ_RATE_HZ = 10_000_000


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("validate", help="check protocol files; one line per problem")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.set_defaults(func=_validate)

    p = subparsers.add_parser(
        "compile", help="write every pulse of every trial as CSV or a numpy archive (.npz)"
    )
    p.add_argument("file", metavar="FILE")
    p.add_argument("--seed", type=common.seed,
                   help="plan seed (default: the protocol's, else a new one)")
    p.add_argument(
        "--out",
        required=True,
        help="trial,pin,start_ns,width_ns as CSV (- for stdout), or arrays in a .npz file",
    )
    p.add_argument(
        "--targets",
        help="also write servo target changes (trial,pin,time_ns,position_steps), CSV or .npz",
    )
    p.add_argument(
        "--daq-rate", type=common.count(1, MAX_DAQ_RATE_HZ), metavar="HZ",
        help="write instead the samples of a DAQ card's 16 digital lines at HZ samples a second "
        "(a whole number, 1 Hz to 10 MHz) to --out FILE.npz: `samples` (uint16, bit n-1 = pin "
        "n), `sample_rate_hz`, and per trial `trial_first_sample`, `trial_sample_count` and its "
        "condition (`trial_pin`, `trial_frequency_hz`, ...; `plan` as JSON) in plan order. "
        "Sample k is at k/HZ s from the trial's onset and is high while a pulse covers that "
        "instant, so each edge is up to one sample late. The trials' samples lie back to back "
        "with no inter-trial interval (a sitting waits for the answer): play each trial's run "
        "as one finite hardware-timed task at its onset; its last sample is low on every line",
    )
    p.add_argument(
        "--allow-long",
        action="store_true",
        help="let a trial hold more than the 1 000 000 pulses one may play (up to the plan's "
        "10 000 000): a schedule written to a file only, e.g. a 24 h endurance run",
    )
    p.set_defaults(func=_compile)

    p = subparsers.add_parser("preview", help="a timeline of one trial's pins")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--trial", type=common.count(1, MAX_TRIAL_NUMBER), default=1,
                   help="trial number in the plan (default 1)")
    p.add_argument("--seed", type=common.seed,
                   help="plan seed (default: the protocol's, else a new one, printed)")
    p.add_argument("--width", type=common.count(20, 1000), default=72,
                   help="columns of the text timeline (20 to 1000, default 72)")
    p.add_argument("--png", help="also draw the timeline to this PNG file")
    p.set_defaults(func=_preview)

    p = subparsers.add_parser(
        "plan", help="print the trial plan (trial -> pin and frequency, or wave), e.g. for a "
        "paper answer sheet")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--seed", type=common.seed,
                   help="plan seed (default: the protocol's, else a new one, printed: give the "
                   "run the same --seed, or type it in the UI's Seed field)")
    p.add_argument("--tsv", action="store_true",
                   help="tab-separated with a header row, for a spreadsheet (default: a table "
                   "with an empty answer column to print)")
    p.set_defaults(func=_plan)


def _validate(args: argparse.Namespace) -> int:
    from pinarray.protocol.load import protocol_warnings, validate_file

    status = 0
    for path in args.files:
        with _rehearsal() as rehearse:
            protocol, problems = validate_file(path, rehearse)
        if problems:
            status = 2
            for line in problems:
                print(line, file=sys.stderr)
        else:
            assert protocol is not None
            refusals = _board_refusals(protocol)
            if refusals:
                status = 2
                for line in refusals:
                    print(f"{path}: {line}", file=sys.stderr)
                continue
            design = protocol.design
            adaptive = design.adaptive
            if adaptive is None:
                print(f"{path}: ok ({design.paradigm.name}, "
                      f"{len(design.conditions) * design.repetitions * design.blocks} trials in "
                      f"{design.blocks} block(s), {design.practice_trials} practice)")
            else:
                values = adaptive.values
                print(f"{path}: ok ({design.paradigm.name}, adaptive: "
                      f"{adaptive.parameter.value} over {len(values)} values "
                      f"({float(values[0]):g}..{float(values[-1]):g} {adaptive.parameter.unit}), "
                      f"{len(adaptive.procedures)} procedures, at most {design.trial_count} trials "
                      f"with {adaptive.catch.count} catch and {design.practice_trials} practice)")
            print(f"{path}: feasibility: {protocol.device.feasibility_basis()}")
            for note in _scaled_notes(protocol):
                print(f"{path}: note: {note}")
            for warning in protocol_warnings(protocol):
                print(f"{path}: warning: {warning}", file=sys.stderr)
    return status


@contextlib.contextmanager
def _rehearsal() -> Iterator[Rehearse]:
    """Each condition that passes every check played on the simulated array, as a run plays
    it (`pinarray.player.rehearsal`); the simulator and numpy are loaded only when a
    protocol's stimuli are played there."""
    rehearsal: Rehearsal | None = None

    def rehearse(drives: Sequence[PinDrive], device: Device) -> str | None:
        nonlocal rehearsal
        from pinarray.player.rehearsal import Rehearsal

        if rehearsal is None:
            rehearsal = Rehearsal()
        return rehearsal(drives, device)

    try:
        yield rehearse
    finally:
        if rehearsal is not None:
            rehearsal.close()


def _board_refusals(protocol) -> tuple[str, ...]:
    """On a PWM board, each condition planned as playing it would (loads numpy: only then)."""
    from pinarray.protocol import HobbyServos

    if not isinstance(protocol.device.servo, HobbyServos):
        return ()
    from pinarray.player.families import board_refusals

    return board_refusals(protocol)


def _scaled_notes(protocol) -> list[str]:
    from pinarray.protocol.drives import trial_drives
    from pinarray.protocol.feasibility import check_train

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
            result = check_train(drive.train, calibration, protocol.device)
            if not result.feasible:
                notes.append(
                    f"scaled to {result.amplitude_fraction:.0%}: "
                    + result.describe(protocol.device.servo, protocol.device.mm_per_step(drive.pin))
                )
    return notes


# Column names and the types a numpy archive stores them as (the schedule's own).
PULSE_COLUMNS = (("trial", "int32"), ("pin", "int16"), ("start_ns", "int64"), ("width_ns", "int64"))
TARGET_COLUMNS = (
    ("trial", "int32"), ("pin", "int16"), ("time_ns", "int64"), ("position_steps", "int32")
)


# Array elements, and CSV rows (as Python objects, some 40x larger), handed on at once: they
# bound what writing a long trial adds to memory.
_BLOCK = 1 << 20
_CSV_ROWS = 1 << 16


class _CsvTable:
    """A CSV file with a header row, written a trial at a time, a block of rows at a time."""

    def __init__(self, path: str, columns: tuple[str, ...]) -> None:
        import csv

        self.output = common.OutputFile(path)
        self.writer = csv.writer(self.output.stream, lineterminator="\n")
        self._writing(self.writer.writerow, columns)

    def add(self, trial: int, *columns) -> None:
        import numpy as np

        # Whole numbers (every table compile writes) as the csv writer writes them, formatted
        # here in half its time (a 10-hour train is a million rows).
        whole = all(np.issubdtype(c.dtype, np.integer) for c in columns)
        line = "%d," * len(columns) + "%d\n"
        for a in range(0, len(columns[0]), _CSV_ROWS):
            block = [c[a : a + _CSV_ROWS].tolist() for c in columns]
            rows = zip([trial] * len(block[0]), *block, strict=True)
            if whole:
                self._writing(self.output.stream.write, "".join([line % row for row in rows]))
            else:
                self._writing(self.writer.writerows, rows)

    def finish(self) -> None:
        self.output.flush()

    def _writing(self, write: Callable, rows) -> None:
        try:
            write(rows)
        except OSError as problem:
            _cannot_write(self.output, problem)


class _NpzTable:
    """A numpy archive of one array per column, written once every trial is compiled.

    The first column is the trial number (int32), the others keep the types given (times int64
    ns). Each column is streamed into its ``.npy`` member a block at a time, from the trials as
    compiled: they are never joined into whole columns, as `np.savez` would need, so the file
    costs no copy of them (the plan's `MAX_PULSES` bounds what the trials hold). The file is
    opened at once so that an unwritable path fails before the compile.
    """

    def __init__(self, path: str, columns: tuple[tuple[str, str], ...]) -> None:
        self.columns = columns
        self.output = common.OutputFile(path, binary=True)
        self.parts: list[tuple[int, tuple]] = []

    def add(self, trial: int, *columns) -> None:
        self.parts.append((trial, columns))

    def finish(self) -> None:
        import zipfile

        # A device: zipfile would trust its position (/dev/null's stays 0) for the offsets.
        device = self.output.temporary is None
        stream = _Unseekable(self.output.stream) if device else self.output.stream
        try:
            # Stored, not compressed, and zip64 as `np.savez` writes: `np.load` reads it alike.
            with zipfile.ZipFile(stream, "w", zipfile.ZIP_STORED) as archive:
                for index, (name, dtype) in enumerate(self.columns):
                    with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                        self._write_column(member, index, dtype)
        except OSError as problem:
            _cannot_write(self.output, problem)
        self.output.flush()

    def _write_column(self, member, index: int, dtype: str) -> None:
        import numpy as np

        count = sum(len(columns[0]) for _, columns in self.parts)
        header = {
            "descr": np.lib.format.dtype_to_descr(np.dtype(dtype)),
            "fortran_order": False,
            "shape": (count,),
        }
        np.lib.format.write_array_header_1_0(member, header)
        for trial, columns in self.parts:
            if index == 0:
                block = np.full(min(_BLOCK, len(columns[0])), trial, dtype)
                for a in range(0, len(columns[0]), _BLOCK):
                    member.write(block[: len(columns[0]) - a])
                continue
            column = columns[index - 1]
            for a in range(0, len(column), _BLOCK):
                member.write(np.ascontiguousarray(column[a : a + _BLOCK], dtype))


class _Unseekable:
    """A stream with neither ``tell`` nor ``seek``: zipfile then counts the offsets itself."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, data: bytes) -> int:
        return self._stream.write(data)

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        pass  # the output file's own `commit` or `discard` closes it


def _cannot_write(output: common.OutputFile, problem: OSError):
    from pinarray.errors import PinArrayError

    output.discard()
    raise PinArrayError(f"{output.path}: cannot write: {problem.strerror}") from None


def _table(path: str, columns: tuple[tuple[str, str], ...]) -> _CsvTable | _NpzTable:
    """The output for ``path``: a numpy archive for a ``.npz`` name, else CSV (``-``: stdout)."""
    if path.lower().endswith(".npz"):
        return _NpzTable(path, columns)
    return _CsvTable(path, tuple(name for name, _ in columns))


def _refuse_adaptive(protocol: Protocol, command: str, does: str) -> None:
    """An adaptive design's values are decided as its run goes: no schedule stands before."""
    from pinarray.errors import PinArrayError

    if protocol.design.adaptive is not None:
        raise PinArrayError(
            f"{protocol.source}: {command} {does}; this design adapts "
            f"{protocol.design.adaptive.parameter.value} as the run goes (its values are chosen "
            "from the answers): run it with pinarray batch or the UI, or rehearse its procedures "
            "with pinarray power")


def _compile(args: argparse.Namespace) -> int:
    from pinarray.plan import make_plan
    from pinarray.protocol.load import load_protocol
    from pinarray.schedule import compile_trial

    if args.daq_rate is not None:
        from pinarray.cli.daq_samples import DaqSamples, check_out

        check_out(args.out)
    protocol = load_protocol(args.file, long_trials=args.allow_long)
    _refuse_adaptive(protocol, "compile", "writes a fixed plan's schedules")
    plan = make_plan(protocol, args.seed)
    tables: list[_CsvTable | _NpzTable] = []
    outputs: list[common.OutputFile] = []
    daq = None
    pulses = 0

    def compiled():
        nonlocal pulses
        for planned in plan.trials:
            schedule = compile_trial(protocol, planned)
            p = schedule.pulses
            if daq is None:
                tables[0].add(planned.trial, p.pin, p.start_ns, p.width_ns)
            pulses += len(p)
            if args.targets:
                t = schedule.targets
                tables[-1].add(planned.trial, t.pin, t.time_ns, t.position_steps)
            yield planned, schedule

    try:
        if args.daq_rate is None:
            tables.append(_table(args.out, PULSE_COLUMNS))
            outputs.append(tables[-1].output)
        else:
            daq = DaqSamples(args.out, protocol, plan, args.daq_rate)
            outputs.append(daq.output)
        if args.targets:
            tables.append(_table(args.targets, TARGET_COLUMNS))
            outputs.append(tables[-1].output)
        if daq is None:
            for _ in compiled():
                pass
        else:
            daq.write(compiled())  # the samples are streamed as each trial is compiled
        for table in tables:
            table.finish()
        # Put in place only once every one is written: a failed one leaves none of them.
        for output in outputs:
            output.commit()
    finally:
        for output in outputs:
            output.discard()  # nothing left of a file not finished
    what = f"{args.out}" if daq is None else (
        f"{args.out}: {daq.total:,} samples at {args.daq_rate:,} Hz (each edge up to one "
        f"sample, {1e6 / args.daq_rate:g} us, late)")
    print(f"{args.file}: {len(plan)} trials, {pulses} pulses, seed {plan.seed} -> {what}",
          file=sys.stderr)
    return 0


def _preview(args: argparse.Namespace) -> int:
    from pinarray.cli.timeline import text_timeline
    from pinarray.plan import make_plan
    from pinarray.protocol.load import load_protocol
    from pinarray.schedule import compile_trial

    protocol = load_protocol(args.file)
    _refuse_adaptive(protocol, "preview", "draws a trial of a fixed plan")
    plan = make_plan(protocol, args.seed)
    planned = plan.trial(args.trial)
    schedule = compile_trial(protocol, planned)
    # Opened before the timeline is printed: a PNG that cannot be written is refused first.
    output = common.OutputFile(common.png_path(args.png), binary=True) if args.png else None
    try:
        print(text_timeline(protocol, planned, schedule, args.width))
        if args.seed is None and protocol.design.seed is None:
            print(f"(plan seed {plan.seed}, drawn for this preview: --seed {plan.seed} shows the "
                  "same plan again)")
        else:
            print(f"(plan seed {plan.seed})")
        if output is not None:
            from pinarray.cli.timeline import draw_timeline

            try:
                draw_timeline(protocol, planned, schedule, output.stream)
            except OSError as problem:
                _cannot_write(output, problem)
            output.commit()
            print(f"timeline drawn to {output.path}")
    finally:
        if output is not None:
            output.discard()  # nothing left of a picture not finished
    return 0


def _plan(args: argparse.Namespace) -> int:
    from pinarray.plan import make_plan
    from pinarray.protocol.load import load_protocol

    protocol = load_protocol(args.file)
    plan = make_plan(protocol, args.seed)
    paradigm = protocol.design.paradigm
    header = ["trial", "block", "practice", "stimulus", *paradigm.plan_columns]
    rows = []
    for planned in plan.trials:
        c = planned.condition
        what = paradigm.plan_cells(c)
        rows.append([str(planned.trial), str(planned.block),
                     "yes" if planned.practice else "no", c.stimulus, *what])
    practice = sum(t.practice for t in plan.trials)
    drawn = args.seed is None and protocol.design.seed is None
    follow = (f"seed {plan.seed}, drawn now: run with --seed {plan.seed} (or that Seed in the UI) "
              "to follow this plan" if drawn else f"seed {plan.seed}")
    if args.tsv:
        print("\t".join(header))
        for row in rows:
            print("\t".join(row))
        print(f"# {protocol.name}: {len(plan)} trials ({practice} practice), {follow}",
              file=sys.stderr)
        return 0
    print(f"{protocol.name}: {len(plan)} trials ({practice} practice), {follow}")
    header.append("answer")
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header[:-1])]
    widths.append(len("answer"))
    print("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip())
    for row in rows:
        cells = [c.rjust(w) if c.isdigit() else c.ljust(w)
                 for c, w in zip(row, widths[:-1], strict=True)]
        print("  ".join(cells) + "  " + "_" * widths[-1])
    return 0
