"""Scanner triggers to onsets, and LSL markers against the schedule, beside bare references.

Each round runs `pinarray batch` as a lab would (``--trigger serial:PTY --dummy-volumes 1
--lsl``) on a short protocol, twice: on the simulator at --time-scale 1 (trials play in batch's
own process) and on simulated servos behind a pseudo-terminal (``pinarray sim-serve``, then
``--port``: trials play in the player process, as on real servos), with `FakeScanner` writing
one ``5`` per volume on a pseudo-terminal and an independent LSL inlet in this process. In the
same round, the references: a bare reader (a thread blocked in ``os.read`` on another pty,
stamping each byte) for the same trigger bytes, and a bare pylsl outlet/inlet pair for marker
delivery. All times are CLOCK_MONOTONIC, which is also LSL's clock on Linux.

Figures (ms unless said):

- trigger -> stamp: a trigger's arrival as pinarray logged it minus when the scanner wrote it;
- trigger -> first onset: trial 1's onset (the schedule's, as the LSL marker says) minus the
  write of the first counted volume's trigger: what the subject waits after time zero;
- marker vs schedule (us): each marker's LSL stamp minus (time zero + the onset or end that
  events.tsv gives): how far the markers stray from the schedule's time base;
- onset marker delivery: when the inlet got an onset marker minus its stamp, the schedule's
  onset: how long after a stimulus starts an online reader knows of it (issue 27's target:
  within 2 ms), in batch's process and from the player process;
- offset marker delivery: the same for the offset markers, stamped at the stimulus's end.

``PINARRAY_BENCH_SECONDS`` (default 20) sets roughly how long the rounds take.
"""

from __future__ import annotations

import csv
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

from tests.lsl_local import keep_lsl_on_this_machine

NS = 1_000_000_000
SECONDS = float(os.environ.get("PINARRAY_BENCH_SECONDS", "20"))
ROUND_SECONDS = 4.0  # one batch round (about 5 s: start-up, handshake, wait, four trials)
TR_S = 0.2
REPO = Path(__file__).resolve().parents[2]

PROTOCOL = """\
protocol: bench_imaging
description: Four pins, 0.3 s each.
stimuli:
  buzz: {frequency_hz: 10, duration_s: 0.3, pulse_width_ms: {up: 2.0, down: 1.5}}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 6, 11, 16]
  frequencies_hz: [10]
  order: sequential
  inter_trial_interval_s: 0.2
"""


def _tsv(path: Path) -> list[dict]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file, delimiter="\t"))


def _bare_reader_round(volumes: int) -> list[float]:
    """The reference for trigger arrival: write a byte, a blocked reader thread stamps it (s)."""
    from tests.imaging.fake_scanner import FakeScanner

    scanner = FakeScanner(TR_S, delay_s=0.05, volumes=volumes)
    stamps: list[int] = []
    device = os.open(scanner.path, os.O_RDONLY | os.O_NOCTTY)
    tty.setraw(device)

    def read() -> None:
        while len(stamps) < volumes:
            data = os.read(device, 64)
            now = time.monotonic_ns()
            stamps.extend([now] * len(data))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    scanner.start()
    reader.join(volumes * TR_S + 10)
    scanner.stop()
    os.close(device)
    return [(s - w) / NS for s, w in zip(stamps, scanner.written_ns, strict=False)]


def _bare_lsl_round(pylsl, count: int) -> list[float]:
    """The reference for marker delivery: a bare pylsl outlet pushes, an inlet pulls (s)."""
    name = f"bench-bare-{os.getpid()}-{time.monotonic_ns()}"
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, "Markers", 1, 0, "string", name))
    (info,) = pylsl.resolve_byprop("name", name, timeout=30)
    inlet = pylsl.StreamInlet(info)
    inlet.open_stream(timeout=10)
    delays = []
    for k in range(count):
        time.sleep(0.01)
        outlet.push_sample([str(k)], pylsl.local_clock())
        _, stamp = inlet.pull_sample(timeout=10)
        delays.append(pylsl.local_clock() - stamp)
    inlet.close_stream()
    del outlet
    return delays


