"""`pinarray batch`: run whole sessions without a UI, answered from a file or a simulated observer."""

from __future__ import annotations

import argparse
import sys

from pinarray.cli.bus import add_bus_choice
from pinarray.journal.paths import DEFAULT_RESULTS_ROOT

BATCH_EPILOG = """\
Answers come from --responses FILE (CSV with columns trial,response; a pin number or 'none'
for localisation, none/left/right/unsure for apparent motion) or from --observer MODEL, a
simulated subject: 'default' reproduces the seed's figures, or override parameters such as
'correct_10hz=0.7,motion_felt=0.9'.

Results go to DIR/sub-ID/ses-N/beh/ (a BIDS dataset); every trial is on disk the moment it
ends. A run that was killed or aborted resumes with --resume: exactly the remaining trials, in
plan order, on the run's own time base. --resume with no unfinished run for any FILE is an
error (exit 2); a file without one starts a new run. A run open in another process is refused
(exit 2): a run has one writer at a time.

In the scanner (--trigger serial:PATH or emulate:TR, or the protocol's sync: section) each run
waits for the first counted volume, times every onset from it, and logs every volume in
sourcedata/ beside its manifest; --lsl sends one LSL marker per stimulus onset and offset.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    from pinarray.cli import common  # here, not at the top: the cli package imports this module
    p = subparsers.add_parser(
        "batch", help="run sessions without a UI (scripted answers or a simulated observer)",
        epilog=BATCH_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="protocol files, run one after another")
    p.add_argument("--subject", required=True, help="subject label (letters and digits)")
    p.add_argument("--session", default="1", help="session label (default 1)")
    p.add_argument("--experimenter", default="", help="who ran it, for the manifest")
    add_bus_choice(p)
    answers = p.add_mutually_exclusive_group(required=True)
    answers.add_argument("--responses", metavar="CSV", help="answers by trial number")
    answers.add_argument("--observer", metavar="MODEL", help="a simulated subject ('default' or overrides)")
    p.add_argument("--seed", type=common.seed, help="plan seed (default: the protocol's, else a new one)")
    common.add_speed(p, default=None,
                     help="simulator only: X times real time (0 or absent: virtual time)")
    p.add_argument("--results", default=str(DEFAULT_RESULTS_ROOT), metavar="DIR",
                   help="results folder (default results/)")
    p.add_argument("--resume", action="store_true", help="continue the subject's unfinished runs")
    common.add_sync_options(p, key=False)
    p.set_defaults(func=_cmd_batch)


def _cmd_batch(args: argparse.Namespace) -> int:
    import sys

    from pinarray.journal.paths import check_label
    from pinarray.protocol.load import load_protocol, protocol_warnings

    subject = check_label("subject", args.subject)
    session = check_label("session", args.session)
    protocols = [load_protocol(path) for path in args.files]  # every file checked before any runs
    responses = None
    if args.responses:  # every answer checked against every protocol before any run starts
        from pinarray.cli.answer_sheets import load_answers

        responses = load_answers(args.responses, protocols)
    for protocol in protocols:
        for warning in protocol_warnings(protocol):
            print(f"pinarray: warning: {protocol.source}: {warning}", file=sys.stderr)
    syncs = [_scanner_settings(args, protocol) for protocol in protocols]  # all checked first
    resumable = _resumable(protocols, args.results, subject, session) if args.resume else set()
    _refuse_resumed_scans(protocols, syncs, resumable)
    outlet = _marker_outlet(args)
    try:
        for index, protocol in enumerate(protocols):
            try:
                run_batch(protocol, args, subject, session, responses, resume=index in resumable,
                          files_left=args.files[index:], sync=syncs[index], outlet=outlet)
            except NotDelivered as failed:
                print(f"pinarray: {failed}", file=sys.stderr)
                return EXIT_NOT_DELIVERED
    finally:
        if outlet is not None:
            outlet.close()
    return 0


def _scanner_settings(args: argparse.Namespace, protocol):
    """The run's scanner settings (protocol's sync: section, the options on top), checked."""
    from pinarray.cli import common
    from pinarray.protocol.imaging import KeyTrigger, SerialTrigger, SyncError

    sync = common.sync_overrides(args).over(protocol.sync)
    if sync is not None and isinstance(sync.trigger, KeyTrigger):
        raise SyncError(f"{protocol.source}: a key trigger needs the experimenter UI (pinarray "
                        "tui); batch has no keyboard: use serial:PATH or emulate:TR")
    if sync is not None and isinstance(sync.trigger, SerialTrigger) and not _wall_clock(args):
        raise SyncError(f"{protocol.source}: {sync.trigger.describe()}: a scanner's triggers "
                        "arrive in real time: run the simulator with --speed 1")
    return sync


def _wall_clock(args: argparse.Namespace) -> bool:
    """Whether the runs keep wall-clock time: real servos, or the simulator at --speed 1."""
    return bool(args.port) or args.time_scale == 1


def _refuse_resumed_scans(protocols, syncs, resumable: set[int]) -> None:
    from pinarray.protocol.imaging import SyncError

    for index in sorted(resumable):
        if syncs[index] is not None:
            raise SyncError(f"{protocols[index].source}: --resume: a run timed from scanner "
                            "volumes cannot go on in a new scan (its time zero was the old "
                            "scan's first volume); start a new run without --resume")


def _marker_outlet(args: argparse.Namespace):
    """The LSL marker outlet, open for every run of the command, or None without --lsl."""
    if args.lsl is None:
        return None
    from pinarray.clock import MonotonicClock
    from pinarray.errors import PinArrayError

    if not _wall_clock(args):
        raise PinArrayError("--lsl: markers are stamped on this machine's clock, and a "
                            "simulated one is not it: run the simulator with --speed 1")
    from pinarray.imaging.lsl import MarkerOutlet

    outlet = MarkerOutlet(args.lsl, MonotonicClock())
    print(f"pinarray: LSL markers on stream {outlet.name!r} (type Markers, source "
          f"{outlet.source_id})", file=sys.stderr)
    return outlet


def _resumable(protocols, root: str, subject: str, session: str) -> set[int]:
    """Which protocols have an unfinished run to resume; every one checked before any runs.

    Refused (exit 2) when none has one, or when one is open in another process.
    """
    from pinarray.journal.lock import RunLocked, locked_message
    from pinarray.journal.runs import NothingToResume, unfinished_run
    from pinarray.session.trials import task_label

    found = set()
    for index, protocol in enumerate(protocols):
        unfinished = unfinished_run(root, subject, session, task_label(protocol))
        if unfinished is not None and unfinished.holder is not None:
            raise RunLocked(locked_message(unfinished.paths.label, unfinished.holder))
        if unfinished is not None:
            found.add(index)
    if not found:
        tasks = ", ".join(sorted({task_label(p) for p in protocols}))
        raise NothingToResume(f"--resume: no unfinished run of {tasks} for subject {subject}, "
                              f"session {session} in {root}; run without --resume to start a new one")
    return found


# How many times batch presents a trial whose stimulus failed before it gives up.
MAX_ATTEMPTS = 3
EXIT_NOT_DELIVERED = 3


class NotDelivered(Exception):
    """A trial failed `MAX_ATTEMPTS` times; the run is left aborted (resumable)."""


def run_batch(protocol, args, subject: str, session: str, responses: dict[int, str] | None, *,
              resume: bool, files_left: list[str], sync=None, outlet=None) -> None:

    from pinarray.analysis.observer import SimulatedObserver, parse_observer
    from pinarray.errors import PinArrayError
    from pinarray.imaging.run import start_session
    from pinarray.journal.runs import open_run
    from pinarray.journal.volumes import volume_log_path
    from pinarray.plan import make_plan
    from pinarray.player.rig import Rig, choose_clock
    from pinarray.session.trials import Phase, task_label
    from pinarray.stop import Stopped, StopRequest, stop_on_signals

    task = task_label(protocol)
    if responses is not None:
        # Checked before anything is opened, so a short file leaves no half-started run behind.
        count = len(make_plan(protocol, 0))  # every seed numbers the same trials 1..N
        missing = [n for n in range(1, count + 1) if n not in responses]
        if missing:
            raise PinArrayError(
                f"{args.responses}: no response for trial(s) {', '.join(map(str, missing[:10]))}"
                + (" ..." if len(missing) > 10 else "")
            )
    from pinarray.protocol import DIRECTION_OF_WAVE, LocalisationCondition
    from pinarray.protocol.imaging import EmulatedTrigger

    # Triggers and markers are stamped on the wall clock: then the simulator keeps wall-clock
    # time (at --speed 1) instead of a paced one.
    wall_clock = outlet is not None or (sync is not None
                                        and not isinstance(sync.trigger, EmulatedTrigger))
    clock = choose_clock(args.port, args.time_scale, paced=not wall_clock)
    if outlet is not None:
        outlet.use_clock(clock)
    observer = None
    if responses is None:
        observer = SimulatedObserver(parse_observer(args.observer).for_protocol(protocol), seed=args.seed)
    with stop_on_signals(StopRequest()) as stop:
        rig = Rig(protocol, args.port, args.sim, clock, stop)
        scanner = None
        try:
            for warning in rig.warnings:
                print(f"pinarray: warning: {warning}", file=sys.stderr)
            if args.resume and not resume:
                print(f"pinarray: no unfinished {task} run for subject {subject}, session {session}; "
                      "starting a new run", file=sys.stderr)
            if sync is not None:
                scanner = _wait_for_scanner(sync, rig.clock, stop)
            writer, plan = open_run(protocol, args.results, subject, session, task, resume=resume,
                                    seed=args.seed, port_url=rig.url, clock=clock,
                                    experimenter=args.experimenter,
                                    scanner=scanner.record() if scanner else None)
            if writer.stale_lock:
                print(f"pinarray: warning: {writer.stale_lock}", file=sys.stderr)
            if writer.resumed and args.seed is not None and args.seed != plan.seed:
                print(f"pinarray: warning: resuming run {writer.paths.run} with its own seed {plan.seed}; "
                      f"--seed {args.seed} is ignored", file=sys.stderr)
            if writer.repaired:
                print(f"pinarray: warning: dropped a half-written last row from {writer.paths.beh_tsv}: "
                      f"{writer.repaired!r}", file=sys.stderr)
            resume_hint = (f"resume with: pinarray batch {' '.join(files_left)} --subject {subject} "
                           f"--session {session} --resume")
            with writer:
                run = start_session(protocol, plan, writer, rig, rig.clock, scanner=scanner,
                                    outlet=outlet)
                progress = Progress(f"{task} sub-{subject} ses-{session}", run.total, run.done_count)
                try:
                    run.begin()
                    attempts = 0
                    while run.phase is Phase.READY:
                        run.present()
                        if run.phase is Phase.FAULT:
                            attempts += 1
                            print(f"\npinarray: trial {run.current.trial}, attempt {attempts} of "
                                  f"{MAX_ATTEMPTS}: {run.fault}", file=sys.stderr)
                            if attempts >= MAX_ATTEMPTS:
                                run.abort(f"trial {run.current.trial} failed {attempts} times: {run.fault}")
                                raise NotDelivered(f"trial {run.current.trial} failed {attempts} times; "
                                                   f"the run is left resumable ({resume_hint})")
                            run.retry()
                            continue
                        attempts = 0
                        assert run.current is not None  # READY -> RESPONSE keeps the trial
                        condition = run.current.condition
                        answer: str | int | None  # None: nothing felt
                        if responses is not None:
                            answer = responses[run.current.trial]
                        elif isinstance(condition, LocalisationCondition):
                            assert observer is not None
                            answer = observer.respond_localisation(condition.pin, float(condition.frequency_hz))
                        else:
                            assert observer is not None
                            answer = observer.respond_motion(DIRECTION_OF_WAVE[condition.direction])
                        run.respond(answer, response_time_ns=None)  # scripted: no real response time
                        progress.update(run.done_count)
                except (Stopped, KeyboardInterrupt) as stopped:
                    run.abort(str(stopped) or "interrupted (Ctrl-C)")
                    progress.close()
                    print(f"pinarray: run {writer.paths.run} aborted, {resume_hint}", file=sys.stderr)
                    raise
                progress.close()
            print(f"{protocol.name}: {len(run.records)} rows in {writer.paths.beh_tsv} (seed {plan.seed}, run {writer.paths.run})")
            if scanner is not None:
                print(f"scanner: {scanner.summary()}; every volume in "
                      f"{volume_log_path(writer.paths)}")
        finally:
            if scanner is not None:
                scanner.close()
            safe = rig.close()
            if not safe.complete:
                print(f"pinarray: warning: {safe.describe()}", file=sys.stderr)


def _wait_for_scanner(sync, clock, stop):
    """Open the trigger and wait for the run's time zero (nothing is written before it)."""
    from pinarray.imaging.scanner import Scanner

    scanner = Scanner(sync, clock, stop)
    try:
        print(f"pinarray: waiting for the scanner ({sync.describe()}); Ctrl-C gives up",
              file=sys.stderr)
        scanner.wait_for_time_zero()
    except BaseException:
        scanner.close()
        raise
    return scanner


class Progress:
    """A one-line progress bar on a terminal; silent when stderr is not one."""

    def __init__(self, label: str, total: int, done: int, width: int = 30):
        import sys

        self.label, self.total, self.width = label, max(total, 1), width
        self.stream = sys.stderr
        self.live = self.stream.isatty()
        self.update(done)

    def update(self, done: int) -> None:
        if not self.live:
            return
        filled = self.width * done // self.total
        bar = "#" * filled + "-" * (self.width - filled)
        self.stream.write(f"\r{self.label} [{bar}] {done}/{self.total}")
        self.stream.flush()

    def close(self) -> None:
        if self.live:
            self.stream.write("\n")
