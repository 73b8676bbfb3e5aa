"""A rehearsal on the simulated array beside a busy machine: stimuli spoiled, and wall time.

`make run` rehearses on the in-process simulator, which shares the interpreter with the UI and
the CPU with whatever else the lab PC runs. Each round presents the same trials twice, in turn,
on a `Rig` at real speed while two CPU-bound processes run beside it and a thread of this
process keeps the interpreter busy (as the UI's redraws do):

- pinarray: the rehearsal clock, each stimulus in the simulator's own time (`ScaledClock.own_time`);
- reference: the same clock without it, every wait on the wall clock (the rehearsal before).

Figures per presentation: whether it was delivered as scheduled, and how long it took on the
wall clock over its scheduled length (own time stretches a stimulus by the host's own
computing instead of making it late). ``PINARRAY_BENCH_SECONDS`` (default 40) sets roughly how
long the rounds take.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from contextlib import nullcontext

from pinarray.clock import ScaledClock
from pinarray.plan import make_plan
from pinarray.player.rig import Rig
from pinarray.protocol.load import parse_protocol
from pinarray.schedule import compile_trial
from tests.benchmarks._timing import SPREAD_HEADER, ratio, spread
from tests.runs import REPO

SECONDS = float(os.environ.get("PINARRAY_BENCH_SECONDS", "40"))
TRIALS = 4  # per variant and round
STIMULUS_S = 1.0
PROTOCOL = (REPO / "protocols" / "localisation.yaml").read_text().replace(
    "duration_s: 10\n", f"duration_s: {STIMULUS_S:g}\n")
LOAD = "while True: pass"


class WallClockOnly(ScaledClock):
    """The reference: the rehearsal clock as it was, every wait on the wall clock."""

    def own_time(self):
        return nullcontext()


def presentations(clock: ScaledClock, seed: int) -> list[tuple[bool, float]]:
    """(delivered, wall seconds over scheduled seconds) of each of TRIALS presentations."""
    protocol = parse_protocol(PROTOCOL, "short.yaml")
    plan = make_plan(protocol, seed)
    out = []
    with Rig(protocol, None, None, clock) as rig:
        for planned in plan.trials[:TRIALS]:
            schedule = compile_trial(protocol, planned)
            started = time.perf_counter()
            presented = rig.present(schedule)
            wall_s = time.perf_counter() - started
            out.append((presented.delivery.delivered, wall_s / (schedule.targets.end_ns / 1e9)))
    return out


def busy_interpreter(stop: threading.Event) -> None:
    """Python work in this process, as the UI's redraws are: it holds the interpreter lock."""
    while not stop.is_set():
        sum(i * i for i in range(20_000))


def run() -> None:
    assert f"duration_s: {STIMULUS_S:g}\n" in PROTOCOL
    rounds = max(1, round(SECONDS / (2 * TRIALS * (STIMULUS_S + 0.4))))
    load = [subprocess.Popen([sys.executable, "-c", LOAD]) for _ in range(2)]
    stop = threading.Event()
    busy = threading.Thread(target=busy_interpreter, args=(stop,), daemon=True)
    busy.start()
    results: dict[str, list[tuple[bool, float]]] = {"pinarray (own time)": [],
                                                     "reference (wall clock)": []}
    try:
        for round_number in range(rounds):
            results["pinarray (own time)"] += presentations(ScaledClock(1.0), round_number)
            results["reference (wall clock)"] += presentations(WallClockOnly(1.0), round_number)
    finally:
        stop.set()
        for process in load:
            process.kill()
            process.wait()
    cores = len(os.sched_getaffinity(0))
    print(f"{rounds} rounds of {TRIALS} presentations of {STIMULUS_S:g} s each, beside 2 "
          f"CPU-bound processes and a busy thread in this process ({cores} cores)")
    print(f"{'':<24} {'not delivered':>13}   wall / scheduled: {SPREAD_HEADER} {'ratio':>7}")
    reference = [stretch for _, stretch in results["reference (wall clock)"]]
    for name, rows in results.items():
        spoiled = sum(not delivered for delivered, _ in rows)
        stretches = [stretch for _, stretch in rows]
        print(f"{name:<24} {spoiled:>6} of {len(rows):<4}   {'':>18}"
              f"{spread(stretches, scale=1, digits=3)} {ratio(stretches, reference):>7}")
    print("ratio: the median stretch over the reference's, measured in the same rounds")
