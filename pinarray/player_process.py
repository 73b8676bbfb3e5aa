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
from pinarray.stop import Stopped, StopRequest, raise_on_signals

# SCHED_FIFO priority of the player: above every normal process, below the kernel's own
# interrupt threads (50), so a stuck loop cannot lock the serial driver out.
REALTIME_PRIORITY = 20
# Spin (rather than sleep) this close to a deadline, in ns; chosen by `make bench`.
SPIN_NS = 200_000
# How often the parent looks at the stop request and the child while a trial plays, in s.
WATCH_S = 0.02
START_TIMEOUT_S = 30.0
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
        self._played = 0
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
        ready = self._answer(START_TIMEOUT_S, "starting")
        assert isinstance(ready, Ready), ready
        self.realtime_problem = ready.realtime_problem

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def play(self, trial: PreparedTrial, *, lead_ns: int = DEFAULT_LEAD_NS,
             tolerance_ns: int) -> PlaybackReport:
        """Play one trial in the child; raises `Stopped`, `PlaybackAborted` or `PlayerDied`."""
        with self._one_at_a_time:
            self._played += 1
            self.conn.send(Play(self._played, trial, lead_ns, tolerance_ns))
            answer = self._answer(None, "playing a trial")
        match answer:
            case Played(report=report):
                if self.bus is not None:
                    self.bus.assume_goals({s.servo_id: s.rest_steps for s in self.bus.setup.servos})
                return report
            case PlayStopped(reason=reason, signal_number=number):
                raise Stopped(reason, number)
            case PlayFailed(message=message, safe_stop=safe):
                raise PlaybackAborted(message, safe)
        raise AssertionError(f"unexpected answer from the player process: {answer!r}")

    def measure_wake_ups(self, duration_ns: int, period_ns: int) -> tuple[int, ...]:
        """How late the child wakes for deadlines every ``period_ns``, for ``duration_ns``."""
        with self._one_at_a_time:
            self.conn.send(MeasureWakeUps(duration_ns, period_ns))
            answer = self._answer(None, "measuring wake-ups")
        assert isinstance(answer, WakeUps), answer
        return answer.lateness_ns

    def _answer(self, timeout_s: float | None, doing: str):
        """The child's next message, passing a stop request on; a dead child is a `PlayerDied`."""
        stop_sent = False
        give_up = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            try:
                if self.conn.poll(WATCH_S):
                    return self.conn.recv()
            except (EOFError, OSError):
                self._died(doing)
            if self.stop.requested and not stop_sent:
                try:
                    self.conn.send(StopPlaying(self._played, self.stop.reason,
                                               self.stop.signal_number))
                except OSError:
                    self._died(doing)
                stop_sent = True
            if not self.alive or (give_up is not None and time.monotonic() > give_up):
                self._died(doing)

    def _died(self, doing: str):
        noticed_ns = time.monotonic_ns()
        try:
            status = self.process.wait(timeout=EXIT_WAIT_S)  # its socket closes as it exits
        except subprocess.TimeoutExpired:
            self.process.kill()
            status = self.process.wait()
        self._errors.seek(0)
        last_words = self._errors.read().decode(errors="replace").strip().splitlines()[-1:]
        how = (f"killed by signal {-status}" if status < 0 else f"exit status {status}")
        text = f"the player process ended while {doing} ({how}"
        text += f": {last_words[0]})" if last_words else ")"
        safe = self.bus.rest_and_release() if self.bus is not None else SafeStopReport((), (), ())
        raise PlayerDied(f"{text}; {describe(safe)}", safe, noticed_ns)

    def close(self) -> None:
        """Ask the child to leave; make sure it has."""
        if self.alive:
            try:
                self.conn.send(Quit())
                self.process.wait(timeout=2)
            except (OSError, subprocess.TimeoutExpired):
                pass
        if self.alive:
            self.process.kill()
            self.process.wait()
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

    A `StopPlaying` for the trial playing, or the parent's end of the socket closing, raises
    `Stopped` at once: the player then rests the pins.
    """

    def __init__(self, conn: Connection, spin_ns: int):
        super().__init__(spin_ns, sleep=self._wait_for_message)
        self.conn = conn
        self._fd = conn.fileno()
        self.playing = 0  # number of the trial playing, 0 between trials

    def _wait_for_message(self, seconds: float) -> None:
        # select, not Connection.poll: the latter rounds its timeout up to whole ms.
        if select.select([self._fd], [], [], seconds)[0]:
            self._message()

    def doze_until_ns(self, deadline_ns: int) -> None:
        self.sleep_until_ns(deadline_ns)

    def _message(self) -> None:
        try:
            message = self.conn.recv()
        except (EOFError, OSError):
            raise _ParentGone("the process controlling the player ended") from None
        if isinstance(message, StopPlaying) and message.number == self.playing:
            raise _AskedToStop(message.reason, message.signal_number)


def _serve(conn: Connection, port_fd: int) -> int:
    hello = conn.recv()
    assert isinstance(hello, Hello), hello
    problem = make_realtime(hello.realtime_priority) if hello.realtime_priority else ""
    clock = ControlledClock(conn, hello.spin_ns)
    # The bus waits on a plain clock: a stop must not cut its own exchanges (the safe stop's).
    bus_clock = MonotonicClock(hello.spin_ns)
    bus = hello.handover.attach(port_fd, bus_clock) if hello.handover is not None else None
    conn.send(Ready(problem))
    released = False
    try:
        while True:
            try:
                message = conn.recv()
            except (EOFError, OSError):
                return 0  # the parent is gone: `finally` makes the pins safe
            match message:
                case Play(number=number, trial=trial, lead_ns=lead_ns, tolerance_ns=tolerance_ns):
                    assert bus is not None
                    clock.playing = number
                    try:
                        conn.send(_play(bus, trial, clock, lead_ns, tolerance_ns))
                    finally:
                        clock.playing = 0
                case MeasureWakeUps(duration_ns=duration_ns, period_ns=period_ns):
                    conn.send(WakeUps(_wake_ups(clock, duration_ns, period_ns)))
                case Quit():
                    released = True  # the parent makes the pins safe through its own port
                    return 0
                # A stop request for a trial already over needs nothing.
    finally:
        if bus is not None and not released:
            bus.rest_and_release()


def _play(bus: FeetechBus, trial: PreparedTrial, clock: ControlledClock, lead_ns: int,
          tolerance_ns: int):
    try:
        report = play_prepared(bus, trial, clock, lead_ns=lead_ns, tolerance_ns=tolerance_ns,
                               release_at_end=False)
    except _AskedToStop as stopped:
        return PlayStopped(str(stopped), stopped.signal_number)
    except PlaybackAborted as aborted:
        return PlayFailed(str(aborted), aborted.safe_stop)
    return Played(report)


def _wake_ups(clock: ControlledClock, duration_ns: int, period_ns: int) -> tuple[int, ...]:
    count = max(1, duration_ns // period_ns)
    lateness = [0] * count
    start_ns = clock.now_ns() + period_ns
    for k in range(count):
        deadline_ns = start_ns + k * period_ns
        clock.sleep_until_ns(deadline_ns)
        lateness[k] = clock.now_ns() - deadline_ns
    return tuple(lateness)


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
