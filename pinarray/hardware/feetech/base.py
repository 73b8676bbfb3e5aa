"""What the Feetech driver's parts share, as plain values; no I/O.

`BusSetup` is what the STS handshake checks and sets; `ReadBackBus` is what the read-backs
(`pinarray.hardware.feetech.readback`) need of the bus. What any family's driver shares with
the rest of pinarray (servo setups, telemetry, the safe-stop report) is in
`pinarray.hardware.driver`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech.registers import STS3215_MODEL_NUMBER, StatusError


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

    @property
    def position_unit(self) -> str:
        return "steps"

    def servo(self, servo_id: int) -> ServoSetup:
        for each in self.servos:
            if each.servo_id == servo_id:
                return each
        raise KeyError(servo_id)


@dataclass(frozen=True)
class GoalReading:
    """A servo's goal-position register as read back, with the error bits of its reply."""

    goal_steps: int
    errors: StatusError


class ReadBackBus(Protocol):
    """What the read-backs between frames need of a connected STS bus."""

    setup: BusSetup

    def read_goals(self, servo_ids: tuple[int, ...], deadline_ns: int) -> dict[int, GoalReading]:
        """Goal registers read back (a servo missing: no reply by ``deadline_ns``)."""
        ...

    def read_goals_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_goals` of these servos should take on this bus."""
        ...

    def read_positions(self, servo_ids: tuple[int, ...], deadline_ns: int) -> dict[int, int]:
        """Present Positions in steps (a servo missing: no reply by ``deadline_ns``)."""
        ...

    def read_positions_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_positions` of these servos should take on this bus."""
        ...

    def read_goals_and_positions(self, servo_ids: tuple[int, ...],
                                 deadline_ns: int) -> dict[int, tuple[GoalReading, int]]:
        """Goal registers and Present Positions in one exchange (a servo missing: no reply)."""
        ...

    def read_goals_and_positions_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_goals_and_positions` of these servos should take on this bus."""
        ...

    def read_request_bytes(self, servo_ids: tuple[int, ...]) -> int:
        """The size of the request that reads these servos' registers."""
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
