"""One sitting at the pin array: the rig, the scanner, the run, the retries and the close.

The experimenter's UI and `pinarray batch` both drive a `Sitting`: it connects the rig, waits
for the scanner, opens (or resumes) a run and starts its session, presents trials under one
retry policy for an undelivered stimulus (`MAX_ATTEMPTS`), and makes sure that however the
sitting ends (finished, aborted, stopped by a signal, quit, terminal closed, an error) a
stimulus in progress is cut short, the run's manifest says how it ended, and the pins go to
rest with torque off. No UI code: the surfaces say what happens, in their own words.

It sits above `imaging` (the scanner's volumes and the LSL markers it puts around a session,
`start_session`) and below the composition roots.

Past 400 lines on purpose: every use of the hardware (connecting, the pre-flight's jobs, the
scanner's wait, a presentation, a pause) and every way out share the count of jobs at work and
the stop request that make closing safe; split apart, the modules would share those instead.
"""

from __future__ import annotations

import contextlib
import threading
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, TypeVar

from pinarray.clock import Clock
from pinarray.errors import PinArrayError, ResultsError
from pinarray.hardware.driver import SafeStopReport
from pinarray.journal.manifest import RunStatus
from pinarray.journal.runs import open_run
from pinarray.journal.timebase import Answers
from pinarray.journal.writer import RunWriter
from pinarray.plan import PlannedTrial, TrialPlan
from pinarray.player.rehearsal import MAX_ATTEMPTS  # the retry policy, which validate plays too
from pinarray.player.rig import Rig
from pinarray.player.simulators import SimulatedArrays
from pinarray.player.timing import CheckSkipped, Verdict
from pinarray.protocol import Protocol
from pinarray.protocol.imaging import EmulatedTrigger, ScannerSync
from pinarray.session.trials import Phase, Session, Stimulator, task_label
from pinarray.stop import StoppableClock, Stopped, StopRequest

# The scanner, the LSL markers and the adaptive procedures are imported where a sitting uses
# them: a fixed design's run without them (most batches) does not load them. The servos'
# bring-up is named for its types alone.
if TYPE_CHECKING:
    from pinarray.adaptive.questplus import QuestPlus as QuestPlusMachine
    from pinarray.hardware.feetech.bringup import ReturnDelayChange, ServoFailure
    from pinarray.imaging.lsl import MarkerStream
    from pinarray.imaging.markers import Presenter
    from pinarray.imaging.scanner import Scanner

QUIT_REASON = "quit from the UI"
PAUSE_REASON = "paused by the experimenter"
END_REASON = "the sitting ended"
INTERRUPTED_REASON = "interrupted (Ctrl-C)"
# How long closing waits for a cut-short stimulus to rest its pins, in seconds.
STOP_WAIT_S = 30.0

T = TypeVar("T")


class RigFactory(typing.Protocol):
    """Makes the `Rig` of a connection: `Rig` itself, or a test's that injects faults."""

    def __call__(self, protocol: Protocol, port: str | None, sim_url: str | None, clock: Clock,
                 stop: StopRequest, *, simulators: SimulatedArrays,
                 markers: MarkerStream | None = None) -> Rig: ...


Answer = str | int | None
"""A subject's answer: a pin (its number, or the number as text), ``"none"`` (nothing felt),
a direction's name or ``"unsure"`` (apparent motion); None counts as nothing felt."""


@dataclass(frozen=True)
class Question:
    """What a scripted answer source is asked once a trial's stimulus has played.

    Attributes
    ----------
    trial : PlannedTrial
        The trial of the plan that was presented (its number, block, condition, catch).
    adapted_value : Fraction or None
        An adaptive design's trial: the value of the adapted parameter it presented, in the
        unit the protocol names it in (``soa_ms``: milliseconds); None in a fixed design and
        on a catch trial that plays its own stimulus.
    """

    trial: PlannedTrial
    adapted_value: Fraction | None = None


