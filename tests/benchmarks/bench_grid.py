"""How fast error classification is, per call, on grids from 4x4 to 64x64."""

import time

from pinarray.grid import Grid


def run() -> None:
    print(f"{'grid':>7} {'pairs':>9} {'ns/classify':>12}")
    for size in (4, 16, 64):
        grid = Grid(size, size)
        pins = list(grid.pins)[:: max(1, grid.pin_count // 256)]
        started = time.perf_counter_ns()
        count = 0
        for s in pins:
            for r in pins:
                grid.classify(s, r)
                count += 1
        elapsed = time.perf_counter_ns() - started
        print(f"{size}x{size:<4} {count:>9} {elapsed / count:>12.0f}")
