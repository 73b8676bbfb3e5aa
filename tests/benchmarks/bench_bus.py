"""Servo bus: deadline error over a pseudo-terminal, wire use, top frame rate, pin travel."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from pinarray.bus.base import BusSetup, ServoSetup
from pinarray.bus.transport import open_bus
from pinarray.clock import MonotonicClock, VirtualClock
from pinarray.player import play_trial
from pinarray.schedule import TargetList

IDS = tuple(range(1, 17))
REST = 2048


def _setup(low: int = 1500, high: int = 2600) -> BusSetup:
    return BusSetup(tuple(ServoSetup(i, i, REST, low, high) for i in IDS), speed_steps_per_s=0)


def _full_frames(rate_hz: float, frames: int, stroke_steps: int = 40) -> TargetList:
    """Every frame moves all 16 pins (the worst case for the wire)."""
    period_ns = round(1e9 / rate_hz)
    times = np.repeat(np.arange(frames, dtype=np.int64) * period_ns, len(IDS))
    pins = np.tile(np.array(IDS, dtype=np.int16), frames)
    up = (np.arange(frames) % 2 == 0).repeat(len(IDS))
    positions = np.where(up, REST + stroke_steps, REST).astype(np.int32)
    positions[-len(IDS):] = REST
    return TargetList(times, pins, positions, end_ns=frames * period_ns + 50_000_000)


def _minimum_bytes(targets: TargetList) -> int:
    """Sync-write bytes of the goal changes alone: 8 + 3 per servo, per frame."""
    return sum(8 + 3 * len(frame.pins) for frame in targets.frames())


def deadline_over_pty() -> None:
    server = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", "--ids", "1-16"],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        path = server.stdout.readline().split(" on ")[1].split()[0]
        clock = MonotonicClock()
        bus = open_bus(path, _setup(), clock)
        print("deadline error over a pseudo-terminal (sim-serve in its own process), "
              "16 servos, every frame moves every pin, 2 s per rate")
        print(f"{'frames/s':>9} {'frames':>7} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} "
              f"{'wire B/s':>9} {'minimum B/s':>11}")
        for rate_hz in (100, 200, 500):
            targets = _full_frames(rate_hz, 2 * rate_hz)
            report = play_trial(bus, targets, clock, telemetry_interval_ns=None,
                                release_at_end=False)
            seconds = targets.end_ns / 1e9
            p50, p99, worst = (report.deadline_error_ns(p) / 1e6 for p in (50, 99, 100))
            minimum = _minimum_bytes(targets) / seconds
            print(f"{rate_hz:>9} {report.frames_sent:>7} {p50:>8.3f} {p99:>8.3f} {worst:>8.3f} "
                  f"{report.bytes_on_wire / seconds:>9.0f} {minimum:>11.0f}")
        bus.rest_and_release()
        bus.close()
    finally:
        server.terminate()
        server.wait(timeout=10)


def wire_use_of_a_sparse_schedule() -> None:
    """Changed-only writes against resending every goal each frame, in virtual time."""
    print("\nbytes on the wire per second, a wave along the bottom row (1 pin changes per "
          "frame at 40 frames/s), virtual time")
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
    print(f"{'written B/s':>12} {'read B/s':>9} {'minimum B/s':>12} {'all 16 each frame':>18}")
    print(f"{report.bytes_written / seconds:>12.0f} {report.bytes_read / seconds:>9.0f} "
          f"{_minimum_bytes(targets) / seconds:>12.0f} {everything:>18.0f}")
    print("(reads: one servo's telemetry per second while playing, all 16 at the end)")


def top_frame_rate() -> None:
    print("\nhighest full 16-servo frame rate at 1 Mbps (virtual time; 56-byte sync writes; "
          "wire limit 1786/s)")
    print(f"{'frames/s':>9} {'p99 ms':>8} {'max ms':>8}  sustained")
    best = 0
    for rate_hz in (1000, 1500, 1700, 1750, 1780, 1790, 1800, 2000):
        bus = open_bus("sim://?ids=1-16", _setup(), VirtualClock())
        report = play_trial(bus, _full_frames(rate_hz, rate_hz), bus.clock,
                            telemetry_interval_ns=None, release_at_end=False)
        worst_ns = report.deadline_error_ns(100)
        sustained = worst_ns < 1e9 / rate_hz  # lateness stays below one period: no backlog
        best = rate_hz if sustained else best
        print(f"{rate_hz:>9} {report.deadline_error_ns(99) / 1e6:>8.3f} {worst_ns / 1e6:>8.3f}  "
              f"{'yes' if sustained else 'no (falls behind)'}")
    print(f"highest sustained of those tried: {best} frames/s")


def pin_travel() -> None:
    print("\ncommanded vs simulated pin travel (one pin, 2 s, acceleration register 0, "
          "max speed 3400 step/s); steady state = last second")
    print(f"{'Hz':>4} {'commanded steps':>16} {'simulated p-p':>14} {'ratio':>6}")
    for rate_hz in (3, 5, 10):
        for stroke in (40, 150, 341):
            bus = open_bus("sim://?ids=1-16", _setup(), VirtualClock())
            servo = bus.sim.servos[1]
            half_ns = round(1e9 / rate_hz / 2)
            count = int(2 * rate_hz * 2)
            times = np.arange(count, dtype=np.int64) * half_ns
            positions = np.where(np.arange(count) % 2 == 0, REST + stroke, REST)
            targets = TargetList(times, np.ones(count, dtype=np.int16),
                                 positions.astype(np.int32), end_ns=count * half_ns)
            servo.start_recording()
            report = play_trial(bus, targets, bus.clock, telemetry_interval_ns=None,
                                release_at_end=False)
            t = np.array([s.time_ns - report.onset_ns for s in servo.trajectory])
            p = np.array([s.position_steps for s in servo.trajectory])
            window = (t >= 1e9) & (t < count * half_ns)
            travel = float(np.ptp(p[window]))
            print(f"{rate_hz:>4} {stroke:>16} {travel:>14.1f} {travel / stroke:>6.2f}")


def run() -> None:
    deadline_over_pty()
    wire_use_of_a_sparse_schedule()
    top_frame_rate()
    pin_travel()
