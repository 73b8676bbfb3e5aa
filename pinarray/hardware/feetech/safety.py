"""The STS safe stop: pins to rest, then torque off, wherever the bus still answers.

Used on every way out of a trial, a session and a connect; it never raises, and it holds the
stop signals back until it is done, so that a second one cannot leave servos holding torque.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from pinarray.errors import BusError
from pinarray.hardware.driver import PortLost, SafeStopReport
from pinarray.hardware.feetech import packets
from pinarray.hardware.feetech.link import WireLost
from pinarray.hardware.feetech.registers import BROADCAST_ID, Register, decode_position, from_bytes
from pinarray.stop import deferred_signals

if TYPE_CHECKING:
    from pinarray.hardware.feetech.feetech import FeetechBus

REST_TOLERANCE_STEPS = 4
# Present position .. moving flag, read in one instruction while waiting for pins to settle.
MOTION_LENGTH = Register.MOVING.address + 1 - Register.PRESENT_POSITION.address
REST_POLL_NS = 10_000_000
# How long pins may take to reach rest before the stop goes on without them.
REST_TIMEOUT_NS = 2_000_000_000
# Torque-off writes are tried twice (the second waiting four times longer): a servo that
# answers neither is reported silent rather than holding up the others' release.
RELEASE_RETRIES = 1


def move_to_rest(bus: FeetechBus, timeout_ns: int = REST_TIMEOUT_NS) -> tuple[int, ...]:
    """Send every pin to rest and wait until they report it; returns the ids at rest."""
    rest = {s.servo_id: s.rest_steps for s in bus.setup.servos}
    bus.write_goals(rest, force=True)
    return _wait_at(bus, rest, timeout_ns)


def _wait_at(bus: FeetechBus, goals: Mapping[int, int], timeout_ns: int) -> tuple[int, ...]:
    deadline_ns = bus.clock.now_ns() + timeout_ns
    pending = dict(goals)
    arrived: list[int] = []
    while pending:
        for servo_id, goal in list(pending.items()):
            if bus.clock.now_ns() >= deadline_ns:
                break
            try:
                # One attempt: this loop asks again until the deadline, so a silent servo
                # costs one reply time a pass, not the growing waits of a retried read.
                data, _ = bus.read(servo_id, Register.PRESENT_POSITION, MOTION_LENGTH, retries=0)
            except PortLost:
                raise
            except BusError:
                continue
            position = decode_position(from_bytes(data[0:2]))
            still = data[-1] == 0  # MOVING register
            if still and abs(position - goal) <= REST_TOLERANCE_STEPS:
                arrived.append(servo_id)
                del pending[servo_id]
        if not pending or bus.clock.now_ns() >= deadline_ns:
            break
        # A sync write lost on the wire would leave a pin up: say it again while waiting.
        bus.write_goals(pending, force=True)
        bus.clock.sleep_until_ns(bus.clock.now_ns() + REST_POLL_NS)
    return tuple(sorted(arrived))


def rest_and_release(bus: FeetechBus, timeout_ns: int = REST_TIMEOUT_NS) -> SafeStopReport:
    """Pins to rest, then torque off, on every servo that still answers. Never raises.

    The stop signals are held back until it is done, so a second one cannot leave
    servos holding torque.
    """
    with deferred_signals():
        return _rest_and_release(bus, timeout_ns)


def _rest_and_release(bus: FeetechBus, timeout_ns: int) -> SafeStopReport:
    ids = bus.setup.servo_ids
    try:
        at_rest = move_to_rest(bus, timeout_ns)
    except PortLost:
        _release_everyone(bus)
        return SafeStopReport((), (), ids, port_lost=True)
    except BusError:
        at_rest = ()
    released = []
    for servo_id in ids:
        try:
            bus.write(servo_id, Register.TORQUE_ENABLE, 0, retries=RELEASE_RETRIES)
            released.append(servo_id)
        except PortLost:
            _release_everyone(bus)
            silent = tuple(i for i in ids if i not in released)
            return SafeStopReport(at_rest, tuple(released), silent, port_lost=True)
        except BusError:
            continue
    silent = tuple(i for i in ids if i not in released or i not in at_rest)
    return SafeStopReport(at_rest, tuple(released), silent)


def _release_everyone(bus: FeetechBus) -> None:
    """A last try when the port fails mid-stop: torque off for every servo, in one
    broadcast write that needs no reply (it may still get through a flaky adapter)."""
    try:
        bus.link.send(packets.write(BROADCAST_ID, Register.TORQUE_ENABLE.address, b"\x00"))
    except (WireLost, OSError):
        pass
