"""`pinarray batch`: run whole sessions without a UI, answered from a file or a simulated observer."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from pinarray.cli.bus import add_bus_choice
from pinarray.journal.paths import DEFAULT_RESULTS_ROOT
from pinarray.journal.timebase import Answers

if TYPE_CHECKING:  # the command imports what it runs when it runs
    from pinarray.api.sessions import AnswerSource
    from pinarray.clock import Clock
    from pinarray.protocol import Protocol
    from pinarray.protocol.imaging import ScannerSync
    from pinarray.session.sitting import FailedAttempt, SessionRequest, Sitting
    from pinarray.session.trials import Session

BATCH_EPILOG = """\
Answers come from --responses FILE (CSV with columns trial,response: an answer the protocol's
paradigm takes, e.g. a pin number or 'none' for localisation, none/left/right/unsure for
apparent motion) or from --observer MODEL, a simulated subject: 'default' reproduces the
seed's figures, or override its paradigm's parameters, e.g. 'correct_10hz=0.7' (localisation)
or 'motion_felt=0.9' (apparent motion); for an adaptive design its psychometric function, e.g.
'threshold=120,slope=3'.

Results go to DIR/sub-ID/ses-N/beh/ (a BIDS dataset); every trial is on disk the moment it
ends. A run that was killed or aborted resumes with --resume: exactly the remaining trials, in
plan order, on the run's own time base and seed (a --seed other than its own is refused).
--resume with no unfinished run for any FILE is an error (exit 2); a file without one starts a
new run. A run open in another process is refused (exit 2): a run has one writer at a time.

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
    from pinarray.journal.paths import check_label
    from pinarray.player.rig import choose_clock
    from pinarray.protocol.load import load_protocol, protocol_warnings
    from pinarray.session.sitting import NotDelivered, SessionRequest, Sitting

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
    answers = Answers.OBSERVER if responses is None else Answers.SHEET
    resumable = (_resumable(protocols, args.results, subject, session, args.seed, answers)
                 if args.resume else set())
    _refuse_resumed_scans(protocols, syncs, resumable)
    _check_markers(args)
    # Each run connects on a clock of its own (`_run_clock`); this one is never asked for.
    def any_clock(port: str | None) -> Clock:
        return choose_clock(port, args.time_scale, paced=True, sim_url=args.sim)

    with Sitting(Path(args.results), any_clock, lsl_name=args.lsl) as sitting:
        stream = sitting.markers()  # pylsl checked before any run
        if stream is not None:
            print(f"pinarray: LSL markers on stream {stream.name!r} (type Markers, source "
                  f"{stream.source_id})", file=sys.stderr)
        for index, protocol in enumerate(protocols):
            request = SessionRequest(protocol, subject, session, args.experimenter, args.port,
                                     args.sim, args.seed, resume=index in resumable,
                                     answers=answers)
            resume_hint = _resume_hint(args, args.files[index:], scanned=syncs[index] is not None)
            try:
                run_batch(sitting, request, args, responses, sync=syncs[index],
                          resume_hint=resume_hint)
            except NotDelivered as failed:
                then = (resume_hint if syncs[index] is not None
                        else f"the run is left resumable ({resume_hint})")
                print(f"pinarray: {failed}; {then}", file=sys.stderr)
                return EXIT_NOT_DELIVERED
    return 0


def _resume_hint(args: argparse.Namespace, files: list[str], *, scanned: bool) -> str:
    """What to type once this run stops: the command that resumes it; for a run timed from
    scanner volumes, which cannot be resumed (its time zero was this scan's first volume), the
    command that starts a new run in a new scan."""
    if not scanned:
        return f"resume with: {_batch_command(args, files, resume=True)}"
    return ("a run timed from scanner volumes cannot be resumed (its time zero was this scan's "
            f"first volume); start a new run in a new scan with: "
            f"{_batch_command(args, files, resume=False)}")


def _batch_command(args: argparse.Namespace, files: list[str], *, resume: bool) -> str:
    """The command that runs ``files`` again as this one ran them, to be typed as it is
    printed: the same results folder, servos, answers, pace and scanner options, quoted for the
    shell; with --resume, the runs' remaining trials (a resumed run keeps its seed), else new
    runs (with this command's --seed, if given)."""
    import shlex

    def _seconds(ns: int) -> str:
        return f"{ns / 1e9:g}"

    words = ["pinarray", "batch", *files, "--subject", args.subject, "--session", args.session]
    given = {"--experimenter": args.experimenter, "--port": args.port, "--sim": args.sim,
             "--responses": args.responses, "--observer": args.observer,
             "--speed": None if args.time_scale is None else f"{args.time_scale:g}",
             "--results": args.results, "--lsl": args.lsl,
             "--seed": None if resume or args.seed is None else str(args.seed),
             "--trigger": args.trigger.describe() if args.trigger else None,
             "--dummy-volumes": None if args.dummy_volumes is None else str(args.dummy_volumes),
             "--tr": None if args.tr is None else _seconds(args.tr),
             "--lock-to-volumes": (None if args.lock_to_volumes is None
                                   else str(args.lock_to_volumes)),
             "--trigger-timeout": (None if args.trigger_timeout is None
                                   else _seconds(args.trigger_timeout))}
    for option, value in given.items():
        if value:
            words += [option, value]
    return shlex.join([*words, "--resume"] if resume else words)


