"""The player process itself: plays trials it is sent on the port it inherited.

Run as ``python -m pinarray.player.child CONTROL_FD PORT_FD PARENT_PID`` by
`pinarray.player.process`; never by hand. It asks for real-time priority, then serves
numbered requests until told to quit; however it ends (a stop, its parent gone, a signal, an
error) it rests the pins and releases torque through its own descriptor first.

It watches its parent process itself (a pidfd, readable the moment the parent ends), not only
the channel, whose other end a forked copy of the parent may still hold. While it works on a
stimulus it also looks, every `PARENT_WATCH_NS`, whether its parent was suspended (Ctrl-Z,
SIGSTOP): a script nobody can stop while it is suspended gets no stimulus played on its
behalf; the child cuts it, rests the pins and releases torque (`PlaySuspended`). Between
stimuli the pins hold at rest, as they do while a script waits for anything else.
"""

from __future__ import annotations

import os
import select
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial

from pinarray.clock import MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.hardware.descriptors import below_select_limit
from pinarray.hardware.driver import ArrayDriver, SafeStopReport
from pinarray.player.channel import Channel
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
    PlaySuspended,
    Quit,
    Ready,
    StopPlaying,
    WakeUpsMeasured,
)
from pinarray.stop import Stopped, deferred_signals, raise_on_signals, signals_wake
from pinarray.units import NS_PER_S

# SCHED_FIFO priority of the player: above every normal process, below the kernel's own
# interrupt threads (50), so a stuck loop cannot lock the serial driver out.
REALTIME_PRIORITY = 20
PR_SET_TIMERSLACK = 29
REALTIME_HOWTO = ("grant it with `sudo setcap cap_sys_nice+ep \"$(readlink -f .venv/bin/python)\"` "
                  "or an rtprio limit in /etc/security/limits.conf (docs/rig/timing.md: real-time priority)")


# How often a player at work looks whether its parent was suspended (and, where the system
# gives no pidfd, whether its parent still lives), in ns.
PARENT_WATCH_NS = 20_000_000
SUSPENDED = "the script was suspended (Ctrl-Z or SIGSTOP)"


class _AskedToStop(Stopped):
    """The parent passed on a stop request: end this trial, answer, wait for the next."""


class _ParentGone(Stopped):
    """The parent ended (or its end of the socket closed): nobody else will make the pins
    safe."""


class _Suspended(Stopped):
    """The parent was suspended while a trial played or waited for its onset."""

    def __init__(self, noticed_ns: int):
        super().__init__(SUSPENDED)
        self.noticed_ns = noticed_ns


class Parent:
    """The process that started this player: a descriptor readable once it has ended (a
    pidfd; None where the system has none: then `gone` is looked at), and whether it is
    suspended."""

    def __init__(self, pid: int):
        self.pid = pid
        self.fd: int | None
        try:
            self.fd = os.pidfd_open(pid)
        except (AttributeError, OSError):
            self.fd = None

    @property
    def gone(self) -> bool:
        """Whether it has ended (this process was handed to another parent)."""
        return os.getppid() != self.pid

    def suspended(self) -> bool:
        """Whether it is stopped by job control (Ctrl-Z, SIGSTOP): state ``T``, not ``t`` (a
        debugger's or a profiler's brief stop)."""
        return process_state(self.pid) == "T"


