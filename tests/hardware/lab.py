"""Small builders the bus tests share: a 16-pin device, hand-made target lists, a bus."""

from __future__ import annotations

import numpy as np

from pinarray.clock import VirtualClock
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.transport import open_bus
from pinarray.schedule import TargetList

REST_STEPS = 2048
MIN_STEPS = 1900
MAX_STEPS = 2300


def device_setup(ids=range(1, 17)) -> BusSetup:
    """Pin n on servo n, resting at 2048 steps, allowed 1900..2300."""
    servos = tuple(ServoSetup(i, i, REST_STEPS, MIN_STEPS, MAX_STEPS) for i in ids)
    return BusSetup(servos=servos, speed_steps_per_s=3000, acceleration_register=0)


def sim_bus(query: str = "", setup: BusSetup | None = None, connect: bool = True):
    """A connected simulated bus in virtual time; ``query`` adds URL keys such as faults."""
    setup = setup or device_setup()
    url = "sim://?ids=1-16" + (f"&{query}" if query else "")
    return open_bus(url, setup if connect else None, VirtualClock())


def targets(changes: list[tuple[int, int, int]], end_ns: int) -> TargetList:
    """A target list from (time_ns, pin, position_steps) changes."""
    changes = sorted(changes)
    return TargetList(
        time_ns=np.array([c[0] for c in changes], dtype=np.int64),
        pin=np.array([c[1] for c in changes], dtype=np.int16),
        position_steps=np.array([c[2] for c in changes], dtype=np.int32),
        end_ns=end_ns,
    )


def pulse_train(pins, rate_hz: float, cycles: int, up_steps: int = 2100) -> TargetList:
    """Every pin in ``pins`` up and down together, ``cycles`` times at ``rate_hz``."""
    half_ns = round(1e9 / rate_hz / 2)
    changes = []
    for k in range(cycles):
        for pin in pins:
            changes.append((2 * k * half_ns, pin, up_steps))
            changes.append(((2 * k + 1) * half_ns, pin, REST_STEPS))
    return targets(changes, end_ns=2 * cycles * half_ns + 200_000_000)


def assert_safe(bus) -> None:
    """Every simulated servo is at rest with torque off: what the lab checks after a stop."""
    for servo_id, servo in bus.sim.servos.items():
        assert not servo.torque_enabled, f"servo {servo_id} still has torque"
        assert abs(servo.position_steps - REST_STEPS) <= 4, f"servo {servo_id} not at rest"
