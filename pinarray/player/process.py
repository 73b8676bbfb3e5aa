"""The deadline loop in a process of its own, at real-time priority when the OS grants it.

On real servos the player shares nothing with the UI: not the interpreter lock, not Textual's
redraws, not the garbage collector. The parent (``play``, ``batch`` or the TUI) keeps the
serial port for the handshake, telemetry and the safe stop; for each trial it sends the
prepared packets through a socket, the child plays them on the same port (its descriptor is
inherited) and sends the `PlaybackReport` back.

Every way out stays safe:

- the parent is asked to stop (a signal, quitting the UI): it tells the child, which ends the
  trial at its next wake-up and puts the pins at rest before answering;
- the child dies (killed, crashed): the parent sees the socket close at once, puts the pins at
  rest through its own descriptor and reports the trial as not delivered;
- the parent dies: the child sees it end (it watches the parent process itself, not only the
  socket, which a forked copy of the parent may still hold), rests the pins and releases
  torque itself;
- the child is sent a signal: it rests the pins, releases torque and exits;
- the child is stopped (SIGSTOP) while it works on a request, or part way through a message
  either way: the parent kills it within a few looks and rests the pins through its own
  descriptor (this end's writes do not block, and a read whose message stops coming looks
  why); one that stops answering unseen (hung) is given until the trial's scheduled end and a
  margin (`ANSWER_MARGIN_NS`), or `STOP_BUDGET_NS` once told to stop, then the same;
- the parent's caller is interrupted mid-request (a Ctrl-C the script catches): the request
  is sent its stop and its answer taken before the next one (`settle`), so that no answer is
  taken for another's; a message cut part way kills the child (the stream is of no more use);
- a write to a side that has gone is an error where it is, never SIGPIPE as well (the child
  ignores it; the parent's writes take it), which a script may have set to end the process;
- the parent is suspended (Ctrl-Z) while a stimulus plays or waits for its onset: the child
  cuts it, rests the pins and releases torque (`Suspended`); between stimuli the pins hold at
  rest, as they do while a script waits for anything else;
- the parent forks (a lab's ``multiprocessing`` workers): the copy lets go of the channel at
  once (`pinarray.player.forks`), so that only the parent's own end keeps the player going.

The channel is a socket pair whose blocking mode is set here, whatever defaults the host
program set for new sockets (PsychoPy sets a 20 s timeout on import, which makes every new
socket non-blocking underneath). A stop request wakes the parent's wait at once (its
`StopRequest` callback), so the child hears of it within a fraction of a millisecond.

The child runs in its own session, so a Ctrl-C or a hang-up meant for the terminal reaches the
parent only, which decides.
"""

from __future__ import annotations

import errno
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import weakref
from collections.abc import Callable
from contextlib import ExitStack
from fractions import Fraction
from typing import NoReturn

from pinarray.clock import MonotonicClock
from pinarray.errors import Interrupted, PinArrayError
from pinarray.hardware.driver import ArrayDriver, SafeStopReport
from pinarray.hardware.motion import DEFAULT_STROKE_TOLERANCE
from pinarray.player.channel import Channel, readable
from pinarray.player.child import REALTIME_PRIORITY, process_state
from pinarray.player.forks import FORKED_COPY, blank_descriptors, let_go_in_forks
from pinarray.player.markers import Announcers, TrialMarkers
from pinarray.player.messages import (
    ANSWERS,
    Answer,
    Cue,
    Hello,
    MeasureWakeUps,
    OnCue,
    OnsetMissed,
    Play,
    Played,
    PlayFailed,
    PlayStopped,
    PlaySuspended,
    Quit,
    Ready,
    Request,
    StopPlaying,
    WakeUpsMeasured,
)
from pinarray.player.playback import (
    SETTLE_NS,
    SOON,
    Onset,
    OnsetAfter,
    OnsetAt,
    OnsetPassed,
    PlaybackAborted,
    PlaybackReport,
    PreparedTrial,
    Suspended,
)
from pinarray.stop import STOP_SIGNALS, Stopped, StopRequest, signal_name

