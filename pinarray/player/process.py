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
- the parent dies: the child sees the socket close, rests the pins and releases torque itself;
- the child is sent a signal: it rests the pins, releases torque and exits.

The child runs in its own session, so a Ctrl-C or a hang-up meant for the terminal reaches the
parent only, which decides.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from fractions import Fraction
from multiprocessing.connection import Connection
from typing import NoReturn

from pinarray.clock import MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.hardware.driver import ArrayDriver, SafeStopReport
from pinarray.hardware.motion import DEFAULT_STROKE_TOLERANCE
from pinarray.player.child import REALTIME_PRIORITY
from pinarray.player.markers import Announcers, TrialMarkers
from pinarray.player.messages import (
    ANSWERS,
    Answer,
    Hello,
    MeasureWakeUps,
    Play,
    Played,
    PlayFailed,
    PlayStopped,
    Quit,
    Ready,
    Request,
    StopPlaying,
    WakeUpsMeasured,
)
from pinarray.player.playback import (
    SOON,
    Onset,
    PlaybackAborted,
    PlaybackReport,
    PreparedTrial,
)
from pinarray.stop import STOP_SIGNALS, Stopped, StopRequest, signal_name

# Spin (rather than sleep) this close to a deadline, in ns; chosen by `make bench`.
SPIN_NS = 200_000
# How often the parent looks at the stop request and the child while a trial plays, in s.
WATCH_S = 0.02
START_TIMEOUT_NS = 30_000_000_000
# Once told to stop, the player process has this long to rest the pins and answer.
STOP_BUDGET_NS = 5_000_000_000
# How long a player process whose socket closed may take to finish exiting, in s.
EXIT_WAIT_S = 1.0


