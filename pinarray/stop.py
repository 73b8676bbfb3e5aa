"""One way to stop: a stop request that composition roots set and every wait looks at.

The only module that handles signals. ``pinarray play``, ``batch``, ``sim-serve`` and the TUI
wrap their work in `stop_on_signals`; SIGHUP (terminal or SSH session closed), SIGINT
(Ctrl-C), SIGQUIT, SIGTERM, SIGUSR1/2, SIGPIPE and every other signal sent to end a process
(`STOP_SIGNALS`: not those of its own faults) then set a `StopRequest` instead of killing it.
Whatever waits (the player between frames, the session between trials) waits on a
`StoppableClock`, which raises `Stopped` at its next look at the request, so every way out runs
through the same ``finally`` that puts the pins at rest and switches torque off.

A terminal's signal that whoever started the process ignored stays ignored (`nohup`: SIGHUP;
a script's background job: SIGINT and SIGQUIT): the run goes on, as asked.

A second signal while a stop is already pending raises `Stopped` at once, wherever the main
thread is: an escape hatch if something does not look at the request. The few steps that must
not be cut in half (a pin's safe stop, a results row) run inside `deferred_signals`.
"""

from __future__ import annotations

import os
import select
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

from pinarray.clock import Clock
from pinarray.errors import Interrupted

# Every signal a stranger can send whose default action ends the process, not only those a
# terminal or a service manager sends: `kill -ALRM`, a CPU-time limit (SIGXCPU), a timer left by
# a wrapper (SIGALRM, SIGVTALRM, SIGPROF), a real-time signal. Left at their default, each ended
# `pinarray servos calibrate` with its pin holding torque. Not the faults a process raises on
# itself (SIGSEGV, SIGABRT, ...), nor SIGXFSZ, which Python ignores so that a write fails where
# it is.
STOP_SIGNALS = tuple(
    getattr(signal, name)
    for name in ("SIGHUP", "SIGINT", "SIGQUIT", "SIGTERM", "SIGUSR1", "SIGUSR2", "SIGPIPE",
                 "SIGALRM", "SIGVTALRM", "SIGPROF", "SIGXCPU", "SIGIO", "SIGPWR", "SIGSTKFLT")
    if hasattr(signal, name)
) + tuple(range(signal.SIGRTMIN, signal.SIGRTMAX + 1) if hasattr(signal, "SIGRTMIN") else ())
_SIGPIPE = getattr(signal, "SIGPIPE", None)
# The signals a terminal sends, which whoever started us may have set to be ignored: `nohup`
# (SIGHUP: the run outlives the SSH session) and a script's background job (SIGINT, SIGQUIT).
# Left ignored, as asked (a batch started with nohup was aborted as the session closed): no
# exit path begins, so nothing needs to rest.
_TERMINAL_SIGNALS = frozenset(
    getattr(signal, name) for name in ("SIGHUP", "SIGINT", "SIGQUIT") if hasattr(signal, name))
# Longest single wait between looks at the stop request, in clock nanoseconds.
SLICE_NS = 20_000_000


class Stopped(Interrupted):
    """The run was asked to stop (a signal, quitting the UI): not a fault of the stimulus.

    Attributes
    ----------
    signal_number : int or None
        The signal that asked, or None when the request came from the program (e.g. the UI).
    """

    def __init__(self, message: str, signal_number: int | None = None):
        super().__init__(message)
        self.signal_number = signal_number

    @property
    def exit_status(self) -> int:
        """The shell's convention for a process ended by a signal: 128 + its number."""
        return 128 + self.signal_number if self.signal_number else 130


class StopRequest:
    """A flag any thread can set once, with the reason; waits look at it."""

    def __init__(self) -> None:
        self._event = threading.Event()
        # The event's flag as a plain attribute: every wait of a trial looks at it (twice per
        # motion sample), and `Event.is_set` is a call.
        self._requested = False
        self.reason = ""
        self.signal_number: int | None = None
        self._callbacks: list[Callable[[], object]] = []

    def request(self, reason: str, signal_number: int | None = None) -> None:
        if not self._event.is_set():
            self.reason, self.signal_number = reason, signal_number
            self._requested = True
            self._event.set()
            for callback in self._callbacks:
                callback()

    def when_requested(self, callback: Callable[[], object]) -> None:
        """Also call ``callback`` (quick, signal-safe: e.g. wake a select loop) on a request."""
        self._callbacks.append(callback)

    def clear(self) -> None:
        self._event.clear()
        self._requested = False
        self.reason, self.signal_number = "", None

    @property
    def requested(self) -> bool:
        return self._event.is_set()

    def wait(self, timeout_s: float) -> bool:
        """Block until a stop is requested or ``timeout_s`` passes; True if requested."""
        return self._event.wait(timeout_s)

    def raise_if_requested(self) -> None:
        if self._requested:
            raise Stopped(self.reason or "stopped", self.signal_number)


