"""Simulated servos behind a pseudo-terminal, usable as if they were ``/dev/ttyUSB0``.

Any client (the SDK's own examples, another program, ``pinarray play --port``) opens the
printed path with pyserial. The servos' motion runs in real time. A pseudo-terminal has no
baud rate, so answers are written as soon as they are computed; wire time at 1 Mbps is
charged only by the in-process `SimSerial`.
"""

from __future__ import annotations

import os
import select
import threading
import tty

from pinarray.bus.faults import SimConfig
from pinarray.bus.sim import SimBus
from pinarray.clock import Clock, MonotonicClock

POLL_S = 0.05


class PtyServer:
    """A `SimBus` answering on a pseudo-terminal until `stop` is called.

    Parameters
    ----------
    config : SimConfig
        Servo ids, return delay and faults.
    clock : Clock, optional
        Real time by default; the servos' motion is integrated against it.
    """

    def __init__(self, config: SimConfig, clock: Clock | None = None):
        self.sim = SimBus(config, clock or MonotonicClock())
        self._controller, self._device = os.openpty()
        # Raw mode: no echo, no CR/LF translation, every byte passes through untouched.
        tty.setraw(self._device)
        tty.setraw(self._controller)
        self.path = os.ttyname(self._device)
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None

    def serve_forever(self) -> None:
        """Answer instruction packets until `stop` (or until a ``vanish_after`` fault fires)."""
        clock = self.sim.clock
        try:
            while not self._stopping.is_set():
                ready, _, _ = select.select([self._controller], [], [], POLL_S)
                if not ready:
                    continue
                try:
                    data = os.read(self._controller, 4096)
                except OSError:
                    continue  # no client attached right now
                for reply in self.sim.receive(data, clock.now_ns()):
                    os.write(self._controller, reply.packet)
                if self.sim.vanished:
                    break  # the "USB adapter" is pulled: clients see I/O errors
        finally:
            self._close()

    def start(self) -> PtyServer:
        """Serve from a background thread (for tests and benchmarks)."""
        self._thread = threading.Thread(target=self.serve_forever, name="sim-pty", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stopping.set()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def _close(self) -> None:
        for fd in (self._controller, self._device):
            try:
                os.close(fd)
            except OSError:
                pass