# Spin (rather than sleep) this close to a deadline, in ns; chosen by `make bench`.
SPIN_NS = 200_000
# How often the parent looks at the stop request and the child while a trial plays, in s.
WATCH_S = 0.02
START_TIMEOUT_NS = 30_000_000_000
# Once told to stop, the player process has this long to rest the pins and answer; then it is
# killed and the parent rests them itself (a stop takes torque off within half a second).
STOP_BUDGET_NS = 300_000_000
# A trial's answer is due this long after its scheduled end at the latest (the read-backs'
# settling, telemetry, a player's own safe stop): a player silent past it is taken for hung.
ANSWER_MARGIN_NS = SETTLE_NS + 1_000_000_000
# How long a player process whose socket closed may take to finish exiting, in s.
EXIT_WAIT_S = 1.0
# A cue given before its trial reached the child: the child starts it as soon as it can.
SOON_AS_ASKED = OnsetAfter(0)


class PlayerDied(PlaybackAborted):
    """The player process ended in the middle of its work; the parent made the pins safe.

    ``noticed_ns`` is when the parent saw it gone (``time.monotonic_ns()``), before the safe stop.
    """

    def __init__(self, message: str, safe_stop: SafeStopReport, noticed_ns: int):
        super().__init__(message, safe_stop)
        self.noticed_ns = noticed_ns


