"""Servo bus timing measured where the servo receives it, beside a minimal reference loop.

Every lateness figure here is taken at the receiving end of a pseudo-terminal: `pinarray
sim-serve --arrivals` runs in its own process and timestamps each instruction packet as it
arrives; a frame's lateness is its sync write's arrival minus ``onset + scheduled time``. The
reference is `tests.benchmarks.reference_loop` (prebuilt packets, absolute deadlines, sleep
then spin, one write each), in a process of its own with the same priority, timed by the same
receiver in the same run, interleaved with the player in chunks so that a noisy neighbour
slows both alike. ``PINARRAY_BENCH_SECONDS`` (default 20) sets the seconds per rate.
"""

from __future__ import annotations

import asyncio
import os
import pickle
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pinarray.clock import MonotonicClock, VirtualClock
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.transport import open_bus
from pinarray.player.child import REALTIME_PRIORITY
from pinarray.player.playback import DEFAULT_LEAD_NS, play_trial, prepare_trial
from pinarray.player.process import SPIN_NS, PlayerDied, PlayerProcess
from pinarray.schedule import TargetList
from pinarray.stop import StopRequest

IDS = tuple(range(1, 17))
REST = 2048
STROKE = 40
SECONDS = float(os.environ.get("PINARRAY_BENCH_SECONDS", "20"))
CHUNKS = 4
RATES = (100, 200, 500)
TOLERANCE_NS = 10_000_000
RECEIVER_PRIORITY = REALTIME_PRIORITY + 10
# A bring-up lowers the servos' return delay from the factory 500 us (`pinarray servos`).
RETURN_DELAY_US = 100


def _setup() -> BusSetup:
    return BusSetup(tuple(ServoSetup(i, i, REST, REST - 200, REST + 200) for i in IDS),
                    speed_steps_per_s=0)