def taken_signals() -> tuple[int, ...]:
    """`STOP_SIGNALS` but a terminal's signal that whoever started this process ignored."""
    return tuple(number for number in STOP_SIGNALS
                 if number not in _TERMINAL_SIGNALS or signal.getsignal(number) != signal.SIG_IGN)


def signal_name(signal_number: int) -> str:
    try:
        return signal.Signals(signal_number).name
    except ValueError:
        pass
    if hasattr(signal, "SIGRTMIN") and signal.SIGRTMIN < signal_number < signal.SIGRTMAX:
        # As kill -l names them: the lower half from SIGRTMIN up, the upper from SIGRTMAX down.
        above_min, below_max = signal_number - signal.SIGRTMIN, signal.SIGRTMAX - signal_number
        if above_min <= (signal.SIGRTMAX - signal.SIGRTMIN) // 2:
            return f"SIGRTMIN+{above_min}"
        return f"SIGRTMAX-{below_max}"
    return f"signal {signal_number}"


@contextmanager
def stop_on_signals(stop: StopRequest) -> Iterator[StopRequest]:
    """Inside the block, every stop signal sets ``stop`` instead of ending the process.

    Outside the main thread (where Python cannot install handlers) this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum, frame):
        if stop.requested:
            _raise_unless_deferred(Stopped(f"stopped by {signal_name(signum)} (again)", signum))
        stop.request(f"stopped by {signal_name(signum)}", signum)

    with _taken_by(handler):
        yield stop


@contextmanager
def note_signals(stop: StopRequest) -> Iterator[StopRequest]:
    """Inside the block, every stop signal sets ``stop`` and does nothing else, second ones
    included: for a program whose event loop takes the signals once it runs (the TUI,
    `on_loop_signals`) and looks at ``stop`` then. A signal while it starts would otherwise
    end it at the signal's default action, the terminal left in its hands (alternate screen,
    keys raw); raised instead, it would land in the middle of the loop's own start.

    Outside the main thread this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum, frame):
        stop.request(f"stopped by {signal_name(signum)}", signum)

    with _taken_by(handler):
        yield stop


@contextmanager
def _taken_by(handler: Callable[[int, FrameType | None], object]) -> Iterator[None]:
    """Inside the block, ``handler`` handles every one of `taken_signals`."""
    previous = {number: signal.signal(number, handler) for number in taken_signals()}
    try:
        yield
    finally:
        for number, old in previous.items():
            signal.signal(number, old)


def on_loop_signals(loop, stop: StopRequest, then: Callable[[int], None]) -> tuple[int, ...]:
    """For an asyncio program (the TUI): every stop signal sets ``stop``, then calls ``then``.

    Returns the signals taken. Raises whatever ``loop.add_signal_handler`` raises where
    signals cannot be handled (not the main thread, Windows).
    """

    def handle(signal_number: int) -> None:
        stop.request(f"stopped by {signal_name(signal_number)}", signal_number)
        then(signal_number)

    taken = taken_signals()
    for number in taken:
        loop.add_signal_handler(number, handle, number)
    return taken


