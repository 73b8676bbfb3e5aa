"""The reference beside which the player is timed: the least a deadline loop can do.

Prebuilt packets, absolute deadlines, sleep then spin, one ``os.write`` each; no read-backs,
no bookkeeping, no garbage collector. Run as ``python -m tests.benchmarks.reference_loop PATH
PLAN [--realtime]``; it prints its onset (``time.monotonic_ns()``) when done.
"""

from __future__ import annotations

import gc
import os
import pickle
import sys
import time

from pinarray.player.child import REALTIME_PRIORITY, make_realtime


def main(argv: list[str]) -> int:
    path, plan_path = argv[0], argv[1]
    with open(plan_path, "rb") as stream:
        times_ns, packets, lead_ns, spin_ns = pickle.load(stream)
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    problem = make_realtime(REALTIME_PRIORITY) if "--realtime" in argv else ""
    gc.disable()
    onset_ns = time.monotonic_ns() + lead_ns
    for time_ns, packet in zip(times_ns, packets, strict=True):
        deadline_ns = onset_ns + time_ns
        remaining_ns = deadline_ns - time.monotonic_ns()
        if remaining_ns > spin_ns:
            time.sleep((remaining_ns - spin_ns) / 1e9)
        while time.monotonic_ns() < deadline_ns:
            pass
        os.write(fd, packet)
    if problem:
        print(problem, file=sys.stderr)
    print(onset_ns, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