def process_state(pid: int) -> str:
    """The state letter /proc gives process ``pid`` (``R``, ``S``, ``T`` stopped, ``t``
    traced, ...); empty when it cannot be read (gone)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat_file:
            stat = stat_file.read()
    except OSError:
        return ""
    # "pid (command) state ...": the command may hold spaces and parentheses.
    end = stat.rfind(b")")
    return stat[end + 2:end + 3].decode(errors="replace")


def make_realtime(priority: int) -> str:
    """Ask for SCHED_FIFO; the problem in one line when refused (empty when granted)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as error:
        why = getattr(error, "strerror", None) or str(error)
        return (f"real-time priority not granted ({why}): on a busy machine stimuli may be "
                f"late by several ms; {REALTIME_HOWTO}")
    try:
        # Sleeps may otherwise end up to 50 us late, the kernel's default timer slack. ctypes
        # imported here: only a process granted the priority needs it (4-7 ms of processor).
        import ctypes

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

    def __init__(self, conn: Channel, spin_ns: int, parent: Parent, woken_fd: int):
        super().__init__(spin_ns, sleep=self._wait_for_message)
        self.conn = conn
        self.parent = parent
        self._fd = conn.fileno()
        self._woken_fd = woken_fd  # readable when a signal came (`woken_by_signals`)
        self._watched = [self._fd, woken_fd] + ([parent.fd] if parent.fd is not None else [])
        self.working = 0  # number of the request being worked on, 0 between requests
        self._cued = 0  # number of the last request a cue came for
        self.playing = False  # a trial is being played (or waits for its onset)
        self._waiting_for_cue = False  # a trial held ready: nothing plays until its cue
        self._looked_ns = 0  # when the parent's state was last looked at

    def _wait_for_message(self, seconds: float | None) -> None:
        watching = self.playing and not self._waiting_for_cue
        if watching or self.parent.fd is None:
            if watching and self.now_ns() - self._looked_ns >= PARENT_WATCH_NS:
                self._looked_ns = self.now_ns()
                if self.parent.suspended():
                    raise _Suspended(self._looked_ns)
            slice_s = PARENT_WATCH_NS / NS_PER_S
            seconds = slice_s if seconds is None else min(seconds, slice_s)
        # select, not poll: the latter takes its timeout in whole ms.
        ready = self._select(seconds)
        if self.parent.fd in ready or (self.parent.fd is None and self.parent.gone):
            raise _ParentGone("the process controlling the player ended")
        if self._fd in ready:
            self._message()

    def _select(self, seconds: float | None) -> list[int]:
        ready = select.select(self._watched, [], [], seconds)[0]
        if self._woken_fd in ready:  # a signal's byte: its handler runs as this returns
            os.read(self._woken_fd, 64)
        return ready

    def wait_for_request(self) -> None:
        """Until the parent sends something; `_ParentGone` if it ends first (a request it
        sent before it ended is not served)."""
        timeout_s = None if self.parent.fd is not None else PARENT_WATCH_NS / NS_PER_S
        while True:
            ready = self._select(timeout_s)
            if self.parent.fd in ready or (self.parent.fd is None and self.parent.gone):
                raise _ParentGone("the process controlling the player ended")
            if self._fd in ready:
                return

    def wait_for_cue(self) -> None:
        """Return when the cue for the request being worked on comes (no time limit: the
        parent stops or cancels a stimulus whose cue never comes)."""
        self._waiting_for_cue = True
        try:
            while self._cued != self.working:
                self._wait_for_message(None)
        finally:
            self._waiting_for_cue = False

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


class Guarded:
    """The servos this process guards, until their safe stop has been made: a stop signal
    landing in `_serve`'s ``finally`` before it (a second signal, at that instant) leaves it
    to `main`."""

    bus: ArrayDriver | None = None


def _serve(conn: Channel, port_fd: int, parent: Parent, woken_fd: int,
           guarded: Guarded) -> int:
    try:
        if parent.gone:
            return 0  # the parent ended before this could watch it: it never turned torque on
        hello = conn.recv()
    except (EOFError, OSError):
        return 0  # the parent ended before saying anything: it never turned torque on
    if not isinstance(hello, Hello):
        raise ProtocolMismatch(f"expected a Hello, found {hello!r}")
    problem = make_realtime(hello.realtime_priority) if hello.realtime_priority else ""
    clock = ControlledClock(conn, hello.spin_ns, parent, woken_fd)
    # The bus waits on a plain clock: a stop must not cut its own exchanges (the safe stop's).
    bus_clock = MonotonicClock(hello.spin_ns)
    bus = None
    if hello.handover is not None:
        bus = guarded.bus = hello.handover.attach(port_fd, bus_clock)
        load_playback()  # before Ready: the first trial must not wait for it
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
                clock.wait_for_request()  # `_ParentGone` when the parent ends meanwhile
                message = conn.recv()
            except (EOFError, OSError):
                return 0  # the parent is gone: `finally` makes the pins safe
            match message:
                case Play(number=number) if bus is not None:
                    answer = _working(clock, number,
                                      partial(_play, bus, message, clock, announcer))
                case MeasureWakeUps(number=number, duration_ns=duration_ns, period_ns=period_ns):
                    answer = _working(clock, number,
                                      partial(_wake_ups, clock, duration_ns, period_ns))
                case Quit():
                    return 0  # `finally` rests the pins: the parent may not outlive this by much
                case StopPlaying() | Cue():
                    continue  # for a request already answered: nothing to stop or start
                case _:
                    raise ProtocolMismatch(f"unexpected message {message!r}")
            try:
                conn.send(answer)
            except OSError:
                return 0  # the parent is gone (EPIPE): `finally` makes the pins safe
    finally:
        if bus is not None:
            bus.rest_and_release()
            guarded.bus = None
        if announcer is not None:
            announcer.close()


