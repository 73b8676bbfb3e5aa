"""Small builders the bus tests share: a 16-pin device, hand-made target lists, a bus."""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable
from math import ceil

import numpy as np

from pinarray.clock import VirtualClock
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.transport import open_bus
from pinarray.hardware.pca9685.driver import REST_SETTLE_NS
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


# -- PWM boards -------------------------------------------------------------------------------

def assert_rest_held_for_the_travel_time(board, protocol, now_ns):
    """The last pulses of every channel: its rest width, from the first of them to the period
    after the last (where a servo would see the next), for the servos' travel time: their
    whole calibrated range at their speed, and the settling time beyond it."""
    device = protocol.device
    span_us = max(c.max_steps - c.min_steps for c in (device.calibration(p) for p in range(1, 17)))
    travel_ns = ceil(span_us * 10**9 / device.servo.speed_us_per_s) + REST_SETTLE_NS
    for channel in range(16):
        carried = board.pulses(channel, 0, now_ns)
        if not carried:
            continue  # never told to pulse
        rest_ns = device.calibration(channel + 1).rest_steps * 1000
        period_ns = board.period_ns()
        held_until = carried[-1][0] + period_ns
        held_from = held_until
        for start, width in reversed(carried):
            if abs(width - rest_ns) > 3_000 or held_from - start > period_ns + 1:
                break  # another width, or a gap: the servo went limp before
            held_from = start
        assert held_until - held_from >= travel_ns, (
            f"channel {channel}: rest width for {(held_until - held_from) / 1e6:.1f} ms before "
            f"the pulses stopped, the servos need {travel_ns / 1e6:.1f} ms")


class SignalFromAnotherThread:
    """Inside the block, SIGTERM is given to a thread of this process that is not the main one,
    0.3 s in (the main thread waiting by then; were it not, the handler runs at once): the
    kernel may give a process's signal to any of its threads, and Python runs the handler only
    when the main thread next runs. If the main thread's wait has not ended 30 s later (a bound
    against a hang, not a timing claim), ``unstick`` ends it otherwise and `slept_through`
    says so."""

    def __init__(self, unstick: Callable[[], object]):
        self.slept_through = False
        self._unstick = unstick
        self._ended = threading.Event()
        self._thread = threading.Thread(target=self._signal)

    def _signal(self) -> None:
        time.sleep(0.3)
        signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
        if not self._ended.wait(30):
            self.slept_through = True
            self._unstick()

    def __enter__(self) -> SignalFromAnotherThread:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._ended.set()
        self._thread.join()