class SignalTap:
    """The signals an asyncio loop is told of, seen by another thread as well: for a loop that
    can be held (blocked in a call that does not return) while a signal must be acted on.

    asyncio hears of a signal through a byte written to Python's wakeup descriptor the moment
    the signal arrives (`on_loop_signals`); the tap puts a pipe of its own there, and `wait`
    passes every byte on to the loop's descriptor (while told to), returning the signals among
    ``watched``. Made from the main thread, after the loop's handlers. Its reader stops passing
    bytes on before the loop closes (a closed descriptor's number may be a file's by then);
    once the main thread has called `detach`, the reader calls `close`.
    """

    def __init__(self, watched: tuple[int, ...]) -> None:
        self.watched = frozenset(watched)
        self._read, self._write = os.pipe()
        os.set_blocking(self._read, False)
        os.set_blocking(self._write, False)
        self._loop_fd = signal.set_wakeup_fd(self._write, warn_on_full_buffer=False)

    def wait(self, timeout_s: float, *, forward: bool = True) -> tuple[int, ...]:
        """The watched signals that arrived, waiting up to ``timeout_s`` for any signal;
        ``forward``: each byte passed on to the loop."""
        if not select.select([self._read], [], [], timeout_s)[0]:
            return ()
        try:
            data = os.read(self._read, 512)
        except BlockingIOError:
            return ()
        if forward and self._loop_fd >= 0:
            try:
                os.write(self._loop_fd, data)
            except OSError:
                pass  # full: the loop has bytes to wake it already
        return tuple(number for number in data if number in self.watched)

    def detach(self) -> None:
        """From the main thread, the loop closed: Python's wakeup descriptor no longer the
        tap's (none, as the loop's close left it)."""
        current = signal.set_wakeup_fd(-1)
        if current != self._write:
            signal.set_wakeup_fd(current, warn_on_full_buffer=False)  # someone else's: theirs

    def close(self) -> None:
        """From the reader, after `detach`: the pipe closed."""
        os.close(self._read)
        os.close(self._write)