@dataclass(frozen=True)
class SessionRequest:
    """What the run is: which protocol, for whom, on which bus."""

    protocol: Protocol
    subject: str
    session: str
    experimenter: str
    port: str | None  # a serial device of real servos; None for the simulator
    sim_url: str | None
    seed: int | None
    resume: bool
    # Who or what answers the trials: a run resumes answered as it started (a subject's, in
    # the UI, by default).
    answers: Answers = Answers.SUBJECT

    @property
    def task(self) -> str:
        return task_label(self.protocol)


@dataclass(frozen=True)
class FailedAttempt:
    """A presentation whose stimulus failed (logged invalid): which one of the trial's tries."""

    planned: PlannedTrial
    attempt: int  # 1..MAX_ATTEMPTS, counted while the same trial keeps failing
    fault: str

    @property
    def last(self) -> bool:
        """No attempt is left: the sitting has aborted the run with `reason`."""
        return self.attempt >= MAX_ATTEMPTS

    @property
    def reason(self) -> str:
        """Why the run stopped after the last attempt, naming the trial (plan number)."""
        return f"trial {self.planned.trial} failed {self.attempt} times: {self.fault}"

    def __str__(self) -> str:
        return (f"trial {self.planned.trial}, attempt {self.attempt} of {MAX_ATTEMPTS}: "
                f"{self.fault}")


class NotDelivered(PinArrayError):
    """A trial failed `MAX_ATTEMPTS` times; the run is left aborted (resumable)."""

    def __init__(self, failed: FailedAttempt):
        super().__init__(f"trial {failed.planned.trial} failed {failed.attempt} times")
        self.failed = failed


