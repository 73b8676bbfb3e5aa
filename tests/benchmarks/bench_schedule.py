"""Run time against timing error: the exact event compiler vs dense sampling, and how the
compiler's cost grows with duration, active pins and array size."""

import time
from fractions import Fraction

import numpy as np

from pinarray.grid import Grid
from pinarray.protocol import NS_PER_S, Device, PinCalibration, PinDrive, ServoSettings, Train
from pinarray.schedule import compile_drives, render_dense


def _device(size: int = 4) -> Device:
    grid = Grid(size, size)
    pins = tuple(
        PinCalibration(p, p, 2048, 2000, 2200, ((1_500_000, 2048), (2_000_000, 2162)))
        for p in grid.pins
    )
    return Device(grid, ServoSettings(), pins)


def _seconds(action, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        started = time.perf_counter()
        action()
        best = min(best, time.perf_counter() - started)
    return best


def _edge_error_ns(schedule, pin: int, rate_hz: int) -> int:
    dense = render_dense(schedule.pulses, [pin], rate_hz, schedule.end_ns)[0]
    rising = np.flatnonzero(np.diff(dense.astype(np.int8)) == 1) + 1
    if dense[0]:
        rising = np.concatenate(([0], rising))
    starts = schedule.pulses.start_ns[schedule.pulses.pin == pin]
    return int(np.max(rising * (NS_PER_S // rate_hz) - starts))


def run() -> None:
    device = _device()
    train = Train(
        Fraction(7), 10 * NS_PER_S
    )  # 70 pulses/s: a 14.285714... ms slot no sample grid hits
    for label, pins in (("1 pin", [1]), ("16 pins", list(range(1, 17)))):
        drives = [PinDrive(p, train) for p in pins]
        schedule = compile_drives(drives, device)
        print(f"\n10 s seed train at 7 Hz, {label}: {len(schedule.pulses)} pulses")
        print(f"{'method':<22} {'time (ms)':>10} {'max edge error':>16}")
        print(
            f"{'exact events':<22} {_seconds(lambda d=drives: compile_drives(d, device)) * 1e3:>10.2f} {'0 ns':>16}"
        )
        for rate_hz in (1_000, 10_000, 100_000):
            cost = _seconds(
                lambda r=rate_hz, s=schedule, p=pins: render_dense(s.pulses, p, r, s.end_ns)
            )
            error_ns = _edge_error_ns(schedule, pins[0], rate_hz)
            print(
                f"{f'dense {rate_hz // 1000} kHz':<22} {cost * 1e3:>10.2f} {f'{error_ns / 1e3:g} us':>16}"
            )

    print("\ncompile time against duration (1 pin, 10 Hz seed train)")
    print(f"{'duration':>10} {'pulses':>10} {'targets':>9} {'time (ms)':>10}")
    for seconds in (10, 60, 600, 3600, 24 * 3600):
        drives = [PinDrive(1, Train(Fraction(10), seconds * NS_PER_S))]
        schedule = compile_drives(drives, device)
        cost = _seconds(
            lambda d=drives: compile_drives(d, device), repeat=1 if seconds > 3600 else 3
        )
        print(
            f"{seconds:>9}s {len(schedule.pulses):>10} {len(schedule.targets):>9} {cost * 1e3:>10.1f}"
        )

    print("\ncompile time against active pins and array size (10 s at 10 Hz)")
    print(f"{'array':>7} {'active':>7} {'time (ms)':>10}")
    for size, active in ((4, 1), (4, 4), (4, 16), (16, 1), (64, 1)):
        big = _device(size)
        drives = [PinDrive(p, Train(Fraction(10), 10 * NS_PER_S)) for p in range(1, active + 1)]
        print(
            f"{size}x{size:<4} {active:>7} {_seconds(lambda d=drives, b=big: compile_drives(d, b)) * 1e3:>10.2f}"
        )
