"""What the player needs from a servo bus, as plain values; no vendor SDK, no I/O.

The player and session speak servo ids and positions in steps; which servo moves which pin
is the protocol's business (`servo_setup_from_device`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from pinarray.errors import BusError
from pinarray.hardware.feetech.registers import STS3215_MODEL_NUMBER, StatusError


class PortLost(BusError):
    """The serial port vanished mid-run (USB unplugged, adapter reset)."""


@dataclass(frozen=True)
class ServoSetup:
    """One servo as playback needs it: where rest is and the calibrated limits, in steps."""

    servo_id: int
    pin: int
    rest_steps: int
    min_steps: int
    max_steps: int


@dataclass(frozen=True)
class BusSetup:
    """Everything the connect handshake checks and sets.

    Attributes
    ----------
    servos : tuple of ServoSetup
        Every servo the device section names.
    model_number : int
        Model-number register value every servo must report (777 = STS3215).
    speed_steps_per_s : int
        Goal speed written to RAM at connect, in steps per second (0 = the servo's maximum).
    acceleration_register : int
        Acceleration register value, in 100 step/s^2 units (0 = the servo's maximum).
    """

    servos: tuple[ServoSetup, ...]
    model_number: int = STS3215_MODEL_NUMBER
    speed_steps_per_s: int = 0
    acceleration_register: int = 0

    @property
    def servo_ids(self) -> tuple[int, ...]:
        return tuple(s.servo_id for s in self.servos)

    def servo(self, servo_id: int) -> ServoSetup:
        for each in self.servos:
            if each.servo_id == servo_id:
                return each
        raise KeyError(servo_id)


@dataclass(frozen=True)
class Telemetry:
    """One servo's slow-changing state, read outside the timing-critical path."""

    servo_id: int
    position_steps: int
    load_permille: int  # signed, 0.1 % of stall torque
    voltage_v: float
    temperature_c: int
    errors: StatusError


@dataclass(frozen=True)
class GoalReading:
    """A servo's goal-position register as read back, with the error bits of its reply."""

    goal_steps: int
    errors: StatusError


@dataclass(frozen=True)
class BusStats:
    """Counters since the bus was opened."""

    bytes_written: int
    bytes_read: int
    sync_writes: int
    goals_written: int
    retries: int
    stale_bytes: int = 0  # late replies drained before a request
    mismatched_replies: int = 0  # status packets whose id or length did not fit the request


@dataclass(frozen=True)
class SafeStopReport:
    """What `Bus.rest_and_release` managed: ids confirmed at rest, released, and silent."""

    at_rest_ids: tuple[int, ...]
    released_ids: tuple[int, ...]
    silent_ids: tuple[int, ...]
    port_lost: bool = False

    @property
    def complete(self) -> bool:
        return not self.silent_ids and not self.port_lost

    def describe(self) -> str:
        """How safe the pins are after a stop, in one clause."""
        if self.port_lost and not self.released_ids:
            return "port lost: could not reach any servo; cut servo power"
        text = f"{len(self.at_rest_ids)} servo(s) at rest, {len(self.released_ids)} released"
        if self.silent_ids:
            text += f"; servo(s) {', '.join(map(str, self.silent_ids))} not confirmed safe"
        return text


class Bus(Protocol):
    """A connected servo bus (real or simulated) that the player drives."""

    setup: BusSetup

    def goal_packet(self, goals_steps: Mapping[int, int]) -> bytes:
        """The bytes of one frame's goal write, checked against the pins' limits."""
        ...

    def send_goals(self, packet: bytes,
                   goals_steps: Mapping[int, int] | tuple[tuple[int, int], ...]) -> None:
        """Write a frame prepared by `goal_packet`, in one call, without waiting for a reply."""
        ...

    def read_goals(self, servo_ids: tuple[int, ...], deadline_ns: int) -> dict[int, GoalReading]:
        """Goal registers read back (a servo missing: no reply by ``deadline_ns``)."""
        ...

    def read_goals_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_goals` of these servos should take on this bus."""
        ...

    def move_to_rest(self, timeout_ns: int = ...) -> tuple[int, ...]:
        """Every pin to rest; the ids confirmed there."""
        ...

    def rewrite_goal(self, servo_id: int, goal_steps: int, deadline_ns: int) -> StatusError | None:
        """Write one goal again, acknowledged (None: no acknowledgement by ``deadline_ns``)."""
        ...

    def reply_time_ns(self, servo_id: int, request_bytes: int, reply_params: int) -> int:
        """What one exchange with ``servo_id`` should take on this bus (to plan read-backs)."""
        ...

    def wire_ns(self, byte_count: int) -> int:
        """Time ``byte_count`` bytes take on the wire."""
        ...

    def read_telemetry(self, servo_ids: tuple[int, ...]) -> tuple[Telemetry, ...]: ...

    def rest_and_release(self) -> SafeStopReport: ...

    def stats(self) -> BusStats: ...

    def close(self) -> None: ...
