"""A connected STS bus handed to another process (the player's) through the port's descriptor.

The parent ran the handshake; the player process inherits the descriptor and, from this
picklable summary, drives the same servos with what the parent learnt of the port (return
delays, the adapter's latency) and without a second handshake.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from pinarray.clock import Clock
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.link import FdWire, Latency, Link

if TYPE_CHECKING:
    from pinarray.hardware.feetech.feetech import FeetechBus


@dataclass(frozen=True)
class Handover:
    """A connected bus as another process takes it over through the port's descriptor."""

    port_name: str
    baud_rate: int
    setup: BusSetup
    return_delay_ns: tuple[tuple[int, int], ...]  # (servo id, ns)
    latency_timer_ms: int | None
    worst_latency_ns: int
    recent_latency_ns: tuple[int, ...]

    def attach(self, fd: int, clock: Clock) -> FeetechBus:
        """The same servos, driven over ``fd`` in this process (no handshake: already done)."""
        from pinarray.hardware.feetech.feetech import FeetechBus

        latency = Latency(self.latency_timer_ms)
        latency.record(self.worst_latency_ns)
        for latency_ns in self.recent_latency_ns:
            latency.record(latency_ns)
        link = Link(FdWire(fd, clock, self.port_name), clock, self.baud_rate, latency)
        link.return_delay_ns.update(dict(self.return_delay_ns))
        bus = FeetechBus(link, clock)
        bus.setup = self.setup
        bus.assume_goals({s.servo_id: s.rest_steps for s in self.setup.servos})
        return bus


def handover_of(bus: FeetechBus) -> Handover:
    """What a process given ``bus``'s port descriptor needs to drive the same servos."""
    link = bus.link
    latency = link.latency
    return Handover(
        port_name=bus.port_name, baud_rate=link.baud_rate, setup=bus.setup,
        return_delay_ns=tuple(link.return_delay_ns.items()),
        latency_timer_ms=latency.timer_ms,
        worst_latency_ns=latency.worst_seen_ns, recent_latency_ns=tuple(latency.recent_ns),
    )
