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

import ctypes
import os
import select
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection

from pinarray.bus.base import SafeStopReport
from pinarray.bus.feetech import FeetechBus, Handover
from pinarray.clock import MonotonicClock
from pinarray.player import (
    DEFAULT_LEAD_NS,
    PlaybackAborted,
    PlaybackReport,
    PreparedTrial,
    describe,
    play_prepared,
)
from pinarray.stop import STOP_SIGNALS, Stopped, StopRequest, raise_on_signals, signal_name

# SCHED_FIFO priority of the player: above every normal process, below the kernel's own
# interrupt threads (50), so a stuck loop cannot lock the serial driver out.
REALTIME_PRIORITY = 20
# Spin (rather than sleep) this close to a deadline, in ns; chosen by `make bench`.
SPIN_NS = 200_000
# How often the parent looks at the stop request and the child while a trial plays, in s.
WATCH_S = 0.02
START_TIMEOUT_NS = 30_000_000_000
# Once told to stop, the player process has this long to rest the pins and answer.
STOP_BUDGET_NS = 5_000_000_000
# How long a player process whose socket closed may take to finish exiting, in s.
EXIT_WAIT_S = 1.0
PR_SET_TIMERSLACK = 29
REALTIME_HOWTO = ("grant it with `sudo setcap cap_sys_nice+ep \"$(readlink -f .venv/bin/python)\"` "
                  "or an rtprio limit in /etc/security/limits.conf (README: real-time priority)")


class PlayerDied(PlaybackAborted):
    """The player process ended in the middle of its work; the parent made the pins safe.

    ``noticed_ns`` is when the parent saw it gone (``time.monotonic_ns()``), before the safe stop.
    """

    def __init__(self, message: str, safe_stop: SafeStopReport, noticed_ns: int):
        super().__init__(message, safe_stop)
        self.noticed_ns = noticed_ns


class _AskedToStop(Stopped):
    """The parent passed on a stop request: end this trial, answer, wait for the next."""


class _ParentGone(Stopped):
    """The parent's end of the socket closed: nobody else will make the pins safe."""


# -- messages between the two processes --------------------------------------------------------


@dataclass(frozen=True)
class Hello:
    handover: Handover | None  # None: no port, only timing measurements
    realtime_priority: int | None
    spin_ns: int


@dataclass(frozen=True)
class Ready:
    realtime_problem: str  # empty when real-time priority was granted (or not asked for)


@dataclass(frozen=True)
class Play:
    number: int  # a stop request names the trial it is for: a late one must not stop the next
    trial: PreparedTrial
    lead_ns: int
    tolerance_ns: int


@dataclass(frozen=True)
class StopPlaying:
    number: int
    reason: str
    signal_number: int | None


@dataclass(frozen=True)
class MeasureWakeUps:
    number: int
    duration_ns: int
    period_ns: int


@dataclass(frozen=True)
class Quit:
    pass


@dataclass(frozen=True)
class Played:
    report: PlaybackReport


@dataclass(frozen=True)
class PlayStopped:
    reason: str
    signal_number: int | None


@dataclass(frozen=True)
class PlayFailed:
    message: str
    safe_stop: SafeStopReport


@dataclass(frozen=True)
class WakeUps:
    lateness_ns: tuple[int, ...]


# -- the parent's side ------------------------------------------------------------------------