@contextmanager
def signals_wake(fd: int) -> Iterator[None]:
    """Inside the block, every signal Python handles also writes a byte to ``fd`` the moment
    it arrives, whichever thread the kernel gives it to: for a main thread that blocks in
    ``select`` with no timeout, watching the read end of ``fd``'s pipe (``fd`` must not block).

    Python runs a handler only when the main thread next runs Python code: a signal taken by
    another thread, or landing just before the ``select`` begins, would leave the main thread
    blocked with the handler not yet run (a ``sim-serve`` once stayed up 60 s after SIGTERM).
    The byte wakes it, and the handler runs. Outside the main thread this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.set_wakeup_fd(fd, warn_on_full_buffer=False)
    try:
        yield
    finally:
        signal.set_wakeup_fd(previous)

@contextmanager
def raise_on_signals(what: str, *, pipe_ignored: bool = False) -> Iterator[None]:
    """Inside the block, every stop signal raises `Stopped` where the main thread is.

    For a process whose only job is a loop that already unwinds safely on `Interrupted` (the
    player process): it has nothing else that could look at a flag in time.

    ``pipe_ignored``: SIGPIPE is ignored instead, so that a write to a reader that has gone
    fails where it is (EPIPE), for the writer to handle: as a signal, raised by that write, its
    exception lands wherever the main thread is next, the ``finally`` that would handle it
    included (the player process: before its safe stop began).
    """

    def handler(signum, frame):
        _raise_unless_deferred(Stopped(f"{what} stopped by {signal_name(signum)}", signum))

    previous = {number: signal.signal(
        number, signal.SIG_IGN if pipe_ignored and number == _SIGPIPE else handler)
        for number in taken_signals()}
    try:
        yield
    finally:
        for number, old in previous.items():
            signal.signal(number, old)


class _Deferral:
    """Nesting depth of `deferred_signals` in the main thread, and what waited meanwhile."""

    depth = 0
    pending: Stopped | None = None


def _raise_unless_deferred(stopped: Stopped) -> None:
    # Masking alone is not enough: once another thread exists (numpy starts one) the kernel
    # hands the signal to that thread and Python still runs the handler in the main one.
    if _Deferral.depth:
        _Deferral.pending = _Deferral.pending or stopped
        return
    raise stopped


@contextmanager
def deferred_signals() -> Iterator[None]:
    """Inside the block every signal waits that Python handles; outside any main thread this
    does nothing.

    For the few steps that must finish once begun: a pin's safe stop (rest, then torque off)
    and a results row (``beh.tsv``, then ``events.tsv``). Each signal that arrives meanwhile
    is handed, when the outermost block ends, to the handler its signal has then (a handler
    that installs its successor is followed), in the order Python took them: a handler that
    raises raises there instead. Not only pinarray's: a lab script's Ctrl-C
    (KeyboardInterrupt) or the exception its watchdog's SIGALRM handler raises would otherwise
    land between the goals to rest and the torque off, and a servo sent a goal holds torque.
    A signal left at its default action of ending the process (SIGTERM or SIGHUP where nothing
    handles them) is noted too, and ends it, by that signal, once the block is done.
    """
    if threading.current_thread() is not threading.main_thread():
        # Python runs signal handlers in the main thread only: this thread is never interrupted.
        yield
        return
    if _Deferral.depth:  # inside another block, which holds them
        _Deferral.depth += 1
        try:
            yield
        finally:
            _Deferral.depth -= 1
        return
    held, counted = _Held(), False
    try:  # a handler may raise at any step (a watchdog's): whatever was swapped goes back
        _hold_handlers(held)
        _Deferral.depth += 1
        counted = True
        yield
    finally:
        if counted:
            _Deferral.depth -= 1
        _hand_over(held)
    # Reached only when the block ended normally: one of pinarray's handlers that ran in it
    # anyway (set inside it) raises now.
    if _Deferral.pending is not None:
        stopped, _Deferral.pending = _Deferral.pending, None
        raise stopped


# Signals whose default action ends the process, held back like those with a handler: masking
# them holds them back from the main thread only, and the kernel gives a signal sent to the
# process to another thread (numpy's OpenBLAS): the process ended in the middle of the rest.
_ENDING = frozenset(STOP_SIGNALS)


class _Held:
    """The handlers `deferred_signals` put aside, and the signals that came for them."""

    def __init__(self) -> None:
        self.handlers: dict[int, Callable[[int, FrameType | None], object] | int] = {}
        self.arrived: list[int] = []
        self.over = False  # the block has ended: its handlers are being put back

    def note(self, signum: int, frame: FrameType | None) -> None:
        if not self.over:
            self.arrived.append(signum)
            return
        # Still in place after the block: an exception cut the putting back short. Put back
        # now and handed on, as if it had been.
        handler = self.handlers[signum]
        signal.signal(signum, handler)
        _deliver(signum, handler, frame)


def _hold_handlers(held: _Held) -> None:
    """Every Python handler, and every default action of ending the process, swapped for a
    handler that notes its signal. Masking is not enough: once another thread exists (numpy's
    OpenBLAS starts one) the kernel hands the signal to that thread, and Python runs the
    handler in the main one all the same (or the default action ends the process).

    A handler not yet swapped may run meanwhile and raise (a watchdog's): ``held`` says which
    were, for `_hand_over` to put back, or the script's Ctrl-C would be noted for ever.
    """
    for number in signal.valid_signals():
        handler = signal.getsignal(number)
        if callable(handler) or handler == signal.SIG_DFL and number in _ENDING:
            held.handlers[number] = handler  # first: put back whatever lands next
            try:
                signal.signal(number, held.note)
            except (OSError, ValueError):  # one Python may not set
                del held.handlers[number]


def _hand_over(held: _Held) -> None:
    """The handlers put back, every one of them, then each signal that came handed to the
    handler its signal has at that moment."""
    held.over = True
    late = _put_back(held)
    for number in held.arrived:
        _deliver(number, signal.getsignal(number), None)
    if late is not None:
        raise late


def _put_back(held: _Held) -> BaseException | None:
    """Every handler put back; the first exception a handler already back raised meanwhile
    (a watchdog's), kept for after: the others go back all the same."""
    late: BaseException | None = None
    left = list(held.handlers.items())
    while left:
        try:
            while left:
                number, handler = left[-1]
                signal.signal(number, handler)
                left.pop()
        except BaseException as error:
            late = late or error
    return late


def _deliver(number: int, handler: object, frame: FrameType | None) -> None:
    """``number`` handed to ``handler``: called, or its default action if that ends the
    process."""
    if callable(handler):
        handler(number, frame)
    elif handler == signal.SIG_DFL and number in _ENDING:
        signal.raise_signal(number)


class StoppableClock:
    """Delegates to ``clock``; once ``stop`` is requested every wait raises `Stopped`.

    Only the session's and the player's waits go through it, never the bus's own: a wait cut
    short inside a packet exchange would leave the safe stop talking to a confused port.

    Parameters
    ----------
    clock : Clock
        The clock the bus also uses (same time base).
    stop : StopRequest
        Looked at before and during every wait, at least every `SLICE_NS`.
    """

    def __init__(self, clock: Clock, stop: StopRequest):
        self.clock = clock
        self.stop = stop

    def now_ns(self) -> int:
        return self.clock.now_ns()

    def sleep_until_ns(self, deadline_ns: int) -> None:
        stop, clock = self.stop, self.clock
        while True:
            stop.raise_if_requested()
            now_ns = clock.now_ns()
            if now_ns >= deadline_ns:
                return
            if deadline_ns - now_ns > SLICE_NS:
                clock.doze_until_ns(now_ns + SLICE_NS)  # not the deadline yet: no spinning
            else:
                clock.sleep_until_ns(deadline_ns)

    doze_until_ns = sleep_until_ns