class StartCue:
    """The moment a stimulus armed without an onset starts (a screen flip as it happens),
    given from any thread; whoever plays it is told at once, or finds it given already.

    `give` starts it; `withdraw` (a stop, a cancel) keeps a cue not given yet from starting it.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._given = threading.Event()
        self._withdrawn = False
        self._tell: Callable[[], None] | None = None
        self.given_ns: int | None = None  # when it was given (``time.monotonic_ns()``)

    def give(self) -> bool:
        """Start it now; False when withdrawn or given already."""
        with self._lock:
            if self._withdrawn or self._given.is_set():
                return False
            self.given_ns = time.monotonic_ns()
            self._given.set()
            tell = self._tell
        if tell is not None:
            tell()
        return True

    def withdraw(self) -> None:
        with self._lock:
            self._withdrawn = not self._given.is_set()
            self._given.set()  # whoever waits wakes, and finds it withdrawn

    @property
    def given(self) -> bool:
        return self._given.is_set() and not self._withdrawn

    @property
    def withdrawn(self) -> bool:
        return self._withdrawn

    def wait(self, timeout_s: float | None) -> bool:
        """Whether it was given (or withdrawn) within ``timeout_s``."""
        return self._given.wait(timeout_s)

    def when_given(self, tell: Callable[[], None]) -> bool:
        """Call ``tell`` when given; True (and no call) if it is given already."""
        with self._lock:
            if self._given.is_set():
                return True
            self._tell = tell
            return False



# The player process multiplies no matrices: no BLAS thread pool beside its real-time thread.
# OpenBLAS (numpy's wheels) starts one thread per core as numpy loads, a quarter of numpy's
# start-up here (136 -> 103 ms of processor, median of 25), threads the scheduler would then
# keep beside the player's own; MKL and OpenMP builds read the other two.
PLAYER_ENV = {"OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


class _ChildFrozen(OSError):
    """The child took nothing of a message and is stopped (SIGSTOP): it never will."""


def ended_how(status: int) -> str:
    """How a child process ended, from its exit status as `subprocess` reads it."""
    if status == 0 and signal.getsignal(signal.SIGCHLD) == signal.SIG_IGN:
        # The system reaps the children of a process that ignores SIGCHLD (as some process
        # supervisors start a lab's script) and keeps no exit status: subprocess reads 0.
        return "its exit status unknown: SIGCHLD is ignored in this process"
    return f"killed by signal {-status}" if status < 0 else f"exit status {status}"


class PlayerProcess:
    """A player process driving the servos of ``bus`` through the port descriptor ``fd``.

    Parameters
    ----------
    bus : ArrayDriver or None
        The parent's connected array (its port descriptor is shared); None for a process
        that only measures this machine's timing.
    fd : int or None
        The port's file descriptor.
    stop : StopRequest
        Looked at while a trial plays; a request is passed on to the child.
    realtime : bool
        Ask the OS for SCHED_FIFO priority in the child.
    markers : Announcers, optional
        A marker stream the child opens once (a `PinArrayError` here if it cannot) and
        announces each trial's markers on, from the child itself.
    keep_fds : tuple of int
        Descriptors the child inherits and keeps until it ends (the port's lock: the port
        stays held while the child may still drive it).
    """

    def __init__(self, bus: ArrayDriver | None, fd: int | None, stop: StopRequest,
                 realtime: bool = True, spin_ns: int = SPIN_NS,
                 markers: Announcers | None = None, keep_fds: tuple[int, ...] = ()):
        self.bus = bus
        self.fd = fd
        self.stop = stop
        self.realtime_problem = ""
        self._clock = MonotonicClock()
        self._requests = 0
        self._working = 0  # number of the request the child is working on, 0 when idle
        self._stop_sent = False
        self._closing = False
        # One request at a time: the UI may ask for a test pin while a timing check runs.
        self._one_at_a_time = threading.Lock()
        self._sending = threading.Lock()  # a cue is sent from another thread than the trial's
        self._forked_away = False  # True in a forked copy of the process that started it
        self._stopped_before = False  # the child was stopped at the last look (`_stopped_twice`)
        self._owed = 0  # the request whose answer is still to be taken (0: none)
        self._killed = False  # sent SIGKILL: ended, however long until it is reaped
        self._death_handled = False  # `_died` has made the pins safe for the child's end
        # Each descriptor made is closed again when a later one cannot be made (EMFILE: a
        # script near its limit of open files) or the child cannot be started.
        with ExitStack() as undo:
            self._errors = tempfile.TemporaryFile()
            undo.callback(self._errors.close)
            parent_end, child_end = socket.socketpair()
            undo.callback(parent_end.close)
            undo.callback(child_end.close)  # the child's copy: ours closed however this ends
            for end in (parent_end, child_end):
                end.setblocking(True)  # whatever the host's default timeout: see the docstring
            # A stop request wakes the wait for the child's answer (a byte down this pipe).
            self._wake_read, self._wake_write = os.pipe()
            undo.callback(os.close, self._wake_read)
            undo.callback(os.close, self._wake_write)
            os.set_blocking(self._wake_write, False)
            passed = (child_end.fileno(),) + ((fd,) if fd is not None else ()) + keep_fds
            command = [sys.executable, "-m", "pinarray.player.child", str(child_end.fileno()),
                       str(fd if fd is not None else -1), str(os.getpid())]
            self.process = subprocess.Popen(
                command, pass_fds=passed, start_new_session=True, stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL, stderr=self._errors,
                env={**os.environ, **PLAYER_ENV},
            )
            self.conn = Channel(parent_end.detach())
            undo.pop_all()
        child_end.close()
        wake = weakref.WeakMethod(self._wake)  # the request outlives this player: keep it light
        stop.when_requested(lambda: (method := wake()) is not None and method())
        # This end's writes do not block: a request bigger than the socket's buffer, sent to a
        # frozen child, would otherwise wait on it for ever (and a stop with it).
        os.set_blocking(self.conn.fileno(), False)
        let_go_in_forks(self)
        try:
            ready = self._hello(bus, realtime, spin_ns, markers)
        except BaseException:
            self.close()  # the child ended, its descriptors closed: none left to the script
            raise
        self.realtime_problem = ready.realtime_problem
        if ready.markers_problem:
            self.close()  # torque is not on yet: nothing moves
            raise PinArrayError(ready.markers_problem)

    def _hello(self, bus: ArrayDriver | None, realtime: bool, spin_ns: int,
               markers: Announcers | None) -> Ready:
        handover = bus.handover() if bus is not None else None
        try:
            self._send(Hello(handover, REALTIME_PRIORITY if realtime else None, spin_ns,
                             markers))
        except _ChildFrozen as frozen:
            self._died("starting", hung=str(frozen))
        except OSError:
            self._died("starting")
        ready_due_ns = self._clock.now_ns() + START_TIMEOUT_NS
        ready = self._answer("starting", lambda: ready_due_ns)
        if not isinstance(ready, Ready):
            raise PlayerDied(f"the player process answered {ready!r} when starting",
                             SafeStopReport((), (), ()), time.monotonic_ns())
        return ready

    @property
    def alive(self) -> bool:
        # Killed is ended, reaped or not (a debugger holding it keeps it unreaped until it lets go).
        return not self._killed and self.process.poll() is None

    def _kill(self) -> None:
        self.process.kill()
        self._killed = True

    def play(self, trial: PreparedTrial, *, onset: Onset | StartCue = SOON,
             tolerance_ns: int, markers: TrialMarkers | None = None,
             stroke_tolerance: Fraction = DEFAULT_STROKE_TOLERANCE) -> PlaybackReport:
        """Play one trial in the child, announcing ``markers`` there if its stream is open;
        raises `Stopped`, `OnsetPassed`, `PlaybackAborted` or `PlayerDied`.

        ``onset`` a `StartCue`: the child holds the trial ready and starts it the moment the
        cue is given (at once if it was given before the trial reached the child).
        """

        def request(number: int) -> Play:
            if not isinstance(onset, StartCue):
                return Play(number, trial, onset, tolerance_ns, markers, stroke_tolerance)
            if onset.when_given(lambda: self._send(Cue(number), quietly=True)):
                return Play(number, trial, SOON_AS_ASKED, tolerance_ns, markers,
                            stroke_tolerance)
            return Play(number, trial, OnCue(), tolerance_ns, markers, stroke_tolerance)

        asked_ns = self._clock.now_ns()

        def due_ns() -> int | None:
            """When the answer is due at the latest (None: a cue not given yet)."""
            match onset:
                case OnsetAt(onset_ns=zero_ns):
                    pass
                case StartCue(given_ns=given_ns):
                    if given_ns is None:
                        return None
                    zero_ns = given_ns
                case _:
                    zero_ns = asked_ns + onset.lead_ns
            return max(zero_ns, asked_ns) + trial.end_ns + ANSWER_MARGIN_NS

        answer = self._ask(request, "playing a trial", due_ns)
        match answer:
            case Played(report=report):
                if self.bus is not None:
                    # The player left every pin at rest (it forces rest when a change of the
                    # trial's end was not confirmed); the next changed-only write starts there.
                    self.bus.assume_goals({s.servo_id: s.rest_steps for s in self.bus.setup.servos})
                return report
            case PlayFailed(message=message, safe_stop=safe):
                raise PlaybackAborted(message, safe)
            case OnsetMissed(message=message, late_ns=late_ns):
                raise OnsetPassed(message, late_ns)
            case PlaySuspended(message=message, safe_stop=safe, noticed_ns=noticed_ns):
                raise Suspended(message, safe, noticed_ns)
        raise PlayerDied(f"the player process answered {answer!r} to a trial",
                         SafeStopReport((), (), ()), time.monotonic_ns())

    def measure_wake_ups(self, duration_ns: int, period_ns: int) -> tuple[int, ...]:
        """How late the child wakes for deadlines every ``period_ns``, for ``duration_ns``."""
        due_ns = self._clock.now_ns() + period_ns + duration_ns + ANSWER_MARGIN_NS
        answer = self._ask(lambda number: MeasureWakeUps(number, duration_ns, period_ns),
                           "measuring wake-ups", lambda: due_ns)
        if not isinstance(answer, WakeUpsMeasured):
            raise PlayerDied(f"the player process answered {answer!r} to a measurement",
                             SafeStopReport((), (), ()), time.monotonic_ns())
        return answer.lateness_ns

    def _ask(self, request: Callable[[int], Request], doing: str,
             due_ns: Callable[[], int | None]) -> Answer:
        """Send a numbered request and wait for its answer, due by ``due_ns()`` at the latest
        (None: not yet known); a stop ends it with `Stopped`."""
        if self._forked_away:
            raise PinArrayError(FORKED_COPY)
        with self._one_at_a_time:
            if self._owed:
                self._settle_owed(doing)
            self._requests += 1
            message = request(self._requests)
            self._death_handled = False
            self._working = self._owed = self._requests
            self._stop_sent = False
            try:
                self._send(message)
                answer = self._answer(doing, due_ns)
                self._owed = 0
            except _ChildFrozen as frozen:
                self._died(doing, hung=str(frozen))
            except BaseException as error:
                if self._death_handled:
                    raise  # the child's end, made safe (`_died`)
                if self._channel_failed(error):
                    self._died(doing)  # the channel's own error: the child's end
                if not self.alive:  # it ended as the caller's own exception came: safe first
                    self._made_safe(doing)
                    raise
                # The caller's own: KeyboardInterrupt (its Ctrl-C), or what a handler of the
                # script's raised (a watchdog's TimeoutError) while the child works on.
                self._interrupted(doing, error)
                raise
            finally:
                self._working = 0
        if isinstance(answer, PlayStopped):
            stopped = Stopped(answer.reason, answer.signal_number)
            stopped.safe_stop = answer.safe_stop
            raise stopped
        return answer

    def _interrupted(self, doing: str, interruption: BaseException) -> None:
        """The caller left (``interruption``: KeyboardInterrupt, or what a handler of the
        script's raised) while the child works on request `_owed`: the stimulus is cut now and
        its answer taken here, so that the next request's answer is its own. Cut part way
        through a message, the channel is of no more use: the child is killed and the pins
        rested from here, and the next stimulus starts another."""
        try:
            if self.conn.midway:
                self._made_safe(doing, hung=f"a message to or from it cut short by "
                                            f"{type(interruption).__name__}: killed")
                self._owed = 0  # made safe: nothing more is owed
                return
            self._send(StopPlaying(self._owed, f"cut short by {type(interruption).__name__}",
                                   None), quietly=True)
            self._stop_sent = True
            self._settle_owed(doing)
        except BaseException:
            pass  # interrupted again: still owed, taken before the next request

    def settle(self) -> None:
        """Take the answer to a request an interruption left (see `_interrupted`), so that
        the next request's is its own; a child killed meanwhile shows as not `alive`."""
        if self._owed and not self._forked_away:
            with self._one_at_a_time:
                if self._owed:
                    self._settle_owed("ending a stimulus cut short")

    def _settle_owed(self, doing: str) -> None:
        """Take (and drop) the answer to request `_owed`, asked to stop if not yet, within
        `STOP_BUDGET_NS`: a child that gives none is killed and the pins rested from here.
        Interrupted again, it is still owed (unless cut part way through the answer: then the
        child is killed), and taken before the next request."""
        number, self._working = self._owed, self._owed
        try:
            if not self._stop_sent:
                self._send(StopPlaying(number, "interrupted", None), quietly=True)
                self._stop_sent = True
            due_ns = self._clock.now_ns() + STOP_BUDGET_NS
            self._answer(doing, lambda: due_ns)
        except BaseException as error:
            if not self._death_handled:
                if self.alive and not self.conn.midway and not self._channel_failed(error):
                    self._working = 0
                    raise  # interrupted again (the caller's, whatever its class): still owed
                self._made_safe(doing, hung=f"its answer cut short by {type(error).__name__}: "
                                            "killed" if self.alive else "")
            # The child's end, made safe (`_died`): the next request finds it gone.
        self._owed = self._working = 0

    def _made_safe(self, doing: str, hung: str = "") -> None:
        """`_died`, for a child that ended (or is killed, ``hung``) while the caller's own
        exception is on its way: the pins made safe, what `_died` raises dropped for it."""
        try:
            self._died(doing, hung=hung)
        except (PinArrayError, Interrupted):
            pass

    def _channel_failed(self, error: BaseException) -> bool:
        """Whether ``error`` is the channel's: this end closed, or the child's end gone as the
        socket shows it (hung up), not only as the exception's class says: a handler of the
        script's may raise a BrokenPipeError of its own (printing into a closed pipe) while the
        child plays on."""
        if self.conn.closed:
            return True
        return (isinstance(error, EOFError | OSError)
                and (self.conn.hung_up() or getattr(error, "errno", None) == errno.EBADF
                     and not self._fd_open()))

    def _fd_open(self) -> bool:
        try:
            os.fstat(self.conn.fileno())
        except OSError:
            return False
        return True

    def _send(self, message: Request | Hello, quietly: bool = False) -> None:
        """One message to the child, whole (a cue may be sent from another thread);
        ``quietly``: a child already gone is left to the watch loop to notice."""
        try:
            with self._sending:
                self.conn.send(message, while_blocked=self._taking_nothing)
        except OSError:
            if not quietly:
                raise

    def _taking_nothing(self) -> None:
        """The child has taken nothing of a message for a while: frozen, it never will."""
        if self._frozen():
            raise _ChildFrozen("it was stopped (SIGSTOP) and took no more of a request: killed")

    def _sending_nothing(self) -> None:
        """The rest of the child's answer has not come for a while: frozen, it never will."""
        if self._frozen():
            raise _ChildFrozen("it was stopped (SIGSTOP) part way through its answer: killed")

    def _wake(self) -> None:
        try:
            os.write(self._wake_write, b"!")
        except OSError:
            pass  # full (woken already) or closed (this player has ended)

    def _answer(self, doing: str, due_ns: Callable[[], int | None]) -> Answer:
        """The child's next message, passing a stop request on; a dead child is a `PlayerDied`.

        An answer not come by ``due_ns()`` (None: no limit yet), or within `STOP_BUDGET_NS` of
        a stop passed on, is never coming: the child is killed and the parent makes the pins
        safe itself.
        """
        clock = self._clock
        stop_due_ns: int | None = None
        self._stopped_before = False
        while True:
            try:
                ready = readable([self.conn.fileno(), self._wake_read], WATCH_S)
                if self._wake_read in ready:
                    os.read(self._wake_read, 64)
                if self.conn.fileno() in ready:
                    answer = self.conn.recv(while_blocked=self._sending_nothing)
                    if isinstance(answer, ANSWERS):
                        return answer
                    self._kill()  # a child that says what no child says: not ours
                    self._died(f"{doing} (it answered {answer!r})")
            except _ChildFrozen as frozen:
                self._died(doing, hung=str(frozen))
            except (EOFError, OSError) as error:
                if self.alive and not self._channel_failed(error):
                    raise  # a handler of the script's raised it meanwhile: the caller's
                self._died(doing)
            if self.stop.requested and self._working and not self._stop_sent:
                self._send_stop()
                stop_due_ns = clock.now_ns() + STOP_BUDGET_NS
            if not self.alive:
                self._died(doing)
            now_ns = clock.now_ns()
            if stop_due_ns is not None and self._frozen():
                self._died(doing, hung="it was stopped (SIGSTOP) and could not stop the trial: "
                                       "killed")
            if self._stopped_twice():
                self._died(doing, hung="it was stopped (SIGSTOP) before it answered: killed")
            if stop_due_ns is not None and now_ns > stop_due_ns:
                self._died(doing, hung=f"it did not answer within {STOP_BUDGET_NS // 10**6} ms "
                                       "of a stop: killed")
            answer_due_ns = due_ns()
            if answer_due_ns is not None and now_ns > answer_due_ns:
                self._died(doing, hung=f"it stopped answering: no answer "
                                       f"{ANSWER_MARGIN_NS / 1e9:g} s after the trial's "
                                       "scheduled end: killed")

    def _stopped_twice(self) -> bool:
        """Whether the child, working on a request, was stopped (SIGSTOP: state T) at this look
        and the one before it: it cannot answer before it is continued, and the stimulus would
        not be delivered as scheduled then, while its pins held torque (a stimulus of minutes
        would, until its end). Twice, so that a stop and continue between two looks is not
        taken for it; not a traced stop (a debugger's, or strace's at every call)."""
        stopped = self._frozen()
        twice, self._stopped_before = stopped and self._stopped_before, stopped
        return twice

    def _frozen(self) -> bool:
        """Whether the child is stopped (SIGSTOP): it cannot answer, however long it is given.
        Not a traced stop: a debugger holding it (or strace, at every call) lets it go on, and
        is left the time a stimulus has, as a hung child is."""
        return process_state(self.process.pid) == "T"

    def _send_stop(self) -> None:
        self._stop_sent = True
        # Gone already: the watch loop notices.
        self._send(StopPlaying(self._working, self.stop.reason, self.stop.signal_number),
                   quietly=True)

    def _ended(self, hung: str) -> int:
        """The child's exit status, once it has ended (``hung``: killed first)."""
        if hung:
            self._kill()  # a stopped process too: SIGKILL needs no cooperation
        try:
            return self.process.wait(timeout=EXIT_WAIT_S)  # its socket closes as it exits
        except subprocess.TimeoutExpired:
            self._kill()
            try:
                return self.process.wait(timeout=EXIT_WAIT_S)
            except subprocess.TimeoutExpired:  # a debugger holds it: reaped once it lets go
                return -signal.SIGKILL

    def _rest_for_death(self) -> SafeStopReport:
        """The pins made safe from here for the child's end, and that recorded: only once
        they are (`rest_and_release` holds every signal back), so that an exception of the
        script's landing before leaves it to be done on the way out."""
        safe = SafeStopReport((), (), ())
        if self.bus is not None and not self._closing:
            safe = self.bus.rest_and_release()
        self._death_handled = True
        return safe

    def _died(self, doing: str, hung: str = "") -> NoReturn:
        """The child ended, or (``hung``: why it is taken for hung) is killed now; the pins
        made safe from here."""
        noticed_ns = time.monotonic_ns()
        try:
            status = self._ended(hung)
        except BaseException:
            # The script's own exception (its watchdog's) as the child is waited for: the
            # pins made safe before it goes on.
            self._rest_for_death()
            raise
        safe = self._rest_for_death()
        stop_signal = status - 128 if status > 128 else -status if status < 0 else None
        if self.stop.requested or stop_signal in STOP_SIGNALS:
            # Asked to stop, or stopped by a signal meant for both (pkill, systemd): a stop.
            number = self.stop.signal_number or stop_signal
            reason = self.stop.reason or (f"stopped by {signal_name(number)}" if number else "stopped")
            stopped = Stopped(reason, number)
            if self.bus is not None and not self._closing:
                stopped.safe_stop = safe  # made here: whoever asked need not make another
            raise stopped
        self._errors.seek(0)
        last_words = self._errors.read().decode(errors="replace").strip().splitlines()[-1:]
        how = hung or ended_how(status)
        text = f"the player process ended while {doing} ({how}"
        text += f": {last_words[0]})" if last_words else ")"
        raise PlayerDied(f"{text}; {safe.describe()}", safe, noticed_ns)

    def close(self) -> None:
        """Stop what the child is doing, ask it to leave, make sure it has; a second close
        does nothing more.

        The caller makes the pins safe through its own port afterwards. In a forked copy of
        the process that started it, nothing: the player is the original's.
        """
        if self._forked_away:
            return
        self._closing = True
        if self.alive and self._frozen():
            self._kill()  # stopped (SIGSTOP): it cannot leave by itself
        if self.alive:
            try:
                if self._working:
                    self._send_stop()
                self._send(Quit())
                self.process.wait(timeout=STOP_BUDGET_NS / 1e9)
            except (OSError, subprocess.TimeoutExpired):
                pass
        if self.alive:
            self._kill()
        if self._killed:
            try:
                self.process.wait(timeout=EXIT_WAIT_S)
            except subprocess.TimeoutExpired:
                pass  # a debugger holds it: reaped once it lets go
        with self._one_at_a_time:  # a request still waiting sees the socket closed
            self.conn.close()
            self._errors.close()
            wake_fds = (self._wake_read, self._wake_write)
            self._wake_read = self._wake_write = -1  # a late stop callback writes nowhere
            for fd in wake_fds:
                if fd >= 0:  # not closed already
                    os.close(fd)

    def _forked(self) -> None:
        """In a forked copy of the process that started this player: let go of its channel
        (and the wake-up pipe), so that the player hears of its parent's end when the parent
        ends, not when the last copy does; the copy never plays."""
        self._forked_away = True
        blank_descriptors(-1 if self.conn.closed else self.conn.fileno(), self._wake_read,
                          self._wake_write)
