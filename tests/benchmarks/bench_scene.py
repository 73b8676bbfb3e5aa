"""The simulated array at the cost of its scene: a seed batch in virtual time beside its compute
floor, and what one simulated exchange costs beside a polled wire.

- batch: ``pinarray batch protocols/localisation.yaml --observer default`` (26 trials of 10 s,
  virtual time, motion sampled) as a whole process; the reference, in the same rounds, is its
  compute floor: a process that loads the protocol, plans it, compiles the 26 schedules and
  encodes every frame, and nothing else (no bus, no results). Target: the batch in at most
  2 s (median).
- exchange: one Present Position read of one servo (the motion sample), virtual time, CPU per
  exchange; the reference is the same exchange over a wire that polls the simulated port every
  20 us of clock time (the wire before it waited for its bytes).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time

from tests.benchmarks._timing import SPREAD_HEADER, interleaved_seconds, median, ratio, spread
from tests.runs import REPO

PROTOCOL = REPO / "protocols" / "localisation.yaml"
BATCH_TARGET_S = 2.0
EXCHANGES = 3000

FLOOR = f"""
from pathlib import Path
from pinarray.protocol.load import load_protocol
from pinarray.plan import make_plan
from pinarray.schedule import compile_trial
from pinarray.player.families import bus_setup
from pinarray.hardware.feetech.transport import open_bus
from pinarray.player.playback import prepare_trial
protocol = load_protocol(Path({str(PROTOCOL)!r}))
plan = make_plan(protocol, 1)
bus = open_bus("sim://", None)  # unconnected: only its frame encoder is used
bus.setup = bus_setup(protocol.device)
frames = 0
for planned in plan.trials:
    schedule = compile_trial(protocol, planned)
    frames += len(prepare_trial(bus, schedule.targets, schedule.pulses).frames)
assert frames > 0
"""


def _batch() -> None:
    with tempfile.TemporaryDirectory() as results:
        subprocess.run([sys.executable, "-m", "pinarray", "batch", str(PROTOCOL), "--observer",
                        "default", "--subject", "bench", "--seed", "1", "--results", results],
                       cwd=REPO, check=True, stdout=subprocess.DEVNULL, timeout=600)


def _floor() -> None:
    subprocess.run([sys.executable, "-c", FLOOR], cwd=REPO, check=True, timeout=600)


def seed_batch() -> None:
    times = interleaved_seconds({"batch": _batch, "floor": _floor})
    print(f"{PROTOCOL.name}: 26 trials of 10 s in virtual time, motion sampled; whole processes,"
          f" {len(times['batch'])} rounds; ms")
    print(f"{'':<44} {SPREAD_HEADER} {'ratio':>7}")
    print(f"{'pinarray batch --observer default':<44} {spread(times['batch'])} "
          f"{ratio(times['batch'], times['floor']):>7}")
    print(f"{'floor: load, plan, compile, encode frames':<44} {spread(times['floor'])} "
          f"{'1.00x':>7}")
    met = "met" if median(times["batch"]) <= BATCH_TARGET_S else "NOT met"
    print(f"target: the batch in at most {BATCH_TARGET_S:g} s (median): {met}; ratio: the "
          "median over the floor's, in the same rounds")


def _exchange_cpu_us(polled: bool) -> float:
    from pinarray.clock import VirtualClock
    from pinarray.hardware.feetech.transport import open_bus

    bus = open_bus("sim://?ids=1-16", None, VirtualClock())
    if polled:
        bus.link.wire._readable_at_ns = None  # the reader polls the port, as it once did
        bus.link.wire._read_arrived = None
    clock = bus.clock
    started = time.process_time()
    for _ in range(EXCHANGES):
        bus.read_positions((4,), clock.now_ns() + 10_000_000)
    return (time.process_time() - started) / EXCHANGES * 1e6


def exchange_cost() -> None:
    rounds = 7
    waited, polled = [], []
    for _ in range(rounds):
        waited.append(_exchange_cpu_us(False))
        polled.append(_exchange_cpu_us(True))
    print(f"one simulated exchange (READ of Present Position, one servo, virtual time); CPU us "
          f"per exchange, {rounds} rounds of {EXCHANGES}")
    print(f"{'':<44} {SPREAD_HEADER} {'ratio':>7}")
    print(f"{'waiting for the port bytes (pinarray)':<44} {spread(waited, scale=1)} "
          f"{ratio(waited, polled):>7}")
    print(f"{'reference: polling every 20 us':<44} {spread(polled, scale=1)} {'1.00x':>7}")


def run() -> None:
    seed_batch()
    exchange_cost()


if __name__ == "__main__":
    run()
