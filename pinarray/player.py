"""Plays a trial's goal-position changes on a servo bus against absolute deadlines.

Frame ``k`` is sent at ``onset + time_ns[k]`` by ``clock.sleep_until_ns``; the loop never
sleeps "period minus elapsed", so a late frame does not push every later one. Scheduled and
actual send times of every frame are kept for the report.

Safety: a schedule that would take any pin outside its calibrated limits is refused before
anything is sent, and every way out of `play_trial` (normal end, exception, Ctrl-C, SIGTERM
turned into `Terminated`, a lost port) first puts pins at rest and torque off where the bus
still answers.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from pinarray.bus.base import Bus, BusSetup, SafeStopReport, Telemetry
from pinarray.bus.registers import StatusError
from pinarray.clock import Clock
from pinarray.errors import BusError, Interrupted, PinArrayError
from pinarray.schedule import TargetList

# Time between "go" and the first frame, so frame 0 is not late by construction.
DEFAULT_LEAD_NS = 20_000_000
# Telemetry is read only when the next frame is at least this far away.
TELEMETRY_SLACK_NS = 5_000_000


class Terminated(Interrupted):
    """The process was asked to stop (SIGTERM); raised inside playback so pins go to rest."""


class PlaybackAborted(PinArrayError):
    """Playback stopped early; says why and what the safe stop achieved."""

    def __init__(self, message: str, safe_stop: SafeStopReport):
        super().__init__(message)
        self.safe_stop = safe_stop


@dataclass(frozen=True, eq=False)
class PlaybackReport:
    """What happened when one trial was played.

    Attributes
    ----------
    onset_ns : int
        Clock time of the trial's time zero, in nanoseconds.
    scheduled_ns, sent_ns : numpy.ndarray
        Per frame, when it was due and when it was handed to the port, both relative to
        onset, in nanoseconds (int64).
    goals_written : int
        Servo goals sent (a frame carries only the servos whose goal changed).
    bytes_written, bytes_read : int
        Bytes the host put on and took off the wire during the trial.
    retries : int
        Transient failures retried during the trial.
    telemetry : tuple of Telemetry
        Readings taken during and right after the trial.
    safe_stop : SafeStopReport or None
        Result of resting and releasing the pins, when the trial ended with it.
    """

    onset_ns: int
    scheduled_ns: np.ndarray
    sent_ns: np.ndarray
    goals_written: int
    bytes_written: int
    bytes_read: int
    retries: int
    telemetry: tuple[Telemetry, ...] = ()
    safe_stop: SafeStopReport | None = None
    errors_ns: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "errors_ns", self.sent_ns - self.scheduled_ns)

    @property
    def frames_sent(self) -> int:
        return len(self.sent_ns)

    @property
    def bytes_on_wire(self) -> int:
        return self.bytes_written + self.bytes_read

    @classmethod
    def merged(cls, reports: list[PlaybackReport]) -> PlaybackReport:
        """Several trials as one report (frame times stay relative to each trial's onset)."""

        def joined(name: str) -> np.ndarray:
            arrays = [getattr(r, name) for r in reports]
            return np.concatenate(arrays) if arrays else np.zeros(0, dtype=np.int64)

        return cls(
            onset_ns=reports[0].onset_ns if reports else 0,
            scheduled_ns=joined("scheduled_ns"),
            sent_ns=joined("sent_ns"),
            goals_written=sum(r.goals_written for r in reports),
            bytes_written=sum(r.bytes_written for r in reports),
            bytes_read=sum(r.bytes_read for r in reports),
            retries=sum(r.retries for r in reports),
            telemetry=tuple(t for r in reports for t in r.telemetry),
        )

    def deadline_error_ns(self, percentile: float) -> int:
        """Lateness of the frames at ``percentile`` (0-100), in nanoseconds."""
        if not len(self.errors_ns):
            return 0
        return int(np.percentile(self.errors_ns, percentile, method="higher"))

    def summary(self) -> str:
        """One line: frames, bytes, deadline error p50/p99/max."""
        p50, p99, worst = (self.deadline_error_ns(p) / 1e6 for p in (50, 99, 100))
        return (
            f"{self.frames_sent} frames sent, {self.bytes_on_wire} bytes on the wire, "
            f"deadline error p50 {p50:.3f} ms, p99 {p99:.3f} ms, max {worst:.3f} ms"
        )


def check_limits(targets: TargetList, setup: BusSetup) -> None:
    """Refuse a target list that would take any pin outside its calibrated limits.

    Raises
    ------
    PinArrayError
        Naming the pin, its servo id, the offending position and time, and the limits.
    """
    by_pin = {s.pin: s for s in setup.servos}
    for pin in np.unique(targets.pin):
        servo = by_pin.get(int(pin))
        if servo is None:
            known = ", ".join(map(str, sorted(by_pin)))
            raise PinArrayError(f"the schedule moves pin {pin}, which has no servo (pins: {known})")
        mask = targets.pin == pin
        positions = targets.position_steps[mask]
        outside = (positions < servo.min_steps) | (positions > servo.max_steps)
        if outside.any():
            first = int(np.argmax(outside))
            time_s = targets.time_ns[mask][first] / 1e9
            raise PinArrayError(
                f"refusing to play: pin {pin} (servo {servo.servo_id}) would go to "
                f"{positions[first]} steps at {time_s:.3f} s, outside its calibrated limits "
                f"{servo.min_steps}..{servo.max_steps}"
            )


def play_trial(
    bus: Bus,
    targets: TargetList,
    clock: Clock,
    *,
    lead_ns: int = DEFAULT_LEAD_NS,
    telemetry_interval_ns: int | None = 1_000_000_000,
    release_at_end: bool = True,
) -> PlaybackReport:
    """Play one trial's goal-position changes against absolute deadlines.

    Parameters
    ----------
    bus : Bus
        A connected bus (torque on); `pinarray.bus.transport.open_bus`.
    targets : TargetList
        The trial's target changes, times relative to trial onset.
    clock : Clock
        The clock the bus uses too (virtual, scaled or monotonic).
    lead_ns : int
        Delay from the call to the trial onset, in nanoseconds.
    telemetry_interval_ns : int or None
        How often to read one servo's telemetry when there is slack; None: never during
        the trial. Any status error bit stops the trial.
    release_at_end : bool
        After a normal end, rest and release torque (True), or leave the pins holding rest
        for the next trial (False; wrap the session in `pins_made_safe`).

    Returns
    -------
    PlaybackReport
    """
    setup = bus.setup
    check_limits(targets, setup)
    servo_of_pin = {s.pin: s.servo_id for s in setup.servos}
    frames = list(targets.frames())
    scheduled = np.fromiter((f.time_ns for f in frames), dtype=np.int64, count=len(frames))
    sent = np.zeros(len(frames), dtype=np.int64)
    before = bus.stats()
    readings: list[Telemetry] = []
    ids = setup.servo_ids
    next_reading_ns = 0
    index = 0
    onset_ns = clock.now_ns() + lead_ns
    try:
        for index, frame in enumerate(frames):
            clock.sleep_until_ns(onset_ns + frame.time_ns)
            goals = {
                servo_of_pin[int(pin)]: int(position)
                for pin, position in zip(frame.pins, frame.position_steps, strict=True)
            }
            bus.write_goals(goals)
            sent[index] = clock.now_ns() - onset_ns
            if telemetry_interval_ns is not None and ids:
                upcoming_ns = frames[index + 1].time_ns if index + 1 < len(frames) else None
                now_ns = clock.now_ns() - onset_ns
                slack = upcoming_ns is None or upcoming_ns - now_ns >= TELEMETRY_SLACK_NS
                if slack and now_ns >= next_reading_ns:
                    servo_id = ids[len(readings) % len(ids)]
                    readings.extend(_checked(bus.read_telemetry((servo_id,)), setup))
                    next_reading_ns = now_ns + telemetry_interval_ns
        index = len(frames)
        clock.sleep_until_ns(onset_ns + targets.end_ns)
        readings.extend(_checked(bus.read_telemetry(ids), setup))
    except Interrupted:
        bus.rest_and_release()  # asked to stop: pins first, then let the caller wind down
        raise
    except PinArrayError as error:
        safe = bus.rest_and_release()
        where = f"at frame {index + 1} of {len(frames)}" if index < len(frames) else "after the last frame"
        raise PlaybackAborted(
            f"playback stopped {where}: {error}; {describe(safe)}",
            safe,
        ) from error
    except BaseException:
        bus.rest_and_release()  # Ctrl-C and anything unexpected: pins first, then re-raise
        raise
    safe_stop = bus.rest_and_release() if release_at_end else None
    after = bus.stats()
    return PlaybackReport(
        onset_ns=onset_ns,
        scheduled_ns=scheduled,
        sent_ns=sent,
        goals_written=after.goals_written - before.goals_written,
        bytes_written=after.bytes_written - before.bytes_written,
        bytes_read=after.bytes_read - before.bytes_read,
        retries=after.retries - before.retries,
        telemetry=tuple(readings),
        safe_stop=safe_stop,
    )


def _checked(readings: tuple[Telemetry, ...], setup: BusSetup) -> tuple[Telemetry, ...]:
    faulty = [r for r in readings if r.errors != StatusError(0)]
    if faulty:
        pins = {s.servo_id: s.pin for s in setup.servos}
        text = ", ".join(
            f"servo {r.servo_id} (pin {pins.get(r.servo_id)}) reports {r.errors.describe()}"
            for r in faulty
        )
        raise BusError(f"servo fault: {text}")
    return readings


def describe(safe: SafeStopReport) -> str:
    """How safe the pins are after a stop, in one clause."""
    if safe.port_lost and not safe.released_ids:
        return "port lost: could not reach any servo; cut servo power"
    text = f"{len(safe.at_rest_ids)} servo(s) at rest, {len(safe.released_ids)} released"
    if safe.silent_ids:
        text += f"; servo(s) {', '.join(map(str, safe.silent_ids))} not confirmed safe"
    return text


@contextmanager
def pins_made_safe(bus: Bus) -> Iterator[None]:
    """Around a whole session: however it ends, pins go to rest and torque off."""
    try:
        yield
    finally:
        bus.rest_and_release()


@contextmanager
def sigterm_raises() -> Iterator[None]:
    """Turn SIGTERM into `Terminated` inside the block, so playback stops through `finally`.

    For composition roots (CLI, TUI) only; does nothing outside the main thread.
    """

    def handler(signum, frame):
        raise Terminated("terminated by SIGTERM")

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
