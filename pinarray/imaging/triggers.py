"""Where volume triggers come from: a serial trigger converter, a key, or an emulated scanner.

Each source calls ``arrived(at_ns)`` once per volume trigger, stamped on the session's clock.
A serial converter is read in a thread of its own, so a trigger is stamped when its byte
arrives whatever the session is doing; a key is stamped when the UI hands it over; an
emulated scanner has no thread at all: its volumes are due every TR from the start of the
wait, on whatever clock the session keeps (virtual time included), and become arrivals as
that clock passes them.

A serial or key trigger is stamped on the wall clock, so the session's clock must run at the
wall clock's pace (`follows_wall_clock`); an emulated one works on any clock.
"""

from __future__ import annotations

import errno
import os
import threading
from collections.abc import Callable
from typing import TypeAlias

from pinarray.clock import Clock, MonotonicClock, ScaledClock
from pinarray.errors import PinArrayError
from pinarray.protocol.imaging import EmulatedTrigger, KeyTrigger, SerialTrigger, Trigger

# How long one read of the converter blocks before looking at whether it should stop, in s.
READ_SLICE_S = 0.05
Arrived = Callable[[int], None]


class TriggerError(PinArrayError):
    """The trigger cannot be used: a device that does not open, or no volume in time."""


def follows_wall_clock(clock: Clock) -> bool:
    """Whether ``clock`` runs at the wall clock's pace (real time, or scaled by exactly 1).

    A trigger stamped on the wall clock, or a marker for another machine's recording, means
    nothing on a simulated clock (virtual, paced, or sped up).
    """
    inner = getattr(clock, "clock", clock)  # a StoppableClock's own clock
    return isinstance(inner, MonotonicClock) or (isinstance(inner, ScaledClock)
                                                 and inner.scale == 1)


class SerialVolumes:
    """A trigger converter on a serial device: one ``trigger.character`` byte per volume.

    Other bytes (button presses on the same converter, noise) are counted, not taken for
    volumes. Bytes waiting in the device before it was opened are dropped: they belong to
    an earlier scan.

    Raises
    ------
    TriggerError
        The device does not exist or cannot be opened.
    """

    def __init__(self, trigger: SerialTrigger, clock: Clock, arrived: Arrived):
        import serial

        self.trigger = trigger
        self._clock = clock
        self._arrived = arrived
        self._code = ord(trigger.character)
        self.other_bytes = 0
        self.other_example = b""
        self.failure = ""  # why reading stopped before close, in words
        try:
            self._port = serial.Serial(trigger.path, trigger.baud_rate, timeout=READ_SLICE_S)
        except (serial.SerialException, OSError, ValueError) as problem:
            raise TriggerError(f"{trigger.path}: cannot open the trigger device: "
                               f"{_reason(problem)}") from None
        self._port.reset_input_buffer()
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._read, name="trigger reader", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        import serial

        while not self._closing.is_set():
            try:
                data = self._port.read(1)
                if not data:
                    continue
                at_ns = self._clock.now_ns()
                waiting = self._port.in_waiting
                if waiting:
                    data += self._port.read(waiting)
            except (serial.SerialException, OSError, TypeError) as problem:
                # TypeError: pyserial reading a port closed under it.
                if not self._closing.is_set():
                    self.failure = f"{self.trigger.path}: reading stopped: {_reason(problem)}"
                return
            for byte in data:
                if byte == self._code:
                    self._arrived(at_ns)
                else:
                    self.other_bytes += 1
                    if len(self.other_example) < 8:
                        self.other_example += bytes([byte])

    def close(self) -> None:
        self._closing.set()
        self._thread.join(timeout=5 * READ_SLICE_S + 1)
        self._port.close()


def _reason(problem: BaseException) -> str:
    number = problem.args[0] if problem.args and isinstance(problem.args[0], int) else None
    if number is not None and number in errno.errorcode:
        return os.strerror(number)
    return " ".join(str(problem).split()) or type(problem).__name__


class KeyVolumes:
    """Volumes as key presses the UI hands over (`press`), stamped when they are handed over."""

    def __init__(self, trigger: KeyTrigger, clock: Clock, arrived: Arrived):
        self.trigger = trigger
        self._clock = clock
        self._arrived = arrived
        self.failure = ""

    def press(self) -> None:
        self._arrived(self._clock.now_ns())

    def close(self) -> None:
        pass


class EmulatedVolumes:
    """A scanner that is not there: volume k is due at ``start_ns + k * tr_ns`` (k = 0, 1, ...)."""

    def __init__(self, trigger: EmulatedTrigger, start_ns: int):
        self.trigger = trigger
        self.start_ns = start_ns
        self.failure = ""
        self._next = 0  # the next volume to hand over

    def next_ns(self) -> int:
        """When the next volume is due (clock ns)."""
        return self.start_ns + self._next * self.trigger.tr_ns

    def due(self, now_ns: int) -> list[int]:
        """The arrivals of every volume due by ``now_ns`` not handed over yet (exact times)."""
        arrivals = []
        while self.next_ns() <= now_ns:
            arrivals.append(self.next_ns())
            self._next += 1
        return arrivals

    def close(self) -> None:
        pass


VolumeSource: TypeAlias = SerialVolumes | KeyVolumes | EmulatedVolumes


def open_source(trigger: Trigger, clock: Clock, arrived: Arrived) -> VolumeSource:
    """The source of ``trigger``'s volumes, open and listening from now on."""
    match trigger:
        case SerialTrigger():
            return SerialVolumes(trigger, clock, arrived)
        case KeyTrigger():
            return KeyVolumes(trigger, clock, arrived)
        case EmulatedTrigger():
            return EmulatedVolumes(trigger, clock.now_ns())
