"""Finding servos over a pseudo-terminal: `servos scan` beside the scan it replaced.

`pinarray sim-serve` runs in its own process (the servos behind a "USB adapter"); this process
scans it. The reference is what `pinarray scan` did before `servos scan` existed, measured in
the same rounds: a PING of each id in turn with the driver's usual wait for an answer (the
SDK's cautious 34 ms on an adapter whose latency timer cannot be read, as a pseudo-terminal's
cannot) until three answers have been timed, then three times the slowest one seen. Ids 0-63
keep a round short; a sweep of 0-252 costs about four times as much.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from contextlib import contextmanager

from pinarray.hardware.feetech import bringup, scan
from pinarray.hardware.feetech.transport import open_bus
from tests.benchmarks._timing import SPREAD_HEADER, interleaved_seconds, ratio, spread

IDS = tuple(range(64))
RUNS = 3


@contextmanager
def sim_serve(ids: str):
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", "--ids", ids],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        yield process.stdout.readline().split(" on ")[1].split()[0]
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=10)


def old_scan(path: str) -> int:
    """`pinarray scan` before bring-up: every id pinged in turn, no answer waited out in full."""
    bus = open_bus(path, retries=1)
    try:
        return sum(bus.ping(servo_id, retry=False) is not None for servo_id in IDS)
    finally:
        bus.close()


def new_scan(path: str, ids) -> int:
    bus = open_bus(path, retries=1)
    try:
        return len(scan.scan(bus, ids, bringup.sweep_timeout_ns(bus)).servo_ids)
    finally:
        bus.close()


def run() -> None:
    print(f"seconds to find the servos on sim-serve's pseudo-terminal (ids {IDS[0]}-{IDS[-1]}), "
          f"{RUNS} interleaved rounds after a warm-up")
    print(f"{'case':<44} {'servos':>6}  {'servos scan ' + SPREAD_HEADER:<42} "
          f"{'old scan ' + SPREAD_HEADER:<39} {'ratio':>6}")
    cases = (("1 new servo: one broadcast ping", "1", None),
             ("2 servos (1, 60): collide, then a sweep", "1,60", IDS),
             ("16 servos (1-16): collide, then a sweep", "1-16", IDS))
    for label, served, ids in cases:
        with sim_serve(served) as path:
            found = {"new": new_scan(path, ids), "old": old_scan(path)}
            times = interleaved_seconds({"new": lambda p=path, i=ids: new_scan(p, i),
                                         "old": lambda p=path: old_scan(p)}, runs=RUNS)
        assert found["new"] == found["old"], found  # both must find the same servos
        print(f"{label:<44} {found['new']:>6}  {'':>12}{spread(times['new'], 1, 3)}"
              f"  {'':>9}{spread(times['old'], 1, 3)} {ratio(times['new'], times['old']):>6}",
              flush=True)


if __name__ == "__main__":
    run()