class PlayerProcess:
    """A player process driving the servos of ``bus`` through the port descriptor ``fd``.

    Parameters
    ----------
    bus : FeetechBus or None
        The parent's connected bus (its port descriptor is shared); None for a process that
        only measures this machine's timing.
    fd : int or None
        The port's file descriptor.
    stop : StopRequest
        Looked at while a trial plays; a request is passed on to the child.
    realtime : bool
        Ask the OS for SCHED_FIFO priority in the child.
    """

    def __init__(self, bus: FeetechBus | None, fd: int | None, stop: StopRequest,
                 realtime: bool = True, spin_ns: int = SPIN_NS):
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
        command = [sys.executable, "-m", "pinarray.player_process", str(child_end.fileno()),
                   str(fd if fd is not None else -1)]
        self.process = subprocess.Popen(
            command, pass_fds=passed, start_new_session=True, stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=self._errors,
        )
        child_end.close()
        self.conn = Connection(parent_end.detach())
        handover = bus.handover() if bus is not None else None
        self.conn.send(Hello(handover, REALTIME_PRIORITY if realtime else None, spin_ns))
        ready = self._answer("starting", START_TIMEOUT_NS)
        if not isinstance(ready, Ready):
            raise PlayerDied(f"the player process answered {ready!r} when starting",
                             SafeStopReport((), (), ()), time.monotonic_ns())
        self.realtime_problem = ready.realtime_problem

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def play(self, trial: PreparedTrial, *, lead_ns: int = DEFAULT_LEAD_NS,
             tolerance_ns: int) -> PlaybackReport:
        """Play one trial in the child; raises `Stopped`, `PlaybackAborted` or `PlayerDied`."""
        answer = self._ask(lambda number: Play(number, trial, lead_ns, tolerance_ns),
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
        if not isinstance(answer, WakeUps):
            raise PlayerDied(f"the player process answered {answer!r} to a measurement",
                             SafeStopReport((), (), ()), time.monotonic_ns())
        return answer.lateness_ns

    def _ask(self, request, doing: str):
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

    def _answer(self, doing: str, timeout_ns: int | None = None):
        """The child's next message, passing a stop request on; a dead child is a `PlayerDied`.

        Once a stop is passed on, the child has `STOP_BUDGET_NS` to answer; after that it is
        killed and the parent makes the pins safe itself.
        """
        clock = self._clock
        give_up_ns = None if timeout_ns is None else clock.now_ns() + timeout_ns
        while True:
            try:
                if self.conn.poll(WATCH_S):
                    return self.conn.recv()
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

    def _died(self, doing: str):
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
        raise PlayerDied(f"{text}; {describe(safe)}", safe, noticed_ns)

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


# -- the child's side -------------------------------------------------------------------------


def make_realtime(priority: int) -> str:
    """Ask for SCHED_FIFO; the problem in one line when refused (empty when granted)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as error:
        why = getattr(error, "strerror", None) or str(error)
        return (f"real-time priority not granted ({why}): on a busy machine stimuli may be "
                f"late by several ms; {REALTIME_HOWTO}")
    try:
        # Sleeps may otherwise end up to 50 us late, the kernel's default timer slack.
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_TIMERSLACK, 1, 0, 0, 0)
    except (OSError, AttributeError):
        pass
    return ""


class ControlledClock(MonotonicClock):
    """Real time for the child: sleeps wake for a message from the parent, then spin.

    A `StopPlaying` for the request being worked on raises `Stopped` at once (the player then
    rests the pins and answers); a `Quit`, or the parent's end of the socket closing, raises
    `_ParentGone` (the child rests the pins and leaves).
    """

    def __init__(self, conn: Connection, spin_ns: int):
        super().__init__(spin_ns, sleep=self._wait_for_message)
        self.conn = conn
        self._fd = conn.fileno()
        self.working = 0  # number of the request being worked on, 0 between requests

    def _wait_for_message(self, seconds: float) -> None:
        # select, not Connection.poll: the latter rounds its timeout up to whole ms.
        if select.select([self._fd], [], [], seconds)[0]:
            self._message()

    def doze_until_ns(self, deadline_ns: int) -> None:
        """Sleep (no spin) until ``deadline_ns``, waking for messages."""
        while (remaining_ns := deadline_ns - self.now_ns()) > 0:
            self._wait_for_message(remaining_ns / 1e9)

    def _message(self) -> None:
        try:
            message = self.conn.recv()
        except (EOFError, OSError):
            raise _ParentGone("the process controlling the player ended") from None
        if isinstance(message, Quit):
            raise _ParentGone("the process controlling the player is closing it")
        if isinstance(message, StopPlaying) and message.number == self.working:
            raise _AskedToStop(message.reason, message.signal_number)


class ProtocolMismatch(Exception):
    """The parent sent something this child does not understand (a different pinarray?)."""


def _serve(conn: Connection, port_fd: int) -> int:
    hello = conn.recv()
    if not isinstance(hello, Hello):
        raise ProtocolMismatch(f"expected a Hello, found {hello!r}")
    problem = make_realtime(hello.realtime_priority) if hello.realtime_priority else ""
    clock = ControlledClock(conn, hello.spin_ns)
    # The bus waits on a plain clock: a stop must not cut its own exchanges (the safe stop's).
    bus_clock = MonotonicClock(hello.spin_ns)
    bus = hello.handover.attach(port_fd, bus_clock) if hello.handover is not None else None
    conn.send(Ready(problem))
    try:
        while True:
            try:
                message = conn.recv()
            except (EOFError, OSError):
                return 0  # the parent is gone: `finally` makes the pins safe
            match message:
                case Play(number=number) if bus is not None:
                    conn.send(_working(clock, number, lambda m=message: _play(bus, m, clock)))
                case MeasureWakeUps(number=number, duration_ns=duration_ns, period_ns=period_ns):
                    conn.send(_working(clock, number,
                                       lambda d=duration_ns, p=period_ns: _wake_ups(clock, d, p)))
                case Quit():
                    return 0  # `finally` rests the pins: the parent may not outlive this by much
                case StopPlaying():
                    pass  # for a request already answered: nothing to stop
                case _:
                    raise ProtocolMismatch(f"unexpected message {message!r}")
    finally:
        if bus is not None:
            bus.rest_and_release()


def _working(clock: ControlledClock, number: int, work):
    """Do one numbered request; a stop for it becomes a `PlayStopped` answer."""
    clock.working = number
    try:
        return work()
    except _AskedToStop as stopped:
        return PlayStopped(str(stopped), stopped.signal_number)
    finally:
        clock.working = 0


def _play(bus: FeetechBus, play: Play, clock: ControlledClock):
    try:
        report = play_prepared(bus, play.trial, clock, lead_ns=play.lead_ns,
                               tolerance_ns=play.tolerance_ns, release_at_end=False)
    except PlaybackAborted as aborted:
        return PlayFailed(str(aborted), aborted.safe_stop)
    return Played(report)


def _wake_ups(clock: ControlledClock, duration_ns: int, period_ns: int) -> WakeUps:
    count = max(1, duration_ns // period_ns)
    lateness = [0] * count
    start_ns = clock.now_ns() + period_ns
    for k in range(count):
        deadline_ns = start_ns + k * period_ns
        clock.sleep_until_ns(deadline_ns)
        lateness[k] = clock.now_ns() - deadline_ns
    return WakeUps(tuple(lateness))


def main(argv: list[str]) -> int:
    control_fd, port_fd = int(argv[0]), int(argv[1])
    conn = Connection(control_fd)
    try:
        with raise_on_signals("the player process"):
            return _serve(conn, port_fd)
    except Stopped as stopped:
        return stopped.exit_status


if __name__ == "__main__":
    # Run the module's importable twin, so the messages unpickle as the parent's classes.
    from pinarray.player_process import main as importable_main

    sys.exit(importable_main(sys.argv[1:]))