class Sitting:
    """Owns the connected rig, the scanner and the open session of one sitting.

    Parameters
    ----------
    results_root : Path
        Where runs are written (BIDS layout below it).
    clock_factory : callable
        ``clock_factory(port)`` gives the clock of a new connection (virtual in tests) when
        `connect` is not given one.
    rig_factory : RigFactory
        ``rig_factory(protocol, port, sim_url, clock, stop, simulators=..., markers=...)``;
        `Rig` unless a test injects faults.
    lsl_name : str or None
        Send LSL markers on a stream of this name (each connection's rig opens it where its
        trials play, and the player sends each marker as the trial plays); None: no markers.
    """

    def __init__(self, results_root: Path, clock_factory: Callable[[str | None], Clock],
                 rig_factory: RigFactory = Rig, lsl_name: str | None = None):
        self.results_root = Path(results_root)
        self.clock_factory = clock_factory
        self.rig_factory = rig_factory
        # Simulated servos outlive a connection, as real ones do: Connect again, or the next
        # run, finds them as the last connection left them.
        self.simulators = SimulatedArrays()
        self.request: SessionRequest | None = None
        self.rig: Rig | None = None
        self.clock: StoppableClock | None = None
        self.stop = StopRequest()
        self.session: Session | None = None
        # Every run opened in this sitting and what asked for it, for the line said on exit.
        self.runs: list[tuple[SessionRequest, Session]] = []
        self.last_safe: SafeStopReport | None = None  # how the last release left the pins
        self.failed: FailedAttempt | None = None  # the current trial's last failed attempt
        self.lsl_name = lsl_name
        self.marker_stream: MarkerStream | None = None
        self.scanner: Scanner | None = None
        # What the last timing check on this connection said, for the run's manifest, and
        # the last verdict one gave (a check skipped gives none).
        self.timing_check = ""
        self._verdict = ""
        self._jobs = 0  # hardware jobs running in workers (a stimulus, a test pin, a timing check)
        self._jobs_done = threading.Condition()
        # Set while the rig is being closed: a pause must not clear the stop a close relies on.
        self._closing = False
        # Held by the `finish` or `release` at work: a second one (another thread's) waits for
        # it, since whoever calls it may end the process as soon as it returns.
        self._ending = threading.RLock()

    def __enter__(self) -> Sitting:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        """However the block ends, an unfinished run is marked and the pins go to rest."""
        if kind is None:
            self.finish(END_REASON)
            return
        # The pins rest whatever happens; if the run cannot be marked either (the disk that
        # failed the block), the block's own error is the one to report.
        with contextlib.suppress(ResultsError):
            if isinstance(error, Stopped | KeyboardInterrupt):
                self.finish(str(error) or INTERRUPTED_REASON)
            else:
                self.finish(f"crashed: {kind.__name__}: {error}", RunStatus.CRASHED)

    # -- hardware ---------------------------------------------------------------------------

    def markers(self) -> MarkerStream | None:
        """The LSL marker stream, pylsl checked now, if the sitting sends markers; None if it
        does not. Each connection's rig opens it where its trials play."""
        if self.lsl_name is not None and self.marker_stream is None:
            from pinarray.imaging.lsl import MarkerStream

            stream = MarkerStream(self.lsl_name)
            stream.check()
            self.marker_stream = stream
        return self.marker_stream

    def connect(self, request: SessionRequest, clock: Clock | None = None) -> Rig:
        """Open the bus and run the handshake (blocking: call it from a worker).

        ``clock``: the connection's clock; None: ``clock_factory(request.port)``. A stop a
        signal asked for stays requested: the sitting is over, not connecting again.
        """
        self.release("connecting again")
        self.request = request
        self.timing_check = self._verdict = ""
        with self._jobs_done:
            self._closing = False
            if self.stop.signal_number is None:
                self.stop.clear()
        base = clock if clock is not None else self.clock_factory(request.port)
        markers = self._marker_stream(base)
        # Counted as hardware at work, so that a sitting closed meanwhile waits for it...
        rig = self._working(lambda: self.rig_factory(request.protocol, request.port,
                                                     request.sim_url, base, self.stop,
                                                     simulators=self.simulators,
                                                     markers=markers))
        with self._jobs_done:
            closed = self._closing
            if not closed:
                # The player and the session wait on the rig's stoppable clock; the bus on the
                # plain one.
                self.clock = rig.clock
                self.rig = rig
        if closed:
            rig.close()  # ...and then finds it here: pins to rest, torque off, port closed
            raise Stopped(self.stop.reason or END_REASON, self.stop.signal_number)
        return rig

    def _marker_stream(self, clock: Clock) -> MarkerStream | None:
        """The marker stream for a connection on ``clock``, if the sitting sends markers."""
        if self.lsl_name is None:
            return None
        from pinarray.imaging.lsl import LslError
        from pinarray.imaging.triggers import follows_wall_clock

        if not follows_wall_clock(clock):
            raise LslError("LSL markers are stamped on this machine's clock, and a simulated "
                           "one is not it: start the UI with --speed 1")
        return self.markers()

    def connected(self) -> Rig:
        """The connected rig; raises `PinArrayError` if there is none (never connected, or
        released meanwhile: a worker may start as the experimenter leaves the pre-flight).
        Not an ``assert``: under ``python -O`` (PYTHONOPTIMIZE) that would vanish and the
        caller would fail on None instead."""
        rig = self.rig
        if rig is None:
            raise PinArrayError("not connected")
        return rig

    def test_pin(self, pin: int) -> None:
        """Wiggle one pin (blocking: call it from a worker)."""
        rig, request = self.connected(), self.request
        assert request is not None
        request.protocol.device.grid.check_pin(pin)
        self._busy(lambda: rig.test_pin(pin))

    def check_timing(self, duration_ns: int | None,
                     progress: Callable[[int, int], bool] = lambda done_ns, total_ns: True
                     ) -> Verdict | CheckSkipped | None:
        """This machine's timing verdict (blocking: call it from a worker), None if stopped;
        see `Rig.check_timing`. What it said goes into the next run's manifest."""
        rig = self.connected()
        outcome = self._busy(lambda: rig.check_timing(duration_ns, progress=progress))
        match outcome:
            case Verdict(judgement=judgement, lines=lines):
                said = [line for line in lines if line.startswith(f"{judgement.value}:")]
                self._verdict = said[0] if said else judgement.value
                self.timing_check = self._verdict
            case CheckSkipped():
                # A re-check skipped (after Lower return delay): the verdict before it stands.
                before = f"; the verdict before it: {self._verdict}" if self._verdict else ""
                self.timing_check = f"timing check {outcome.describe()}{before}"
        return outcome

    def lower_return_delay(self, delay_us: int = 0
                           ) -> tuple[tuple[ReturnDelayChange, ...], tuple[ServoFailure, ...]] | None:
        """Every servo's return delay to ``delay_us``, until power-off (blocking: from a worker).

        Returns ``(changes, failures)`` as `pinarray.hardware.feetech.bringup.set_return_delay` does, or
        None if stopped. A rig with a player process is connected again: the player plans
        its read-backs with the delays the handshake reads, and the servos keep the new ones.
        """
        from pinarray.hardware.feetech.bringup import set_return_delay
        from pinarray.hardware.feetech.feetech import FeetechBus

        rig, request = self.connected(), self.request
        assert request is not None
        bus = rig.bus
        if not isinstance(bus, FeetechBus):
            raise PinArrayError(f"{rig.url}: only Feetech bus servos have a return delay")
        result = self._busy(
            lambda: set_return_delay(bus, rig.setup.servo_ids, delay_us, save=False))
        if result is not None and rig.isolated:
            self.connect(request)
        return result

    def release(self, reason: str = "left the pre-flight") -> SafeStopReport | None:
        """Stop what the hardware is doing, then pins to rest, torque off, port closed.

        Returns the `SafeStopReport`, or None if nothing was connected. Safe from any thread:
        one called while another thread's is at work returns once that one has rested the
        pins (or `STOP_WAIT_S` on, if it never does).
        """
        with self._one_ending():
            self._stop_jobs(reason)
            rig, self.rig = self.rig, None
            try:
                self.close_scanner()
            finally:
                if rig is not None:
                    self.last_safe = rig.close()  # pins first, whatever the scanner's close did
            return None if rig is None else self.last_safe

    @contextlib.contextmanager
    def _one_ending(self) -> Iterator[None]:
        """One `finish` or `release` at a time; a second waits for the first, a bounded time."""
        held = self._ending.acquire(timeout=STOP_WAIT_S)
        try:
            yield
        finally:
            if held:
                self._ending.release()

    # -- the scanner ------------------------------------------------------------------------

    def wait_for_scanner(self, sync: ScannerSync,
                         opened: Callable[[Scanner], object] | None = None) -> Scanner | None:
        """Open the trigger and wait for the first counted volume (blocking: from a worker).

        ``opened`` is called once the trigger is open, before the wait. Returns the scanner,
        or None when the wait was stopped (`abort_wait`, quitting, a signal); raises
        `pinarray.imaging.triggers.TriggerError` for a device that cannot be opened or a
        scanner that sends nothing in time. No run is opened either way.
        """
        rig, clock = self.connected(), self.clock
        assert clock is not None  # set with the rig
        if not isinstance(sync.trigger, EmulatedTrigger):
            rig.keep_wall_time()  # the scanner's triggers are stamped on the wall clock
        from pinarray.imaging.scanner import Scanner

        self.scanner = Scanner(sync, clock, self.stop)
        try:
            if opened is not None:
                opened(self.scanner)
            zero_ns = self._busy(self.scanner.wait_for_time_zero)
        except BaseException:
            self.close_scanner()
            raise
        if zero_ns is None:
            self.close_scanner()
            return None
        return self.scanner

    def abort_wait(self) -> None:
        """Stop waiting for the scanner; the rig stays connected."""
        reason = "stopped waiting for the scanner"
        self.stop.request(reason)
        self._wait_for_jobs()
        with self._jobs_done:
            # A stop a close or a signal asked for meanwhile stays.
            if not self._closing and self.stop.reason == reason:
                self.stop.clear()

    def close_scanner(self) -> None:
        scanner, self.scanner = self.scanner, None
        if scanner is not None:
            scanner.close()

    # -- the run ----------------------------------------------------------------------------

    def open_session(self, on_change: Callable[[Session], None] | None = None) -> Session:
        """Start (or resume) the request's run on the connected rig.

        A run open in another process is refused (`pinarray.journal.lock.RunLocked`), as is a
        resume with nothing to resume; the run's lock is held until the session ends. After
        `wait_for_scanner` the run is timed from the scanner's first counted volume.
        """
        request = self.request
        assert request is not None and self.rig is not None and self.clock is not None
        scanner = self.scanner
        adaptive = request.protocol.design.adaptive
        # What can fail without the run is done before it is opened: a failure leaves no new
        # run, participant row or lock behind.
        prepared = None
        if adaptive is not None:
            from pinarray.procedures import prepare_quest_plus

            prepared = prepare_quest_plus(adaptive)
        writer, plan = open_run(
            request.protocol, self.results_root, request.subject, request.session, request.task,
            resume=request.resume, seed=request.seed, port_url=self.rig.url,
            clock=self.rig.bus_clock, experimenter=request.experimenter,
            scanner=None if scanner is None else scanner.record(), answers=request.answers,
        )
        with contextlib.ExitStack() as opened:
            # A session that cannot start on it (its rows refused) marks the run and gives up
            # its lock: the next try, or another process, finds it free.
            opened.enter_context(writer)
            if self.timing_check:
                writer.note_timing_check(self.timing_check)
            self.session = start_session(request.protocol, plan, writer, self.rig, self.clock,
                                         scanner=scanner, marked=self.marker_stream is not None,
                                         on_change=on_change, prepared=prepared)
            opened.pop_all()
        self.failed = None
        self.runs.append((request, self.session))
        return self.session

    def present(self) -> FailedAttempt | None:
        """Present the current trial (blocking: call it from a worker).

        Returns the failed attempt if the stimulus failed (logged invalid; `Session.retry`
        presents it again), None otherwise. The `MAX_ATTEMPTS`-th failure of the same trial
        aborts the run, naming the trial. A stop cuts the presentation short and returns None:
        `finish` aborts the run (a pause holds it instead).
        """
        try:
            return self._present()
        except Stopped:
            return None

    def _present(self) -> FailedAttempt | None:
        session = self.session
        assert session is not None
        self._working(session.present)
        if session.phase is Phase.RESPONSE:
            self.failed = None  # delivered: a later failure of the trial starts counting again
        if session.phase is not Phase.FAULT or session.current is None:
            return None
        before = self.failed
        attempt = before.attempt + 1 if before is not None and before.planned == session.current else 1
        self.failed = FailedAttempt(session.current, attempt, session.fault)
        if self.failed.last:
            session.abort(self.failed.reason)
        return self.failed

    def run_scripted(self, answer: Callable[[Question], Answer], *,
                     failed: Callable[[FailedAttempt], object] = lambda attempt: None,
                     answered: Callable[[Session], object] = lambda session: None) -> Session:
        """Every remaining trial of the open run, answered by ``answer`` (no response times).

        A failed stimulus is presented again at once (``failed`` hears of each attempt) until
        the policy gives up: then `NotDelivered`. A stop (a signal, Ctrl-C) aborts the run
        with its reason and is raised again; any other error marks the run crashed.
        """
        session = self.session
        assert session is not None
        with session.writer:  # an error nothing here expects marks the run crashed
            try:
                session.begin()
                while session.phase is Phase.READY:
                    attempt = self._present()
                    if attempt is not None:
                        failed(attempt)
                        if attempt.last:
                            raise NotDelivered(attempt)
                        session.retry()
                        continue
                    assert session.current is not None  # READY -> RESPONSE keeps the trial
                    presented = session.presented
                    question = Question(session.current,
                                        None if presented is None else presented.value)
                    session.respond(answer(question), response_time_ns=None)
                    answered(session)
            except (Stopped, KeyboardInterrupt) as stopped:
                session.abort(str(stopped) or INTERRUPTED_REASON)
                raise
        return session

    def cut_short(self, reason: str = PAUSE_REASON) -> None:
        """Stop what the hardware is doing (pins to rest), then let it be used again.

        For a pause (blocking: call it from a worker): the stimulus in progress ends at the
        player's next look at the stop request, and the session logs it as cut short. A stop
        that a close asked for meanwhile stays.
        """
        self.stop.request(reason)
        self._wait_for_jobs()
        with self._jobs_done:
            if not self._closing and self.stop.reason == reason:
                self.stop.clear()

    def _busy(self, job: Callable[[], T]) -> T | None:
        try:
            return self._working(job)
        except Stopped:
            return None  # cut short: `finish` aborts the run, logging a trial that was playing

    def _working(self, job: Callable[[], T]) -> T:
        """``job()``, counted as hardware at work until it returns (closing waits for it)."""
        with self._jobs_done:
            self._jobs += 1
        try:
            return job()
        finally:
            with self._jobs_done:
                self._jobs -= 1
                self._jobs_done.notify_all()

    def _stop_jobs(self, reason: str) -> None:
        """Closing: the job at work is asked to stop and waited for (a connection that ends
        meanwhile closes the rig it made)."""
        with self._jobs_done:
            self._closing = True
        self.stop.request(reason)
        self._wait_for_jobs()

    def _wait_for_jobs(self) -> None:
        with self._jobs_done:
            self._jobs_done.wait_for(lambda: self._jobs == 0, STOP_WAIT_S)

    def finish(self, reason: str = QUIT_REASON,
               status: RunStatus = RunStatus.ABORTED) -> SafeStopReport | None:
        """End the sitting: cut a stimulus short, mark an unfinished run ``status`` (aborted,
        or crashed), pins to rest (the rig takes its LSL stream with it).

        Safe to call more than once and from any thread; one called while another is at work
        returns once that one has ended (see `release`). Returns the `SafeStopReport` (None
        if nothing was connected). The pins go to rest even if marking the run fails.
        """
        with self._one_ending():
            self._stop_jobs(reason)
            session, self.session = self.session, None
            try:
                # A run whose writer already said how it ended (a crash in `run_scripted`)
                # stays so.
                if (session is not None and session.phase not in (Phase.DONE, Phase.ABORTED)
                        and session.writer.manifest.status is RunStatus.RUNNING):
                    session.abort(reason, status)
            finally:
                safe = self.release(reason)
            return safe


