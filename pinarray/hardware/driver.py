"""The array-driver seam: what the player, the rig and the pre-flight know of a pin array.

A family of servos plugs in here. Feetech STS bus servos (`pinarray.hardware.feetech`) are
the first; hobby PWM servos on a PCA9685 board would be `pinarray.hardware.pca9685`, a
package implementing `ArrayDriver`, plus one entry in `pinarray.player.families` that builds
its setup from a protocol's device section and opens it. Nothing above the player (session,
journal, UI) changes for a new family: they speak pins, servo ids, positions in steps and
nanoseconds, and see a stimulus as a `Presentation` (`pinarray.hardware.delivery`).

What a driver does, in the order a sitting asks for it:

1. **connect**: opened on a port with its setup (which servo lifts which pin, rest and
   calibrated limits), `check_servos` reads every servo and refuses, naming each missing or wrong
   one, before anything moves; `hold` then gives them torque where their horns are. A player
   process that guards the servos is started between the two (`handover`).
2. **limits**: `goal_packet` and `prepare` refuse any goal outside a pin's calibrated limits.
3. **prepare a trial's frames**: `prepare` turns a trial's goal changes (and, for a family
   that needs them, its pulses) into frames encoded before onset, so that at each deadline the
   player hands prepared bytes to the port in one call (`pinarray.hardware.frames`).
4. **start and write**: `begin` readies the hardware in the lead time before onset (a PWM
   board: its period and its counter started at onset; bus servos: nothing), then each frame
   goes out at its deadline: `send_goals`.
5. **verify and heal**: `verifier` returns the driver's own way of confirming, in the slack
   between frames, that each change reached its servo, and of healing those that did not,
   recording each change's fate in the trial's `DeliveryLedger`; `heal_time_ns` says what
   that takes, for the pre-flight's timing verdict. With time left, the verifier samples
   where the moving pins are (`sample_until`, `trace`), where the servos can say.
6. **telemetry** after a trial (`read_telemetry`; a family without any returns none).
7. **safe stop**: `rest_and_release` never raises: pins to rest, then torque off (PWM:
   pulses stop) wherever the hardware still answers, and a report of what it managed.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from pinarray.errors import BusError

if TYPE_CHECKING:
    import numpy as np  # in the seam's annotations only: the bring-up commands need no numpy

    from pinarray.clock import Clock
    from pinarray.hardware.delivery import DeliveryLedger, PreparedFrame, PreparedTrial
    from pinarray.hardware.motion import Samples


class PortLost(BusError):
    """The port to the servos vanished mid-run (USB unplugged, adapter reset)."""


class GoalOutOfRange(BusError):
    """A jogged pin's goal beyond what its servo may be sent: nothing was sent."""


@dataclass(frozen=True)
class ServoSetup:
    """One servo as playback needs it: where rest is and the calibrated limits, in steps."""

    servo_id: int
    pin: int
    rest_steps: int
    min_steps: int
    max_steps: int


class ArraySetup(Protocol):
    """The servos a driver was opened for (each family adds what its handshake checks)."""

    @property
    def servos(self) -> tuple[ServoSetup, ...]: ...

    @property
    def servo_ids(self) -> tuple[int, ...]: ...

    @property
    def position_unit(self) -> str:
        """What positions count: ``steps`` (bus servos), ``us`` of pulse width (PWM)."""
        ...


class TargetFrame(Protocol):
    """The goal changes due at one instant (ns from onset)."""

    @property
    def time_ns(self) -> int: ...

    @property
    def pins(self) -> np.ndarray: ...

    @property
    def position_steps(self) -> np.ndarray: ...


class Targets(Protocol):
    """A trial's goal changes, sorted by time then pin (`pinarray.schedule.TargetList`)."""

    @property
    def time_ns(self) -> np.ndarray: ...

    @property
    def pin(self) -> np.ndarray: ...

    @property
    def position_steps(self) -> np.ndarray: ...

    @property
    def end_ns(self) -> int: ...

    def frames(self) -> Iterator[TargetFrame]: ...


class Pulses(Protocol):
    """A trial's servo pulses, sorted by start then pin (`pinarray.schedule.PulseList`)."""

    @property
    def pin(self) -> np.ndarray: ...

    @property
    def start_ns(self) -> np.ndarray: ...

    @property
    def width_ns(self) -> np.ndarray: ...


class ServoFaults(Protocol):
    """A servo's fault flags as it reported them: false when there are none."""

    def __bool__(self) -> bool: ...

    def describe(self) -> str:
        """The faults in words ("none" when there are none)."""
        ...


@dataclass(frozen=True)
class Telemetry:
    """One servo's slow-changing state, read outside the timing-critical path."""

    servo_id: int
    position_steps: int
    load_permille: int  # signed, 0.1 % of stall torque
    voltage_v: float
    temperature_c: int
    errors: ServoFaults


@dataclass(frozen=True)
class BusStats:
    """Counters since the driver was opened."""

    bytes_written: int
    bytes_read: int
    sync_writes: int  # frames written (one write each)
    goals_written: int
    retries: int
    stale_bytes: int = 0  # late replies drained before a request
    mismatched_replies: int = 0  # replies whose id or length did not fit the request


