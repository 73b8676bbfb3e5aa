"""One scanner run beside one session: wait for time zero, log every volume, lock onsets to volumes.

The session's clock keeps the time throughout: volumes only fix where its zero is and, when
onsets are locked, when a trial may start. A trigger stream that stops therefore holds
nothing up: the log marks the volumes that did not come, and a locked trial whose volume does
not come starts when the TR said it would (plus the tolerance), on the session's own clock.

Every wait looks at the stop request at least every `pinarray.stop.SLICE_NS`, so Ctrl-C, a
closed terminal or the UI's abort end a wait for the scanner like any other wait.
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable

from pinarray.clock import Clock
from pinarray.imaging.timeline import VolumeTimeline, tolerance_ns
from pinarray.imaging.triggers import (
    EmulatedVolumes,
    KeyVolumes,
    SerialVolumes,
    TriggerError,
    follows_wall_clock,
    open_source,
)
from pinarray.journal.volumes import ScannerRecord, VolumeRow, VolumeStatus
from pinarray.protocol.imaging import KeyTrigger, ScannerSync
from pinarray.stop import SLICE_NS, StopRequest
from pinarray.units import NS_PER_S


class Scanner:
    """A scanner's volumes for one run, from the moment it is opened.

    Parameters
    ----------
    sync : ScannerSync
        Trigger, dummy volumes, TR, locking, how long to wait.
    clock : Clock
        The session's clock; triggers are stamped on it.
    stop : StopRequest
        Ends any wait (`pinarray.stop.Stopped`).

    Raises
    ------
    TriggerError
        The trigger device cannot be opened, or the clock cannot stamp this trigger.
    """

    def __init__(self, sync: ScannerSync, clock: Clock, stop: StopRequest):
        self.sync = sync
        self.clock = clock
        self.stop = stop
        self.timeline = VolumeTimeline(sync.dummy_volumes, sync.tr_ns)
        self._changed = threading.Condition()
        self._first_call = True
        self._next_slot = 0  # the next counted volume a locked trial may start at
        self.gate = self if sync.lock_to_volumes else None
        self.source = open_source(sync.trigger, clock, self._arrived)
        if not isinstance(self.source, EmulatedVolumes) and not follows_wall_clock(clock):
            self.source.close()
            raise TriggerError(f"{sync.trigger.describe()}: a scanner's triggers arrive in real "
                               "time; run the simulator at --speed 1 (or use emulate:TR)")

    # -- arrivals --------------------------------------------------------------------------------

    def _arrived(self, at_ns: int) -> None:
        with self._changed:
            self.timeline.arrive(at_ns)
            self._changed.notify_all()

    def press(self) -> None:
        """A key trigger's key was pressed (the UI calls this); other triggers ignore it."""
        if isinstance(self.source, KeyVolumes):
            self.source.press()

    @property
    def listens_for_key(self) -> str | None:
        """The key whose presses are volumes, for a key trigger."""
        trigger = self.sync.trigger
        return trigger.character if isinstance(trigger, KeyTrigger) else None

    @property
    def seen(self) -> int:
        """Triggers received so far."""
        with self._changed:
            self._poll()
            return self.timeline.seen

    def _poll(self) -> None:
        if isinstance(self.source, EmulatedVolumes):
            for at_ns in self.source.due(self.clock.now_ns()):
                self.timeline.arrive(at_ns)

    def _wait(self, done: Callable[[], bool], deadline: Callable[[], int]) -> bool:
        """Wait until ``done()`` (True) or the clock passes ``deadline()`` (False)."""
        while True:
            self.stop.raise_if_requested()
            with self._changed:
                self._poll()
                if done():
                    return True
                now_ns, deadline_ns = self.clock.now_ns(), deadline()
                if now_ns >= deadline_ns:
                    return False
                wake_ns = min(deadline_ns, now_ns + SLICE_NS)
                if not isinstance(self.source, EmulatedVolumes):
                    # Stamped on a clock at the wall clock's pace: its ns are wall ns.
                    self._changed.wait((wake_ns - now_ns) / NS_PER_S)
                    continue
                wake_ns = min(wake_ns, self.source.next_ns())
            self.clock.sleep_until_ns(wake_ns)

    # -- time zero ---------------------------------------------------------------------------------

    def wait_for_time_zero(self) -> int:
        """Wait for the first counted volume; its arrival (clock ns) is the run's time zero.

        Raises
        ------
        TriggerError
            No trigger came within the wait timeout (counted from the start of the wait, then
            from each trigger), or the device failed.
        pinarray.stop.Stopped
            A stop was requested while waiting.
        """
        started_ns = self.clock.now_ns()

        def deadline() -> int:
            arrivals = self.timeline.arrivals_ns
            return max(started_ns, arrivals[-1] if arrivals else started_ns) + (
                self.sync.wait_timeout_ns)

        if not self._wait(lambda: self.timeline.zero_ns is not None or bool(self.source.failure),
                          deadline) or self.timeline.zero_ns is None:
            raise TriggerError(self._no_volume(started_ns))
        return self.timeline.zero_ns

    def _no_volume(self, started_ns: int) -> str:
        sync, seen = self.sync, self.timeline.seen
        needed = sync.dummy_volumes + 1
        waited = f"{(self.clock.now_ns() - started_ns) / NS_PER_S:.0f} s"
        text = (f"{sync.trigger.describe()}: {seen} of the {needed} volume(s) to time zero "
                f"came ({sync.dummy_volumes} dummy) in {waited} of waiting")
        if self.source.failure:
            text += f"; {self.source.failure}"
        else:
            text += f", none in the last {sync.wait_timeout_ns / NS_PER_S:g} s"
        if isinstance(self.source, SerialVolumes) and self.source.other_bytes:
            example = self.source.other_example.decode("ascii", "backslashreplace")
            return (f"{text}; {self.source.other_bytes} other byte(s) came instead "
                    f"({example!r}): is the trigger character right? No run was started.")
        return text + ". Is the scanner running? No run was started."

    @property
    def zero_event(self) -> str:
        """What the run's time zero is, in words, for the manifest and the sidecars."""
        return (f"the first counted scanner volume: trigger {self.sync.dummy_volumes + 1} from "
                f"{self.sync.trigger.describe()}, after {self.sync.dummy_volumes} dummy volume(s)")

    # -- the log -----------------------------------------------------------------------------------

    def pending_rows(self) -> list[VolumeRow]:
        """Volumes not logged yet, up to now (for `RunWriter.log_volumes`)."""
        with self._changed:
            self._poll()
            return self.timeline.rows_until(self.clock.now_ns())

    def record(self) -> ScannerRecord:
        """What the run's manifest says about this scanner."""
        tr_ns = self.sync.tr_ns
        return ScannerRecord(self.sync.trigger.describe(), self.sync.dummy_volumes, tr_ns,
                             self.sync.lock_to_volumes, None if tr_ns is None else tolerance_ns(tr_ns))

    def summary(self) -> str:
        """Volumes logged so far by status, and a device failure, in one line."""
        with self._changed:
            counts = Counter(row.status for row in self.timeline.rows)
            tr_ns = self.timeline.current_tr_ns()
        parts = [f"{counts[VolumeStatus.RECEIVED] + counts[VolumeStatus.IRREGULAR]} volume(s) "
                 f"received ({self.sync.dummy_volumes} dummy)"]
        parts += [f"{counts[status]} {status}" for status in
                  (VolumeStatus.MISSED, VolumeStatus.IRREGULAR, VolumeStatus.EXTRA)]
        if tr_ns is not None:
            parts.append(f"TR {tr_ns / NS_PER_S:.4g} s")
        text = ", ".join(parts)
        return f"{text}; {self.source.failure}" if self.source.failure else text

    # -- onsets locked to volumes ------------------------------------------------------------------

    def wait_for_onset(self, ready_ns: int) -> None:
        """Hold a trial until its volume: the first counted volume numbered a multiple of
        ``lock_to_volumes`` that comes after the trial was ready (`pinarray.session.trials.OnsetGate`).

        The first trial starts at once: it was ready before time zero. A volume whose trigger
        does not come is waited for until the TR says it was due, plus the tolerance.
        """
        every = self.sync.lock_to_volumes
        if self._first_call:
            self._first_call = False
            self._next_slot = every
            return
        tr_ns = self.timeline.current_tr_ns()
        assert tr_ns is not None, "locking needs the TR (checked with the settings)"
        with self._changed:
            self._poll()
            slot = self._next_slot
            while (at_ns := self._slot_ns(slot)) is not None and at_ns < ready_ns:
                slot += every
        self._next_slot = slot + every

        def due() -> int:
            expected_ns = self.timeline.expected_ns(slot)
            return ready_ns if expected_ns is None else expected_ns + tolerance_ns(tr_ns)

        self._wait(lambda: self.timeline.counted_volume_ns(slot) is not None, due)

    def _slot_ns(self, counted: int) -> int | None:
        arrived_ns = self.timeline.counted_volume_ns(counted)
        return arrived_ns if arrived_ns is not None else self.timeline.expected_ns(counted)

    def close(self) -> None:
        """Stop listening (a serial device is closed)."""
        self.source.close()

    def __enter__(self) -> Scanner:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
