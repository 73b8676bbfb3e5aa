"""`make test` and CI's `.ci/run` on a fresh clone, setup included, as a lab's new machine or
CI first runs them.

The clone is of this repository's committed HEAD (what is not committed is not in it). One
round: clone, then ``make test`` (the virtual environment created and filled, then both lanes
of tests/suite.py), wall seconds and the processor seconds of everything it ran; then another
clone and ``.ci/run`` (make test, the lowest versions' tests, PsychoPy's, the gates, the
examples and the documentation). The reference, timed in the same round before and after
each, is the seed batch's compute floor (`tests.benchmarks.bench_fidelity`): a fixed workload
that says how fast the machine is that hour. Targets (issue 48) on this 2-core machine:
make test within 120 s, .ci/run within 360 s. ``PINARRAY_BENCH_SUITE_RUNS`` and
``PINARRAY_BENCH_CI_RUNS`` (default 1 each: a round takes minutes; 0 leaves it out) set the
rounds.
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from tests.benchmarks._timing import SPREAD_HEADER, spread
from tests.benchmarks.bench_fidelity import floor
from tests.runs import REPO

RUNS = int(os.environ.get("PINARRAY_BENCH_SUITE_RUNS", "1"))
CI_RUNS = int(os.environ.get("PINARRAY_BENCH_CI_RUNS", "1"))
TARGET_S = 120.0
CI_TARGET_S = 360.0


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def fresh_clone_run(command: list[str]) -> tuple[float, float, int]:
    """(wall s, processor s, exit status) of ``command`` in a fresh clone."""
    with tempfile.TemporaryDirectory(prefix="pinarray-clone-") as folder:
        clone = Path(folder) / "pinarray"
        subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
        environment = {k: v for k, v in os.environ.items() if k != "VIRTUAL_ENV"}
        cpu_before, started = _children_cpu_s(), time.perf_counter()
        status = subprocess.run(command, cwd=clone, env=environment,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                timeout=3600).returncode
        return time.perf_counter() - started, _children_cpu_s() - cpu_before, status


def measure(command: list[str], rounds: int) -> tuple[list[float], list[float], list[float],
                                                       list[int]]:
    """Wall and processor seconds and exit statuses of ``command`` on fresh clones, and the
    reference's seconds before and after each round."""
    wall, cpu, reference, statuses = [], [], [], []
    for _ in range(rounds):
        started = time.perf_counter()
        floor("localisation")
        reference.append(time.perf_counter() - started)
        seconds, processor, status = fresh_clone_run(command)
        statuses.append(status)
        wall.append(seconds)
        cpu.append(processor)
        started = time.perf_counter()
        floor("localisation")
        reference.append(time.perf_counter() - started)
    return wall, cpu, reference, statuses


def table(name: str, command: list[str], rounds: int, target_s: float) -> None:
    if rounds < 1:
        return
    wall, cpu, reference, statuses = measure(command, rounds)
    print(f"{name} on a fresh clone of HEAD, setup included; {rounds} round(s); s")
    print(f"{'':<40} {SPREAD_HEADER} {'/ref':>9}")
    ratio = statistics.median(wall) / statistics.median(reference)
    print(f"{name + ', wall':<40} {spread(wall, 1, 1)} {ratio:>8.0f}x")
    print(f"{name + ', processor (all its processes)':<40} {spread(cpu, 1, 1)}")
    print(f"{'reference: the seed batch compute floor':<40} {spread(reference, 1, 3)} "
          f"{'1x':>9}")
    failed = [s for s in statuses if s]
    met = "met" if statistics.median(wall) <= target_s and not failed else "NOT met"
    note = f" ({name} failed in {len(failed)} round(s): exit {failed[0]})" if failed else ""
    print(f"target: within {target_s:g} s (median wall): {met}{note}")


def run() -> None:
    table("make test", ["make", "test"], RUNS, TARGET_S)
    table(".ci/run", [".ci/run"], CI_RUNS, CI_TARGET_S)
