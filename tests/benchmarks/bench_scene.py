"""What one simulated exchange costs at each level of the simulated array's fidelity ladder.

One Present Position read of one servo (a motion sample), virtual time, CPU per exchange, at
the wire level (every byte at its time) and the packet level (the exchange computed whole,
the in-process default); the reference, in the same rounds, is the same exchange over a wire
that polls the simulated port every 20 us of clock time (the wire before it waited for its
bytes). The seed batch, at every level and beside its compute floor, is in
`tests.benchmarks.bench_fidelity`.
"""

from __future__ import annotations

import time

from tests.benchmarks._timing import SPREAD_HEADER, ratio, spread

EXCHANGES = 3000
ROUNDS = 7


def _exchange_cpu_us(level: str, polled: bool = False) -> float:
    from pinarray.clock import VirtualClock
    from pinarray.hardware.feetech.transport import open_bus

    bus = open_bus(f"sim://?ids=1-16&fidelity={level}", None, VirtualClock())
    if polled:  # the reader polls the port, as it once did
        bus.link.wire._readable_at_ns = None
        bus.link.wire._read_arrived = None
    clock = bus.clock
    started = time.process_time()
    for _ in range(EXCHANGES):
        bus.read_positions((4,), clock.now_ns() + 10_000_000)
    return (time.process_time() - started) / EXCHANGES * 1e6


def exchange_cost() -> None:
    measured: dict[str, list[float]] = {"wire": [], "packet": [], "polled": []}
    for _ in range(ROUNDS):
        measured["wire"].append(_exchange_cpu_us("wire"))
        measured["packet"].append(_exchange_cpu_us("packet"))
        measured["polled"].append(_exchange_cpu_us("wire", polled=True))
    print(f"one simulated exchange (READ of Present Position, one servo, virtual time); CPU us "
          f"per exchange, {ROUNDS} rounds of {EXCHANGES}")
    print(f"{'':<44} {SPREAD_HEADER} {'ratio':>7}")
    reference = measured["polled"]
    print(f"{'wire level: waiting for the port bytes':<44} {spread(measured['wire'], scale=1)} "
          f"{ratio(measured['wire'], reference):>7}")
    print(f"{'packet level: the exchange computed whole':<44} "
          f"{spread(measured['packet'], scale=1)} {ratio(measured['packet'], reference):>7}")
    print(f"{'reference: wire level, polling every 20 us':<44} {spread(reference, scale=1)} "
          f"{'1.00x':>7}")


def run() -> None:
    exchange_cost()


if __name__ == "__main__":
    run()