def _servos_on_a_pty() -> tuple[subprocess.Popen, str]:
    """``pinarray sim-serve`` in a process of its own, and its pseudo-terminal's path."""
    server = subprocess.Popen([sys.executable, "-m", "pinarray", "sim-serve"], cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = server.stdout.readline()
    if " on " not in line:
        server.kill()
        raise RuntimeError(f"sim-serve did not start: {line}{server.communicate()}")
    return server, line.split(" on ", 1)[1].split()[0]


def _pinarray_round(pylsl, protocol: Path, root: Path, port: str | None = None
                    ) -> dict[str, list[float]]:
    from tests.imaging.fake_scanner import FakeScanner
    from tests.imaging.lsl_inlet import unique_stream_name

    name = unique_stream_name()
    scanner = FakeScanner(TR_S, delay_s=0.1)
    bus = ["--port", port] if port else []
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "batch", str(protocol), "--subject", "bench",
         "--observer", "default", "--results", str(root), "--time-scale", "1", *bus,
         "--trigger", f"serial:{scanner.path}", "--dummy-volumes", "1", "--lsl", name],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        while "waiting for the scanner" not in (line := process.stderr.readline()):
            if not line:
                raise RuntimeError(f"batch ended before waiting: {process.communicate()}")
        (info,) = pylsl.resolve_byprop("name", name, timeout=30)
        inlet = pylsl.StreamInlet(info)
        inlet.open_stream(timeout=10)
        scanner.start()
        markers = []
        while len(markers) < 8:
            sample, stamp = inlet.pull_sample(timeout=30)
            if sample is None:
                raise RuntimeError("markers stopped coming")
            markers.append((sample[0], stamp, pylsl.local_clock()))
        out, err = process.communicate(timeout=60)
        if process.returncode != 0:
            raise RuntimeError(err)
    finally:
        if process.poll() is None:
            process.kill()
        scanner.stop()
    (events_path,) = root.rglob("*bench*_events.tsv")
    (volumes_path,) = root.rglob("*bench*_volumes.tsv")
    events, volumes = _tsv(events_path), _tsv(volumes_path)
    for path in root.rglob("*"):  # the next round starts a fresh dataset
        if path.is_file():
            path.unlink()
    onsets = [float(e["onset"]) for e in events]
    ends = [o + float(e["duration"]) for o, e in zip(onsets, events, strict=True)]
    zero_s = markers[0][1] - onsets[0]
    scheduled = [t for pair in zip(onsets, ends, strict=True) for t in pair]
    written = scanner.written_ns
    arrivals = [(zero_s + float(v["onset"]) - written[int(v["volume"]) - 1] / NS)
                for v in volumes if v["status"] in ("received", "irregular")
                and int(v["volume"]) <= len(written)]
    return {
        "trigger -> stamp": arrivals,
        "trigger -> first onset": [markers[0][1] - written[1] / NS],
        "marker vs schedule": [stamp - (zero_s + t)
                               for (_, stamp, _), t in zip(markers, scheduled, strict=True)],
        "onset marker delivery": [got - stamp for _, stamp, got in markers[0::2]],
        "offset marker delivery": [got - stamp for _, stamp, got in markers[1::2]],
    }


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def _row(name: str, rounds: list[list[float]], scale: float, reference: list[list[float]] | None):
    pooled = [v for r in rounds for v in r]
    medians = [statistics.median(r) for r in rounds]
    cells = " ".join(f"{x * scale:>9.3f}" for x in (min(medians), statistics.median(medians),
                                                     max(medians), _pct(pooled, 0.5),
                                                     _pct(pooled, 0.99)))
    ratio = "-"
    if reference is not None:
        ref = statistics.median(v for r in reference for v in r)
        ratio = f"{statistics.median(pooled) / ref:.1f}x" if ref > 0 else "-"
    print(f"{name:<38} {cells} {ratio:>8}")


def run() -> None:
    keep_lsl_on_this_machine()  # before the first pylsl call, for this process and batch's
    import pylsl

    rounds = max(5, round(SECONDS / ROUND_SECONDS))
    figures: dict[str, list[list[float]]] = {}
    bare_reader: list[list[float]] = []
    bare_lsl: list[list[float]] = []
    player: dict[str, list[list[float]]] = {}
    server, port = _servos_on_a_pty()
    try:
        with tempfile.TemporaryDirectory(prefix="pinarray-bench-sync-") as folder:
            protocol = Path(folder) / "bench_imaging.yaml"
            protocol.write_text(PROTOCOL)
            root = Path(folder) / "results"
            for _ in range(rounds):  # interleaved: a noisy neighbour slows all alike
                for name, values in _pinarray_round(pylsl, protocol, root).items():
                    figures.setdefault(name, []).append(values)
                for name, values in _pinarray_round(pylsl, protocol, root, port).items():
                    player.setdefault(name, []).append(values)
                bare_reader.append(_bare_reader_round(10))
                bare_lsl.append(_bare_lsl_round(pylsl, 8))
    finally:
        server.terminate()
        server.communicate(timeout=30)
    print(f"{rounds} rounds of 4 trials, TR {TR_S} s, 1 dummy volume; min/median/max of the "
          "rounds' medians, p50/p99 of all samples")
    print(f"{'':<38} {'min':>9} {'median':>9} {'max':>9} {'p50':>9} {'p99':>9} {'ratio':>8}")
    _row("bare reader: trigger -> read (ms)", bare_reader, 1e3, None)
    _row("pinarray: trigger -> stamp (ms)", figures["trigger -> stamp"], 1e3, bare_reader)
    _row("pinarray: trigger -> 1st onset (ms)", figures["trigger -> first onset"], 1e3,
         bare_reader)
    _row("pinarray: marker vs schedule (us)", figures["marker vs schedule"], 1e6, None)
    _row("player process: marker vs sched (us)", player["marker vs schedule"], 1e6, None)
    _row("bare pylsl: marker delivery (ms)", bare_lsl, 1e3, None)
    _row("in process: onset -> inlet (ms)", figures["onset marker delivery"], 1e3, bare_lsl)
    _row("player process: onset -> inlet (ms)", player["onset marker delivery"], 1e3, bare_lsl)
    _row("in process: offset -> inlet (ms)", figures["offset marker delivery"], 1e3, bare_lsl)
    _row("player process: offset -> inlet (ms)", player["offset marker delivery"], 1e3,
         bare_lsl)
    for where, found in (("in process", figures), ("player process", player)):
        onsets = [v for r in found["onset marker delivery"] for v in r]
        print(f"{where}: onset -> inlet over all {len(onsets)} markers: min "
              f"{min(onsets) * 1e3:.3f}, median {statistics.median(onsets) * 1e3:.3f}, max "
              f"{max(onsets) * 1e3:.3f} ms (target: within 2 ms of the onset)")
    print("ratio: pinarray's median over the bare reference's median in the same rounds; "
          "marker vs schedule is an error, its reference is 0")
