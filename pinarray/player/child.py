"""The player process itself: plays trials it is sent on the port it inherited.

Run as ``python -m pinarray.player.child CONTROL_FD PORT_FD`` by `pinarray.player.process`;
never by hand. It asks for real-time priority, then serves numbered requests until told to
quit; however it ends (a stop, its parent gone, a signal, an error) it rests the pins and
releases torque through its own descriptor first.
"""

from __future__ import annotations

import ctypes
import os
import select
import sys
from collections.abc import Callable
from functools import partial
from multiprocessing.connection import Connection

from pinarray.clock import MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.hardware.driver import ArrayDriver, SafeStopReport
from pinarray.player.markers import Announcer
from pinarray.player.messages import (
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
    Quit,
    Ready,
    StopPlaying,
    WakeUpsMeasured,
)
from pinarray.player.playback import OnsetAfter, OnsetPassed, PlaybackAborted, play_prepared
from pinarray.stop import Stopped, raise_on_signals

# SCHED_FIFO priority of the player: above every normal process, below the kernel's own
# interrupt threads (50), so a stuck loop cannot lock the serial driver out.
REALTIME_PRIORITY = 20
PR_SET_TIMERSLACK = 29
REALTIME_HOWTO = ("grant it with `sudo setcap cap_sys_nice+ep \"$(readlink -f .venv/bin/python)\"` "
                  "or an rtprio limit in /etc/security/limits.conf (docs/rig/timing.md: real-time priority)")


class _AskedToStop(Stopped):
    """The parent passed on a stop request: end this trial, answer, wait for the next."""


class _ParentGone(Stopped):
    """The parent's end of the socket closed: nobody else will make the pins safe."""


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
    rests the pins and answers); a `Cue` for it starts a trial waiting for one
    (`wait_for_cue`); a `Quit`, or the parent's end of the socket closing, raises
    `_ParentGone` (the child rests the pins and leaves).
    """

    def __init__(self, conn: Connection, spin_ns: int):
        super().__init__(spin_ns, sleep=self._wait_for_message)
        self.conn = conn
        self._fd = conn.fileno()
        self.working = 0  # number of the request being worked on, 0 between requests
        self._cued = 0  # number of the last request a cue came for

    def _wait_for_message(self, seconds: float | None) -> None:
        # select, not Connection.poll: the latter rounds its timeout up to whole ms.
        if select.select([self._fd], [], [], seconds)[0]:
            self._message()

    def wait_for_cue(self) -> None:
        """Return when the cue for the request being worked on comes (no time limit: the
        parent stops or cancels a stimulus whose cue never comes)."""
        while self._cued != self.working:
            self._wait_for_message(None)

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
        if isinstance(message, Cue) and message.number == self.working:
            self._cued = message.number


class ProtocolMismatch(Exception):
    """The parent sent something this child does not understand (a different pinarray?)."""


def _serve(conn: Connection, port_fd: int) -> int:
    try:
        hello = conn.recv()
    except (EOFError, OSError):
        return 0  # the parent ended before saying anything: it never turned torque on
    if not isinstance(hello, Hello):
        raise ProtocolMismatch(f"expected a Hello, found {hello!r}")
    problem = make_realtime(hello.realtime_priority) if hello.realtime_priority else ""
    clock = ControlledClock(conn, hello.spin_ns)
    # The bus waits on a plain clock: a stop must not cut its own exchanges (the safe stop's).
    bus_clock = MonotonicClock(hello.spin_ns)
    bus = hello.handover.attach(port_fd, bus_clock) if hello.handover is not None else None
    announcer: Announcer | None = None
    markers_problem = ""
    if hello.markers is not None:
        # Opened at real-time priority: the stream's own threads inherit it.
        try:
            announcer = hello.markers.open(clock)
        except PinArrayError as error:
            markers_problem = str(error)
    # From here on this process guards the servos: the parent turns torque on only once it
    # has heard Ready, and however either of us ends, `finally` rests the pins.
    try:
        try:
            conn.send(Ready(problem, markers_problem))
        except OSError:
            return 0  # the parent is gone
        while True:
            try:
                message = conn.recv()
            except (EOFError, OSError):
                return 0  # the parent is gone: `finally` makes the pins safe
            match message:
                case Play(number=number) if bus is not None:
                    conn.send(_working(clock, number,
                                       partial(_play, bus, message, clock, announcer)))
                case MeasureWakeUps(number=number, duration_ns=duration_ns, period_ns=period_ns):
                    conn.send(_working(clock, number,
                                       partial(_wake_ups, clock, duration_ns, period_ns)))
                case Quit():
                    return 0  # `finally` rests the pins: the parent may not outlive this by much
                case StopPlaying() | Cue():
                    pass  # for a request already answered: nothing to stop or start
                case _:
                    raise ProtocolMismatch(f"unexpected message {message!r}")
    finally:
        if bus is not None:
            bus.rest_and_release()
        if announcer is not None:
            announcer.close()


def _working(clock: ControlledClock, number: int, work: Callable[[], Answer]) -> Answer:
    """Do one numbered request; a stop for it becomes a `PlayStopped` answer."""
    clock.working = number
    try:
        return work()
    except _AskedToStop as stopped:
        safe = stopped.safe_stop if isinstance(stopped.safe_stop, SafeStopReport) else None
        return PlayStopped(str(stopped), stopped.signal_number, safe)
    finally:
        clock.working = 0


def _play(bus: ArrayDriver, play: Play, clock: ControlledClock,
          announcer: Announcer | None) -> Played | PlayFailed | OnsetMissed:
    onset = play.onset
    if isinstance(onset, OnCue):
        clock.wait_for_cue()
        onset = OnsetAfter(0)  # at once: the time zero is when the cue came, as measured
    try:
        report = play_prepared(bus, play.trial, clock, onset=onset,
                               tolerance_ns=play.tolerance_ns, release_at_end=False,
                               markers=play.markers, announcer=announcer,
                               stroke_tolerance=play.stroke_tolerance)
    except OnsetPassed as passed:
        return OnsetMissed(str(passed), passed.late_ns)
    except PlaybackAborted as aborted:
        return PlayFailed(str(aborted), aborted.safe_stop)
    return Played(report)


def _wake_ups(clock: ControlledClock, duration_ns: int, period_ns: int) -> WakeUpsMeasured:
    count = max(1, duration_ns // period_ns)
    lateness = [0] * count
    start_ns = clock.now_ns() + period_ns
    for k in range(count):
        deadline_ns = start_ns + k * period_ns
        clock.sleep_until_ns(deadline_ns)
        lateness[k] = clock.now_ns() - deadline_ns
    return WakeUpsMeasured(tuple(lateness))


def main(argv: list[str]) -> int:
    control_fd, port_fd = int(argv[0]), int(argv[1])
    # The channel blocks, whatever its creator's defaults were: a recv that found nothing to
    # read would be taken for the parent gone (a host program's socket timeout made it
    # non-blocking: PsychoPy sets one on import).
    os.set_blocking(control_fd, True)
    conn = Connection(control_fd)
    try:
        with raise_on_signals("the player process"):
            return _serve(conn, port_fd)
    except Stopped as stopped:
        return stopped.exit_status


if __name__ == "__main__":
    # Run the module's importable twin, so its exceptions are the ones the rest imports.
    from pinarray.player.child import main as importable_main

    sys.exit(importable_main(sys.argv[1:]))