@dataclass(frozen=True)
class SafeStopReport:
    """What `ArrayDriver.rest_and_release` managed: the servo ids confirmed at rest
    (``at_rest_ids``), released (``released_ids``: torque off) and ``silent_ids`` (no answer);
    ``port_lost`` when the port itself had gone."""

    at_rest_ids: tuple[int, ...]
    released_ids: tuple[int, ...]
    silent_ids: tuple[int, ...]
    port_lost: bool = False

    @property
    def complete(self) -> bool:
        """Every servo answered the safe stop (none silent, the port still there)."""
        return not self.silent_ids and not self.port_lost

    def describe(self) -> str:
        """How safe the pins are after a stop, in one clause."""
        if self.port_lost and not self.released_ids:
            return "port lost: could not reach any servo; cut servo power"
        text = f"{len(self.at_rest_ids)} servo(s) at rest, {len(self.released_ids)} released"
        if self.silent_ids:
            text += f"; servo(s) {', '.join(map(str, self.silent_ids))} not confirmed safe"
        return text


class FrameVerifier(Protocol):
    """A driver's confirmation of one trial's goal changes, worked in the slack between frames.

    Created by `ArrayDriver.verifier` at onset; told of each frame as its write returns;
    given time until a limit it must never pass (the next frame's deadline less a guard).
    """

    @property
    def pending(self) -> Mapping[int, int]:
        """Servo id -> index of its change not yet confirmed."""
        ...

    def sent(self, frame: PreparedFrame, sent_ns: int) -> None:
        """A frame's write returned ``sent_ns`` after onset: its changes await confirmation."""
        ...

    def work_until(self, limit_ns: int) -> None:
        """Confirm or heal pending changes while that still ends before ``limit_ns``."""
        ...

    def sample_until(self, limit_ns: int) -> None:
        """With nothing pending: sample where the moving pins are while that still ends before
        ``limit_ns`` (a family whose servos cannot say does nothing)."""
        ...

    def trace(self) -> tuple[Samples, ...]:
        """The moving pins' samples so far (empty where the servos cannot say): a family used
        by the player process keeps them without numpy (`PinSamples`)."""
        ...


class Handover(Protocol):
    """A connected driver as another process (the player's) takes it over; picklable."""

    def attach(self, fd: int, clock: Clock) -> ArrayDriver:
        """The same servos, driven over the inherited descriptor ``fd`` (no handshake)."""
        ...


class ArrayDriver(Protocol):
    """A connected pin array of one family of servos, real or simulated."""

    @property
    def setup(self) -> ArraySetup: ...

    @property
    def port_name(self) -> str: ...

    @property
    def warnings(self) -> list[str]:
        """What the lab should know about the port (e.g. a slow adapter setting)."""
        ...

    @property
    def descriptor(self) -> int | None:
        """The port's file descriptor, which a player process can inherit (None: none)."""
        ...

    @property
    def latency_timer_ms(self) -> int | None:
        """A USB adapter's latency timer when the driver knows it (for the timing verdict)."""
        ...

    def check_servos(self) -> None:
        """The handshake's reads: every servo there and fit for its pin. Nothing moves.

        Raises `BusError` naming every missing or unfit servo at once.
        """
        ...

    def hold(self) -> None:
        """Torque on for every checked servo, holding where it is; none holding on failure."""
        ...

    def reconnect(self) -> None:
        """`check_servos` then `hold` again, after a fault released torque."""
        ...

    def goal_packet(self, goals_steps: Mapping[int, int]) -> bytes:
        """One frame's goal changes, encoded, after checking each against its pin's limits."""
        ...

    def prepare(self, targets: Targets, pulses: Pulses) -> PreparedTrial:
        """A trial's frames encoded for the wire before onset, limits checked.

        Raises `pinarray.errors.PinArrayError` for a trial this array cannot play as
        scheduled (outside a pin's limits; a PWM board: pulses its period cannot place within
        the protocol's tolerance), saying what to change.
        """
        ...

    def begin(self, trial: PreparedTrial, onset_ns: int) -> None:
        """In the lead time before ``onset_ns``: ready the hardware for ``trial``'s frames."""
        ...

    def send_goals(self, packet: bytes,
                   goals_steps: Mapping[int, int] | tuple[tuple[int, int], ...]) -> None:
        """Write a frame prepared by `goal_packet`, in one call, without waiting for a reply."""
        ...

    def verifier(self, clock: Clock, trial: PreparedTrial, onset_ns: int,
                 ledger: DeliveryLedger) -> FrameVerifier:
        """This driver's verification of ``trial`` played from ``onset_ns`` on ``clock``."""
        ...

    def heal_time_ns(self, changes_per_frame: int) -> int:
        """Verifying a frame of that many changes and healing one, as this port usually takes."""
        ...

    def move_to_rest(self, timeout_ns: int = ...) -> tuple[int, ...]:
        """Every pin to rest; the ids confirmed there."""
        ...

    def assume_goals(self, goals_steps: Mapping[int, int]) -> None:
        """Another process (the player's) left these goals on the servos."""
        ...

    def read_telemetry(self, servo_ids: tuple[int, ...]) -> tuple[Telemetry, ...]: ...

    def rest_and_release(self) -> SafeStopReport:
        """Pins to rest, then torque off, wherever the servos answer. Never raises."""
        ...

    def handover(self) -> Handover: ...

    def stats(self) -> BusStats: ...

    def close(self) -> None: ...