def start_session(protocol: Protocol, plan: TrialPlan, writer: RunWriter, stimulator: Presenter,
                  clock: Clock, *, scanner: Scanner | None = None, marked: bool = False,
                  on_change: Callable[[Session], None] | None = None,
                  prepared: Mapping[str, QuestPlusMachine] | None = None) -> Session:
    """A `Session` on ``writer``'s run, timed from ``scanner`` if given, its stimuli marked.

    With a scanner, the session's time zero is the first counted volume (the scanner has
    waited for it already), trials may be held for their volumes, and the run's volume log is
    written with its rows. ``marked``: every presentation hands ``stimulator`` (a rig opened
    with a marker stream) its onset and offset markers, which its player sends.

    ``writer`` must have been started with ``scanner.record()`` when there is a scanner, and
    ``scanner`` must be past `Scanner.wait_for_time_zero`.
    """
    session: Session | None = None
    presenter: Stimulator = stimulator
    if marked:
        from pinarray.imaging.markers import MarkedStimulator

        presenter = MarkedStimulator(stimulator, protocol, writer.paths.task,
                                     lambda: session.current if session else None)
    if scanner is None:
        session = Session(protocol, plan, writer, presenter, clock, on_change, prepared=prepared)
        return session
    zero_ns = scanner.timeline.zero_ns
    assert zero_ns is not None, "wait for the scanner's time zero first"
    writer.log_volumes(scanner.pending_rows)
    session = Session(protocol, plan, writer, presenter, clock, on_change,
                      time_zero_ns=zero_ns, time_zero_event=scanner.zero_event,
                      gate=scanner.gate, prepared=prepared)
    return session