class PlayerDied(PlaybackAborted):
    """The player process ended in the middle of its work; the parent made the pins safe.

    ``noticed_ns`` is when the parent saw it gone (``time.monotonic_ns()``), before the safe stop.
    """

    def __init__(self, message: str, safe_stop: SafeStopReport, noticed_ns: int):
        super().__init__(message, safe_stop)
        self.noticed_ns = noticed_ns



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
    """

    def __init__(self, bus: ArrayDriver | None, fd: int | None, stop: StopRequest,
                 realtime: bool = True, spin_ns: int = SPIN_NS,
                 markers: Announcers | None = None):
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
        self._errors = tempfile.TemporaryFile()
        parent_end, child_end = socket.socketpair()
        passed = (child_end.fileno(),) + ((fd,) if fd is not None else ())
        command = [sys.executable, "-m", "pinarray.player.child", str(child_end.fileno()),
                   str(fd if fd is not None else -1)]
        self.process = subprocess.Popen(
            command, pass_fds=passed, start_new_session=True, stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=self._errors,
        )
        child_end.close()
        self.conn = Connection(parent_end.detach())
        handover = bus.handover() if bus is not None else None
        self.conn.send(Hello(handover, REALTIME_PRIORITY if realtime else None, spin_ns,
                             markers))
        ready = self._answer("starting", START_TIMEOUT_NS)
        if not isinstance(ready, Ready):
            raise PlayerDied(f"the player process answered {ready!r} when starting",
                             SafeStopReport((), (), ()), time.monotonic_ns())
        self.realtime_problem = ready.realtime_problem
        if ready.markers_problem:
            self.close()  # torque is not on yet: nothing moves
            raise PinArrayError(ready.markers_problem)

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def play(self, trial: PreparedTrial, *, onset: Onset = SOON,
             tolerance_ns: int, markers: TrialMarkers | None = None,
             stroke_tolerance: Fraction = DEFAULT_STROKE_TOLERANCE) -> PlaybackReport:
        """Play one trial in the child, announcing ``markers`` there if its stream is open;
        raises `Stopped`, `PlaybackAborted` or `PlayerDied`."""
        answer = self._ask(lambda number: Play(number, trial, onset, tolerance_ns, markers,
                                               stroke_tolerance),
                           "playing a trial")
        match answer:
            case Played(report=report):
                if self.bus is not None:
                    # The player left every pin at rest (it forces rest when a change of the
                    # trial's end was not confirmed); the next changed-only write starts there.
                    self.bus.assume_goals({s.servo_id: s.rest_steps for s in self.bus.setup.servos})
                return report
            case PlayFailed(message=message, safe_stop=safe):
                raise PlaybackAborted(message, safe)
        raise PlayerDied(f"the player process answered {answer!r} to a trial",
                         SafeStopReport((), (), ()), time.monotonic_ns())

    def measure_wake_ups(self, duration_ns: int, period_ns: int) -> tuple[int, ...]:
        """How late the child wakes for deadlines every ``period_ns``, for ``duration_ns``."""
        answer = self._ask(lambda number: MeasureWakeUps(number, duration_ns, period_ns),
                           "measuring wake-ups")
        if not isinstance(answer, WakeUpsMeasured):
            raise PlayerDied(f"the player process answered {answer!r} to a measurement",
                             SafeStopReport((), (), ()), time.monotonic_ns())
        return answer.lateness_ns

    def _ask(self, request: Callable[[int], Request], doing: str) -> Answer:
        """Send a numbered request and wait for its answer; a stop ends it with `Stopped`."""
        with self._one_at_a_time:
            self._requests += 1
            self._working = self._requests
            self._stop_sent = False
            try:
                self.conn.send(request(self._requests))
                answer = self._answer(doing)
            except OSError:
                self._died(doing)
            finally:
                self._working = 0
        if isinstance(answer, PlayStopped):
            raise Stopped(answer.reason, answer.signal_number)
        return answer

    def _answer(self, doing: str, timeout_ns: int | None = None) -> Answer:
        """The child's next message, passing a stop request on; a dead child is a `PlayerDied`.

        Once a stop is passed on, the child has `STOP_BUDGET_NS` to answer; after that it is
        killed and the parent makes the pins safe itself.
        """
        clock = self._clock
        give_up_ns = None if timeout_ns is None else clock.now_ns() + timeout_ns
        while True:
            try:
                if self.conn.poll(WATCH_S):
                    answer = self.conn.recv()
                    if isinstance(answer, ANSWERS):
                        return answer
                    self.process.kill()  # a child that says what no child says: not ours
                    self._died(f"{doing} (it answered {answer!r})")
            except (EOFError, OSError):
                self._died(doing)
            if self.stop.requested and self._working and not self._stop_sent:
                self._send_stop()
                give_up_ns = clock.now_ns() + STOP_BUDGET_NS
            if not self.alive or (give_up_ns is not None and clock.now_ns() > give_up_ns):
                self._died(doing)

    def _send_stop(self) -> None:
        self._stop_sent = True
        try:
            self.conn.send(StopPlaying(self._working, self.stop.reason, self.stop.signal_number))
        except OSError:
            pass  # gone already: the watch loop notices

    def _died(self, doing: str) -> NoReturn:
        noticed_ns = time.monotonic_ns()
        try:
            status = self.process.wait(timeout=EXIT_WAIT_S)  # its socket closes as it exits
        except subprocess.TimeoutExpired:
            self.process.kill()
            status = self.process.wait()
        safe = SafeStopReport((), (), ())
        if self.bus is not None and not self._closing:
            safe = self.bus.rest_and_release()
        stop_signal = status - 128 if status > 128 else -status if status < 0 else None
        if self.stop.requested or stop_signal in STOP_SIGNALS:
            # Asked to stop, or stopped by a signal meant for both (pkill, systemd): a stop.
            number = self.stop.signal_number or stop_signal
            reason = self.stop.reason or (f"stopped by {signal_name(number)}" if number else "stopped")
            raise Stopped(reason, number)
        self._errors.seek(0)
        last_words = self._errors.read().decode(errors="replace").strip().splitlines()[-1:]
        how = (f"killed by signal {-status}" if status < 0 else f"exit status {status}")
        text = f"the player process ended while {doing} ({how}"
        text += f": {last_words[0]})" if last_words else ")"
        raise PlayerDied(f"{text}; {safe.describe()}", safe, noticed_ns)

    def close(self) -> None:
        """Stop what the child is doing, ask it to leave, make sure it has.

        The caller makes the pins safe through its own port afterwards.
        """
        self._closing = True
        if self.alive:
            try:
                if self._working:
                    self._send_stop()
                self.conn.send(Quit())
                self.process.wait(timeout=STOP_BUDGET_NS / 1e9)
            except (OSError, subprocess.TimeoutExpired):
                pass
        if self.alive:
            self.process.kill()
            self.process.wait()
        with self._one_at_a_time:  # a request still waiting sees the socket closed
            self.conn.close()
            self._errors.close()