def _scanner_settings(args: argparse.Namespace, protocol: Protocol) -> ScannerSync | None:
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


def _refuse_resumed_scans(protocols: list[Protocol], syncs: list[ScannerSync | None],
                          resumable: set[int]) -> None:
    from pinarray.protocol.imaging import SyncError

    for index in sorted(resumable):
        if syncs[index] is not None:
            raise SyncError(f"{protocols[index].source}: --resume: a run timed from scanner "
                            "volumes cannot go on in a new scan (its time zero was the old "
                            "scan's first volume); start a new run without --resume")


def _check_markers(args: argparse.Namespace) -> None:
    """--lsl only where markers can be stamped: on this machine's clock (exit 2 otherwise)."""
    if args.lsl is None:
        return
    from pinarray.errors import PinArrayError

    if not _wall_clock(args):
        raise PinArrayError("--lsl: markers are stamped on this machine's clock, and a "
                            "simulated one is not it: run the simulator with --speed 1")


def _resumable(protocols: list[Protocol], root: str, subject: str, session: str,
               seed: int | None, answers: Answers) -> set[int]:
    """Which protocols have an unfinished run to resume; every one checked before any runs.

    Refused (exit 2) when none has one, when one is open in another process, when ``seed``
    (--seed) is not the seed one was planned with (a resumed run keeps its own), or when one
    was answered by another kind than ``answers`` (a subject's, in the UI, say).
    """
    from pinarray.errors import PinArrayError
    from pinarray.journal.lock import RunLocked, locked_message
    from pinarray.journal.runs import SCANNED, NothingToResume, unfinished_run
    from pinarray.journal.writer import refuse_other_answers
    from pinarray.session.trials import task_label

    found = set()
    for index, protocol in enumerate(protocols):
        unfinished = unfinished_run(root, subject, session, task_label(protocol))
        if unfinished is not None and unfinished.holder is not None:
            raise RunLocked(locked_message(unfinished.paths.label, unfinished.holder))
        if unfinished is not None and seed is not None and seed != unfinished.manifest.seed:
            raise PinArrayError(
                f"--seed {seed} --resume: {unfinished.paths.label} was planned with seed "
                f"{unfinished.manifest.seed}, which it keeps when resumed; leave --seed out "
                "(or start a new run without --resume)")
        if unfinished is not None and unfinished.manifest.scanner is not None:
            raise PinArrayError(f"{protocol.source}: --resume: {unfinished.paths.label} {SCANNED}")
        if unfinished is not None:
            refuse_other_answers(unfinished.paths.label, unfinished.manifest, answers)
            found.add(index)
    if not found:
        tasks = ", ".join(sorted({task_label(p) for p in protocols}))
        raise NothingToResume(f"--resume: no unfinished run of {tasks} for subject {subject}, "
                              f"session {session} in {root}; run without --resume to start a new one")
    return found


EXIT_NOT_DELIVERED = 3  # a trial failed every attempt the sitting allows


