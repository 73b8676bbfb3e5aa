"""Shared by the benchmarks: repeated, interleaved timings, their spread, and peak memory.

Each figure is measured beside its reference in the same rounds (one run of each, in turn),
so a noisy neighbour on the shared machine slows both alike and their ratio stays fair.
"""

from __future__ import annotations

import statistics
import time
import tracemalloc
from collections.abc import Callable, Mapping

RUNS = 5


def interleaved_seconds(
    calls: Mapping[str, Callable[[], object]], runs: int = RUNS
) -> dict[str, list[float]]:
    """Seconds of each call, ``runs`` rounds of one call of each in turn (after one warm-up)."""
    for call in calls.values():
        call()
    times: dict[str, list[float]] = {name: [] for name in calls}
    for _ in range(runs):
        for name, call in calls.items():
            started = time.perf_counter()
            call()
            times[name].append(time.perf_counter() - started)
    return times


def median(times: list[float]) -> float:
    return statistics.median(times)


def spread(times: list[float], scale: float = 1e3, digits: int = 1) -> str:
    """``min median max`` of ``times`` (s) times ``scale``, in three right-aligned columns."""
    return " ".join(f"{t * scale:>9.{digits}f}" for t in (min(times), median(times), max(times)))


SPREAD_HEADER = f"{'min':>9} {'median':>9} {'max':>9}"


def ratio(times: list[float], reference: list[float]) -> str:
    return f"{median(times) / median(reference):.2f}x"


def peak_bytes(call: Callable[[], object]) -> int:
    """Largest traced allocation total while ``call`` runs (numpy reports its arrays)."""
    tracemalloc.start()
    try:
        result = call()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    del result
    return peak