def wave(rate_hz: int, seconds: float) -> TargetList:
    """A wave over the 16 pins: each frame lifts one pin and lowers the one lifted 8 before."""
    period_ns = 1_000_000_000 // rate_hz
    frames = int(seconds * rate_hz)
    times, pins, positions = [], [], []
    for k in range(frames):
        times.append(k * period_ns)
        pins.append(IDS[k % 16])
        positions.append(REST + STROKE if (k // 16) % 2 == 0 else REST)
    # everything back at rest one period after the last frame
    end_ns = frames * period_ns
    for pin in IDS:
        times.append(end_ns)
        pins.append(pin)
        positions.append(REST)
    order = np.lexsort((pins, times))
    targets = TargetList(np.array(times, dtype=np.int64)[order],
                         np.array(pins, dtype=np.int16)[order],
                         np.array(positions, dtype=np.int32)[order], end_ns=end_ns)
    # keep changes only (a pin already at rest is not lowered again)
    keep, last = [], {}
    for i in range(len(targets)):
        pin, position = int(targets.pin[i]), int(targets.position_steps[i])
        if last.get(pin, REST) != position:
            keep.append(i)
            last[pin] = position
    return TargetList(targets.time_ns[keep], targets.pin[keep], targets.position_steps[keep],
                      end_ns=end_ns + 50_000_000)


class Receiver:
    """`pinarray sim-serve` in its own process, logging every packet's arrival."""

    def __init__(self, folder: Path):
        self.log = folder / f"arrivals-{time.monotonic_ns()}.tsv"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "pinarray", "sim-serve", "--ids", "1-16", "--faults",
             f"return_delay_us={RETURN_DELAY_US}", "--arrivals", str(self.log)],
            stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.path = self.process.stdout.readline().split(" on ")[1].split()[0]
        try:
            # A servo has no scheduler: at real-time priority above the player's, the receiver
            # reads each packet when it arrives, so what it logs is the sender's lateness.
            os.sched_setscheduler(self.process.pid, os.SCHED_FIFO, os.sched_param(RECEIVER_PRIORITY))
            self.realtime = True
        except (AttributeError, OSError):
            self.realtime = False

    def arrivals(self) -> list[tuple[int, str, str]]:
        """(arrival_ns, instruction, data_hex) of every packet, once the server stopped."""
        self.process.send_signal(signal.SIGTERM)
        self.process.communicate(timeout=30)
        rows = self.log.read_text().splitlines()[1:]
        out = []
        for row in rows:
            arrival, _servo, instruction, _address, data, delivered = row.split("\t")
            if delivered == "1":
                out.append((int(arrival), instruction, data))
        return out


def frame_lateness_ns(arrivals, onset_ns: int, trial) -> np.ndarray:
    """Each frame's lateness at the servo: its sync write's arrival minus its deadline."""
    expected = [frame.packet[6:-1].hex() for frame in trial.frames]
    # A frame cannot reach the servo before its deadline: earlier sync writes are someone else's.
    syncs = [(at, data) for at, instruction, data in arrivals
             if instruction == "SYNC_WRITE" and at >= onset_ns]
    lateness = []
    for frame, wanted, (at, data) in zip(trial.frames, expected, syncs, strict=False):
        assert data == wanted, "a frame arrived out of order or altered"
        lateness.append(at - (onset_ns + frame.time_ns))
    assert len(lateness) == len(trial.frames), f"{len(trial.frames) - len(lateness)} frames never arrived"
    return np.array(lateness, dtype=np.int64)


def run_reference(path: str, trial, realtime: bool, folder: Path) -> int:
    plan = folder / "plan.pickle"
    with open(plan, "wb") as stream:
        pickle.dump(([f.time_ns for f in trial.frames], [f.packet for f in trial.frames],
                     DEFAULT_LEAD_NS, SPIN_NS), stream)
    args = [sys.executable, "-m", "tests.benchmarks.reference_loop", path, str(plan)]
    done = subprocess.run(args + (["--realtime"] if realtime else []), capture_output=True,
                          text=True, check=True)
    return int(done.stdout.split()[0])


@dataclass
class Sample:
    lateness_ns: list[np.ndarray]
    chunk_p99_ns: list[int]
    bytes_written: int = 0
    bytes_read: int = 0
    goal_bytes: int = 0
    not_delivered: int = 0
    problems: list[str] = field(default_factory=list)

    def add(self, lateness: np.ndarray) -> None:
        self.lateness_ns.append(lateness)
        self.chunk_p99_ns.append(int(np.percentile(lateness, 99, method="higher")))

    def pooled(self) -> np.ndarray:
        return np.concatenate(self.lateness_ns)


def measure(rate_hz: int, realtime: bool, folder: Path, redraw=None,
            chunks: int = CHUNKS) -> tuple[Sample, Sample]:
    """Reference and player, ``chunks`` interleaved chunks of ``SECONDS / CHUNKS`` each."""
    reference, ours = Sample([], []), Sample([], [])
    targets = wave(rate_hz, SECONDS / CHUNKS)
    for _ in range(chunks):
        receiver = Receiver(folder)
        try:
            bus = open_bus(receiver.path, _setup(), MonotonicClock())
            player = PlayerProcess(bus, bus.link.wire.fd, StopRequest(), realtime=realtime)
            try:
                trial = prepare_trial(bus, targets)
                # The reference runs under the same load as the player (a redrawing UI too).
                reference_onset, report = (redraw or (lambda call: call()))(
                    lambda player=player, trial=trial, path=receiver.path: (
                        run_reference(path, trial, realtime, folder),
                        player.play(trial, tolerance_ns=TOLERANCE_NS)))
            finally:
                player.close()
                bus.rest_and_release()
                bus.close()
        finally:
            arrivals = receiver.arrivals()  # stops the receiver whatever happened
        reference.add(frame_lateness_ns(arrivals, reference_onset, trial))
        ours.add(frame_lateness_ns(arrivals, report.onset_ns, trial))
        ours.bytes_written += report.bytes_written
        ours.bytes_read += report.bytes_read
        ours.goal_bytes += sum(len(f.packet) for f in trial.frames)
        if not report.delivery.delivered:
            ours.not_delivered += 1
            ours.problems.append(report.delivery.problem)
    return reference, ours


def _ms(ns) -> str:
    return f"{ns / 1e6:7.3f}"


def _quantiles(lateness: np.ndarray) -> str:
    return " ".join(_ms(np.percentile(lateness, q, method="higher")) for q in (50, 99, 100))


def _table_row(label: str, rate: int, reference: Sample, ours: Sample) -> str:
    ref, mine = reference.pooled(), ours.pooled()
    ratio99 = np.percentile(mine, 99) / max(1.0, np.percentile(ref, 99))
    spread = " ".join(_ms(v) for v in (min(ours.chunk_p99_ns), statistics.median(ours.chunk_p99_ns),
                                        max(ours.chunk_p99_ns)))
    return (f"{label:<22} {rate:>5} {len(mine):>6}  {_quantiles(ref)}  {_quantiles(mine)}  "
            f"{ratio99:5.2f}x  {spread}  {ours.not_delivered:>3}/{CHUNKS}")


HEADER = (f"{'variant':<22} {'fps':>5} {'frames':>6}  {'reference p50/p99/max ms':^23}  "
          f"{'player p50/p99/max ms':^23}  {'p99':>6}  {'player p99 min/med/max':^23}  "
          "not delivered")


def receiver_side_lateness(folder: Path) -> dict:
    print(f"lateness of each frame at the receiving end of a pseudo-terminal (sim-serve in its "
          f"own process), {SECONDS:g} s per rate in {CHUNKS} interleaved chunks; a wave over 16 "
          f"pins, one goal change per frame; read-back of every change on (player)")
    print(HEADER)
    results = {}
    for realtime in (True, False):
        for rate in RATES:
            reference, ours = measure(rate, realtime, folder)
            label = "real-time priority" if realtime else "normal priority"
            print(_table_row(label, rate, reference, ours), flush=True)
            results[(realtime, rate)] = (reference, ours)
    _reasons(results.values())
    return results


def _reasons(samples) -> None:
    problems = [p for _, ours in samples for p in ours.problems]
    for problem in problems[:5]:
        print(f"  not delivered: {problem}")


class Redrawing:
    """A Textual app in this process redrawing the pin grid at the run screen's rate."""

    def __call__(self, call):
        from textual.app import App

        from pinarray.grid import Grid
        from pinarray.tui.pin_grid import PinGrid
        from pinarray.tui.run_screen import GRID_FPS

        result = {}

        class Busy(App):
            def compose(self):
                yield PinGrid(Grid(), used=IDS)

            def on_mount(self):
                self.set_interval(1 / GRID_FPS, self._redraw)

            def _redraw(self):
                lifted = frozenset(random.sample(IDS, 4))
                for grid in self.query(PinGrid):  # none while the app tears down
                    grid.show(lifted=lifted, active=lifted)

        async def drive():
            app = Busy()
            async with app.run_test(headless=True, size=(80, 24)):
                result["report"] = await asyncio.to_thread(call)

        asyncio.run(drive())
        return result["report"]


def _merge(into: Sample, chunk: Sample) -> None:
    into.lateness_ns += chunk.lateness_ns
    into.chunk_p99_ns += chunk.chunk_p99_ns
    into.not_delivered += chunk.not_delivered
    into.problems += chunk.problems


def tui_redrawing(folder: Path) -> None:
    print("\nthe same with the experimenter UI redrawing the pin grid in the parent process "
          "(real-time priority), in chunks alternating with quiet ones so that a noisy "
          "neighbour weighs on both alike; change of the player's p99 against the quiet chunks")
    print(HEADER + "  player p99 change")
    samples = []
    for rate in RATES:
        reference, ours, quiet = Sample([], []), Sample([], []), Sample([], [])
        for _ in range(CHUNKS):
            _, quiet_chunk = measure(rate, True, folder, chunks=1)
            reference_chunk, ours_chunk = measure(rate, True, folder, redraw=Redrawing(),
                                                  chunks=1)
            _merge(quiet, quiet_chunk)
            _merge(reference, reference_chunk)
            _merge(ours, ours_chunk)
        samples.append((reference, ours))
        change = (np.percentile(ours.pooled(), 99) / np.percentile(quiet.pooled(), 99) - 1)
        print(_table_row("UI redrawing", rate, reference, ours) + f"  {change * 100:+6.1f} %",
              flush=True)
    _reasons(samples)


def verification_bytes(results: dict) -> None:
    print("\nbytes on the wire: the player's writes and reads (read-backs included) against the "
          "goal writes alone")
    print(f"{'fps':>5} {'goal writes B':>14} {'player wrote B':>15} {'player read B':>14} "
          f"{'total / goal writes':>20}")
    for rate in RATES:
        _, ours = results[(True, rate)]
        total = ours.bytes_written + ours.bytes_read
        print(f"{rate:>5} {ours.goal_bytes:>14} {ours.bytes_written:>15} {ours.bytes_read:>14} "
              f"{total / ours.goal_bytes:>19.2f}x")


def noticing_a_dead_player(folder: Path, tries: int = 10) -> None:
    print(f"\nhow soon the parent notices its player process killed mid-trial (SIGKILL at a "
          f"random moment), {tries} tries; reference: the parent's watch interval; goal 100 ms")
    noticed = []
    for attempt in range(tries):
        receiver = Receiver(folder)
        try:
            bus = open_bus(receiver.path, _setup(), MonotonicClock())
        except BaseException:
            receiver.arrivals()
            raise
        player = PlayerProcess(bus, bus.link.wire.fd, StopRequest())
        trial = prepare_trial(bus, wave(100, 10))
        killed_at = []

        def kill(pid=player.process.pid, killed_at=killed_at):
            killed_at.append(time.monotonic_ns())
            os.kill(pid, signal.SIGKILL)

        threading.Timer(0.3 + random.Random(attempt).random() * 0.5, kill).start()
        try:
            player.play(trial, tolerance_ns=TOLERANCE_NS)
        except PlayerDied as died:
            noticed.append((died.noticed_ns - killed_at[0]) / 1e9)
        finally:
            player.close()
            bus.close()
            receiver.arrivals()  # stops the receiver
    from pinarray.player.process import WATCH_S

    times = sorted(noticed)
    print(f"{'min ms':>8} {'median ms':>10} {'max ms':>8} {'watch interval ms':>18} "
          f"(then the parent rests and releases the pins through its own port)")
    print(f"{times[0] * 1e3:>8.1f} {statistics.median(times) * 1e3:>10.1f} "
          f"{times[-1] * 1e3:>8.1f} {WATCH_S * 1e3:>18.1f}")


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def spin_thresholds(seconds: float = 2.0) -> None:
    print(f"\nwake-up lateness of the player process by spin threshold (sleep until this close "
          f"to the deadline, then spin), deadlines every 1 ms for {seconds:g} s, real-time "
          f"priority; CPU the process used per second of waiting")
    print(f"{'spin us':>8} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} {'CPU s/s':>8}")
    for spin_ns in (0, 20_000, 50_000, 100_000, 200_000, 500_000):
        player = PlayerProcess(None, None, StopRequest(), spin_ns=spin_ns)
        try:
            before = _cpu_s(player.process.pid)
            lateness = np.array(player.measure_wake_ups(int(seconds * 1e9), 1_000_000))
            cpu = (_cpu_s(player.process.pid) - before) / seconds
        finally:
            player.close()
        print(f"{spin_ns // 1000:>8} {_quantiles(lateness)} {cpu:>8.2f}"
              + ("   <- the player's" if spin_ns == SPIN_NS else ""))


def _minimum_bytes(targets: TargetList) -> int:
    """Sync-write bytes of the goal changes alone: 8 + 3 per servo, per frame."""
    return sum(8 + 3 * len(frame.pins) for frame in targets.frames())


def wire_use_of_a_sparse_schedule() -> None:
    """Changed-only writes and read-backs against resending every goal each frame."""
    print("\nbytes on the wire per second, a wave along the bottom row (1 pin changes per "
          "frame at 40 frames/s), virtual time, every change read back")
    changes = []
    for k in range(400):
        pin = 1 + k % 4
        changes.append((k * 25_000_000, pin, REST + 40 if (k // 4) % 2 == 0 else REST))
    times, pins, positions = (np.array(c) for c in zip(*changes, strict=True))
    targets = TargetList(times.astype(np.int64), pins.astype(np.int16),
                         positions.astype(np.int32), end_ns=10_100_000_000)
    bus = open_bus("sim://?ids=1-16", _setup(), VirtualClock())
    report = play_trial(bus, targets, bus.clock, release_at_end=False)
    seconds = targets.end_ns / 1e9
    everything = len(report.sent_ns) * 56 / seconds
    print(f"{'written B/s':>12} {'read B/s':>9} {'goal writes B/s':>16} {'all 16 each frame':>18}")
    print(f"{report.bytes_written / seconds:>12.0f} {report.bytes_read / seconds:>9.0f} "
          f"{_minimum_bytes(targets) / seconds:>16.0f} {everything:>18.0f}")


def top_frame_rate() -> None:
    print("\nhighest full 16-servo frame rate at 1 Mbps (virtual time; 56-byte sync writes; "
          "wire limit 1786/s): the lateness of the last frame as it reaches its servos")
    print(f"{'frames/s':>9} {'latest ms':>10}  sustained")
    best = 0
    for rate_hz in (1000, 1500, 1700, 1750, 1780, 1790, 1800, 2000):
        period_ns = round(1e9 / rate_hz)
        frames = rate_hz
        times = np.repeat(np.arange(frames, dtype=np.int64) * period_ns, 16)
        pins = np.tile(np.array(IDS, dtype=np.int16), frames)
        up = (np.arange(frames) % 2 == 0).repeat(16)
        positions = np.where(up, REST + 40, REST).astype(np.int32)
        positions[-16:] = REST
        targets = TargetList(times, pins, positions, end_ns=frames * period_ns + 50_000_000)
        bus = open_bus("sim://?ids=1-16", _setup(), VirtualClock())
        report = play_trial(bus, targets, bus.clock, release_at_end=False)
        latest_ns = report.delivery.worst_lateness_ns
        sustained = latest_ns < period_ns + 600_000  # one frame's wire time: no backlog
        best = rate_hz if sustained else best
        print(f"{rate_hz:>9} {latest_ns / 1e6:>10.3f}  {'yes' if sustained else 'no (falls behind)'}")
    print(f"highest sustained of those tried: {best} frames/s")


def run() -> None:
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        results = receiver_side_lateness(folder)
        tui_redrawing(folder)
        verification_bytes(results)
        noticing_a_dead_player(folder)
        spin_thresholds()
    wire_use_of_a_sparse_schedule()
    top_frame_rate()
