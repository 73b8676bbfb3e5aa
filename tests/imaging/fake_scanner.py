"""A scanner's trigger converter on a pseudo-terminal: one byte per volume at a set TR.

The bytes are written at absolute deadlines (``start + delay + k * TR``), so the TR does not
drift, and the moment each write began is kept (``time.monotonic_ns``, the clock pinarray
stamps on).
"""

import os
import threading
import time
import tty
from contextlib import contextmanager

NS = 1_000_000_000


class FakeScanner:
    """``volumes`` triggers ``character`` every ``tr_s`` after ``delay_s``; `path` to open.

    ``stop_after`` volumes, the stream stops (the converter goes quiet, the device stays).
    """

    def __init__(self, tr_s: float, delay_s: float = 0.5, volumes: int = 10_000,
                 character: bytes = b"5", stop_after: int | None = None):
        self.tr_ns = round(tr_s * NS)
        self.delay_ns = round(delay_s * NS)
        self.volumes = volumes if stop_after is None else min(volumes, stop_after)
        self.character = character
        self._controller, self._device = os.openpty()
        tty.setraw(self._controller)
        tty.setraw(self._device)
        self.path = os.ttyname(self._device)
        self.written_ns: list[int] = []
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> "FakeScanner":
        self.start_ns = time.monotonic_ns()
        self._thread.start()
        return self

    def _run(self) -> None:
        for k in range(self.volumes):
            due_ns = self.start_ns + self.delay_ns + k * self.tr_ns
            while (left := due_ns - time.monotonic_ns()) > 0:
                if self._stopping.wait(min(left / NS, 0.05)):
                    return
            # Stamped before the write: a reader may take the byte and stamp it before this
            # thread runs again.
            self.written_ns.append(time.monotonic_ns())
            os.write(self._controller, self.character)

    def send(self, data: bytes) -> None:
        os.write(self._controller, data)

    def stop(self) -> None:
        self._stopping.set()
        if self._thread.is_alive():
            self._thread.join(5)
        os.close(self._controller)
        os.close(self._device)


@contextmanager
def fake_scanner(*args, **kwargs):
    scanner = FakeScanner(*args, **kwargs)
    try:
        yield scanner
    finally:
        scanner.stop()
