"""`pinarray validate`, `compile` and `preview`: protocols in, checks and schedules out.

Only argparse at import: `validate` must answer fast and never load Textual or matplotlib.
"""

from __future__ import annotations

import argparse
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("validate", help="check protocol files; one line per problem")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.set_defaults(func=_validate)

    p = subparsers.add_parser("compile", help="write every pulse of every trial as CSV")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--seed", type=int, help="plan seed (default: the protocol's, else a new one)")
    p.add_argument(
        "--out", required=True, help="CSV path (trial,pin,start_ns,width_ns); - for stdout"
    )
    p.add_argument(
        "--targets", help="also write servo target changes (trial,pin,time_ns,position_steps)"
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
    from pinarray.protocol_load import validate_file

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
    return status


def _scaled_notes(protocol) -> list[str]:
    from pinarray.feasibility import check_train
    from pinarray.schedule import trial_drives

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


def _open_out(path: str):
    from pinarray.errors import PinArrayError

    if path == "-":
        return sys.stdout
    try:
        return open(path, "w", newline="", encoding="utf-8")
    except OSError as problem:
        raise PinArrayError(f"{path}: cannot write: {problem.strerror}") from None


def _compile(args: argparse.Namespace) -> int:
    import csv

    from pinarray.plan import make_plan
    from pinarray.protocol_load import load_protocol
    from pinarray.schedule import compile_trial

    protocol = load_protocol(args.file)
    plan = make_plan(protocol, args.seed)
    out = _open_out(args.out)
    targets_out = _open_out(args.targets) if args.targets else None
    pulses = 0
    try:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(["trial", "pin", "start_ns", "width_ns"])
        target_writer = csv.writer(targets_out, lineterminator="\n") if targets_out else None
        if target_writer:
            target_writer.writerow(["trial", "pin", "time_ns", "position_steps"])
        for planned in plan.trials:
            schedule = compile_trial(protocol, planned)
            p = schedule.pulses
            writer.writerows(
                zip(
                    [planned.trial] * len(p),
                    p.pin.tolist(),
                    p.start_ns.tolist(),
                    p.width_ns.tolist(),
                    strict=True,
                )
            )
            pulses += len(p)
            if target_writer:
                t = schedule.targets
                target_writer.writerows(
                    zip(
                        [planned.trial] * len(t),
                        t.pin.tolist(),
                        t.time_ns.tolist(),
                        t.position_steps.tolist(),
                        strict=True,
                    )
                )
    finally:
        for stream in (out, targets_out):
            if stream not in (None, sys.stdout):
                stream.close()
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