def run_batch(sitting: Sitting, request: SessionRequest, args: argparse.Namespace,
              responses: dict[int, str] | None, *, sync: ScannerSync | None,
              resume_hint: str) -> None:
    """One protocol's run on ``sitting``, answered from ``responses`` or ``--observer``; says
    what happens on stderr and where the rows went on stdout. The rig is closed after it."""
    from pinarray.journal.volumes import volume_log_path
    from pinarray.player.simulators import simulation_level
    from pinarray.protocol.response import MeasuredResponse
    from pinarray.stop import Stopped, stop_on_signals

    protocol, subject, session = request.protocol, request.subject, request.session
    answer = _answers(protocol, args, responses)
    with stop_on_signals(sitting.stop):
        try:
            rig = sitting.connect(request, _run_clock(args, sync, sitting.marker_stream is not None))
            for warning in rig.warnings:
                print(f"pinarray: warning: {warning}", file=sys.stderr)
            if isinstance(protocol.device.bandwidth, MeasuredResponse):
                print(f"pinarray: feasibility: {protocol.device.feasibility_basis()}",
                      file=sys.stderr)
            if args.resume and not request.resume:
                print(f"pinarray: no unfinished {request.task} run for subject {subject}, "
                      f"session {session}; starting a new run", file=sys.stderr)
            if sync is not None:
                def waiting(scanner: object) -> None:
                    print(f"pinarray: waiting for the scanner ({sync.describe()}); Ctrl-C gives up",
                          file=sys.stderr)

                if sitting.wait_for_scanner(sync, opened=waiting) is None:
                    sitting.stop.raise_if_requested()
            scanner = sitting.scanner
            run = sitting.open_session()
            _say_how_the_run_opened(run, args)
            writer = run.writer
            progress = Progress(f"{request.task} sub-{subject} ses-{session}", run.total,
                                run.done_count)

            def failed(attempt: FailedAttempt) -> None:
                print(f"\npinarray: {attempt}", file=sys.stderr)

            try:
                sitting.run_scripted(answer, failed=failed,
                                     answered=lambda done: progress.update(done.done_count))
            except (Stopped, KeyboardInterrupt):
                progress.close()
                print(f"pinarray: run {writer.paths.run} aborted, {resume_hint}", file=sys.stderr)
                raise
            progress.close()
            level = simulation_level(sitting.rig.bus) if sitting.rig is not None else None
            simulated = f"; simulated, {level}" if level is not None else ""
            print(f"{protocol.name}: {len(run.records)} rows in {writer.paths.beh_tsv} (seed "
                  f"{run.plan.seed}, run {writer.paths.run}{simulated})")
            if scanner is not None:
                print(f"scanner: {scanner.summary()}; every volume in "
                      f"{volume_log_path(writer.paths)}")
        finally:
            problems = sitting.rig.marker_problems if sitting.rig is not None else []
            if problems:  # a marker that could not go out never fails its trial: said here
                print(f"pinarray: warning: LSL markers of {len(problems)} trial(s) not sent "
                      f"(first: {problems[0]})", file=sys.stderr)
            safe = sitting.release("the run is over")
            if safe is not None and not safe.complete:
                print(f"pinarray: warning: {safe.describe()}", file=sys.stderr)


def _answers(protocol: Protocol, args: argparse.Namespace,
             responses: dict[int, str] | None) -> AnswerSource:
    """Who answers each trial: the --responses file (checked complete) or a simulated subject."""
    from pinarray.api.sessions import simulated_observer
    from pinarray.errors import PinArrayError
    from pinarray.plan import make_plan

    if responses is not None:
        # Checked before anything is opened, so a short file leaves no half-started run behind.
        count = len(make_plan(protocol, 0))  # every seed numbers the same trials 1..N
        missing = [n for n in range(1, count + 1) if n not in responses]
        if missing:
            raise PinArrayError(
                f"{args.responses}: no response for trial(s) {', '.join(map(str, missing[:10]))}"
                + (" ..." if len(missing) > 10 else "")
            )
        return lambda question: responses[question.trial.trial]
    return simulated_observer(protocol, args.observer, seed=args.seed)


def _run_clock(args: argparse.Namespace, sync: ScannerSync | None, markers: bool) -> Clock:
    """The run's clock: virtual or paced for the simulator, unless it must keep the wall's."""
    from pinarray.player.rig import choose_clock
    from pinarray.protocol.imaging import EmulatedTrigger

    # Triggers and markers are stamped on the wall clock: then the simulator keeps wall-clock
    # time (at --speed 1) instead of a paced one.
    wall_clock = markers or (sync is not None and not isinstance(sync.trigger, EmulatedTrigger))
    return choose_clock(args.port, args.time_scale, paced=not wall_clock, sim_url=args.sim)


def _say_how_the_run_opened(run: Session, args: argparse.Namespace) -> None:
    writer = run.writer
    if writer.stale_lock:
        print(f"pinarray: warning: {writer.stale_lock}", file=sys.stderr)
    if writer.resumed and args.seed is not None and args.seed != run.plan.seed:
        print(f"pinarray: warning: resuming run {writer.paths.run} with its own seed {run.plan.seed}; "
              f"--seed {args.seed} is ignored", file=sys.stderr)
    if writer.repaired:
        print(f"pinarray: warning: dropped a half-written last row from {writer.paths.beh_tsv}: "
              f"{writer.repaired!r}", file=sys.stderr)


class Progress:
    """A one-line progress bar on a terminal; silent when stderr is not one."""

    def __init__(self, label: str, total: int, done: int, width: int = 30) -> None:
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
