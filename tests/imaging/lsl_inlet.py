"""An independent LSL inlet, as LabRecorder would open one: it finds the stream by name and
keeps every marker with its timestamp. On 127.0.0.1 only (``tests/lsl_local.py``)."""

import json
import threading
import uuid

import pylsl


def unique_stream_name() -> str:
    """A stream name no other test (or helper on this machine) uses at the same time."""
    return f"pinarray-test-{uuid.uuid4().hex[:12]}"


class MarkerInlet:
    """Resolves ``name`` in a thread and keeps ``(payload dict, timestamp s)`` until ``count``
    markers came, or ``quiet_s`` passed with none after the first (then `join` says so);
    ``arrivals`` holds when each came, on LSL's clock (s)."""

    def __init__(self, name: str, count: int, resolve_s: float = 60.0, quiet_s: float = 30.0):
        self.name, self.count = name, count
        self.resolve_s, self.quiet_s = resolve_s, quiet_s
        self.markers: list[tuple[dict, float]] = []
        self.arrivals: list[float] = []
        self.info: pylsl.StreamInfo | None = None
        self.found = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        streams = pylsl.resolve_byprop("name", self.name, timeout=self.resolve_s)
        if not streams:
            return
        inlet = pylsl.StreamInlet(streams[0])
        self.info = inlet.info(timeout=10)
        inlet.open_stream(timeout=10)
        self.found.set()
        while len(self.markers) < self.count:
            sample, stamp = inlet.pull_sample(timeout=self.quiet_s)
            if sample is None:
                break
            self.arrivals.append(pylsl.local_clock())
            self.markers.append((json.loads(sample[0]), stamp))
        inlet.close_stream()

    def join(self, timeout_s: float = 120.0) -> list[tuple[dict, float]]:
        self._thread.join(timeout_s)
        return self.markers