def _working(clock: ControlledClock, number: int, work: Callable[[], Answer]) -> Answer:
    """Do one numbered request; a stop for it becomes a `PlayStopped` answer, a suspended
    parent a `PlaySuspended`."""
    clock.working = number
    try:
        return work()
    except _AskedToStop as stopped:
        safe = stopped.safe_stop if isinstance(stopped.safe_stop, SafeStopReport) else None
        return PlayStopped(str(stopped), stopped.signal_number, safe)
    except _Suspended as suspended:
        # Cut before it began: nothing moved, the pins hold at rest as between stimuli.
        safe = (suspended.safe_stop if isinstance(suspended.safe_stop, SafeStopReport)
                else SafeStopReport((), (), ()))
        return PlaySuspended(str(suspended), safe, suspended.noticed_ns)
    finally:
        clock.working = 0


def load_playback() -> None:
    """Load playback in a player given servos, before it answers `Ready`; a player that only
    measures wake-ups (a timing check's) never needs it. No numpy comes with it, nor while a
    trial plays (`pinarray.player.playback`): a tenth of a second of processor at every start
    of a player process (bench_startup)."""
    import pinarray.player.playback  # noqa: F401


def _play(bus: ArrayDriver, play: Play, clock: ControlledClock,
          announcer: Announcer | None) -> Played | PlayFailed | OnsetMissed:
    from pinarray.player.playback import OnsetAfter, OnsetPassed, PlaybackAborted, play_prepared

    onset = play.onset
    if isinstance(onset, OnCue):
        clock.wait_for_cue()
        onset = OnsetAfter(0)  # at once: the time zero is when the cue came, as measured
    clock.playing = True  # from here a suspended parent cuts it
    try:
        report = play_prepared(bus, play.trial, clock, onset=onset,
                               tolerance_ns=play.tolerance_ns, release_at_end=False,
                               markers=play.markers, announcer=announcer,
                               stroke_tolerance=play.stroke_tolerance)
    except OnsetPassed as passed:
        return OnsetMissed(str(passed), passed.late_ns)
    except PlaybackAborted as aborted:
        return PlayFailed(str(aborted), aborted.safe_stop)
    finally:
        clock.playing = False
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


@contextmanager
def woken_by_signals() -> Iterator[int]:
    """A descriptor the clock's waits watch, readable the moment a signal arrives
    (`pinarray.stop.signals_wake`): a stop signal landing just before a wait with no timeout
    began (between requests), or taken by another thread (a marker stream's), would otherwise
    leave its handler unrun until the parent's next message."""
    read_fd, write_fd = os.pipe()
    os.set_blocking(read_fd, False)
    os.set_blocking(write_fd, False)  # a signal's byte must never block
    try:
        with signals_wake(write_fd):
            yield read_fd
    finally:
        os.close(read_fd)
        os.close(write_fd)


def main(argv: list[str]) -> int:
    control_fd, port_fd, parent_pid = int(argv[0]), int(argv[1]), int(argv[2])
    # Numbers select can watch, whatever the parent held (its waits are select's).
    control_fd = below_select_limit(control_fd)
    port_fd = below_select_limit(port_fd) if port_fd >= 0 else port_fd
    parent = Parent(parent_pid)
    # The channel blocks, whatever its creator's defaults were: a recv that found nothing to
    # read would be taken for the parent gone (a host program's socket timeout made it
    # non-blocking: PsychoPy sets one on import).
    os.set_blocking(control_fd, True)
    conn = Channel(control_fd)
    guarded = Guarded()
    try:
        # A write to a parent that has gone fails with EPIPE where it is (the parent gone:
        # `_serve`'s `finally` rests the pins). As SIGPIPE, a stop signal, it landed in that
        # `finally` itself, before the safe stop began: torque stayed on.
        with raise_on_signals("the player process", pipe_ignored=True), \
                woken_by_signals() as woken_fd:
            try:
                return _serve(conn, port_fd, parent, woken_fd, guarded)
            finally:
                if guarded.bus is not None:  # a signal cut `_serve`'s safe stop short
                    with deferred_signals():
                        guarded.bus.rest_and_release()
    except Stopped as stopped:
        return stopped.exit_status


if __name__ == "__main__":
    # Run the module's importable twin, so its exceptions are the ones the rest imports.
    from pinarray.player.child import main as importable_main

    sys.exit(importable_main(sys.argv[1:]))
