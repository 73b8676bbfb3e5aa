"""Plays a trial's goal changes against absolute deadlines and verifies that they arrived.

Any `ArrayDriver` (`pinarray.hardware.driver`) can be played. Before onset every frame is
encoded by the driver (`prepare_trial`) and the driver readies its hardware in the lead time
(`ArrayDriver.begin`), so at each deadline the loop does one thing: hand
prepared bytes to the port in one call. Frame ``k`` goes out at ``onset + time_ns[k]``
(never "period minus elapsed", so a late frame does not push the later ones), with the
garbage collector frozen and paused for the trial.

In the slack between frames the driver's `FrameVerifier` confirms each goal change on its
servo (Feetech: reads it back, and writes again, acknowledged, a goal the servo does not hold,
counted as healed with how late it arrived), never past the next frame's deadline. The
trial's `DeliveryRecord` says whether it was delivered as scheduled. With the changes
confirmed and time left before the next frame, the verifier samples where the moving pins are
(`FrameVerifier.sample_until`: Feetech servos report it, PWM servos cannot); the samples give
each pin's achieved stroke (`pinarray.hardware.motion`), and a pin that fell short of the
protocol's stroke tolerance makes the trial not delivered as specified. Telemetry is read only
after the trial's last frame.

Given an `Announcer` and the trial's markers (`pinarray.player.markers`), the onset marker goes
out right after the onset frame's write (in the slack, as the read-backs: never delaying a
frame) and the offset marker at the trial's end, both stamped on the schedule's times.

Safety: a schedule that would take any pin outside its calibrated limits is refused before
anything is sent, and every way out of `play_prepared` (normal end, exception, a stop request,
a lost port) first puts pins at rest and torque off where the hardware still answers.
"""

from __future__ import annotations

import gc
from array import array
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from fractions import Fraction
from functools import cached_property
from typing import TYPE_CHECKING

from pinarray.clock import Clock
from pinarray.errors import BusError, Interrupted, PinArrayError
from pinarray.hardware.delivery import (
    DEFAULT_TOLERANCE_NS,
    DeliveryLedger,
    DeliveryRecord,
    PreparedTrial,
)
from pinarray.hardware.driver import (
    ArrayDriver,
    ArraySetup,
    PortLost,
    SafeStopReport,
    Telemetry,
)
from pinarray.hardware.frames import check_limits
from pinarray.hardware.motion import DEFAULT_STROKE_TOLERANCE, PinTrace, Samples, measure_trial
from pinarray.player.markers import Announcer, MarkerPush, TrialMarkers

# No numpy at import, nor while a trial plays: the player process plays trials and never
# imports it (some 100 ms of processor at each of its starts). A report's frame times and
# samples are kept as the player keeps them and become numpy arrays where they are read
# (`PlaybackReport.sent_ns`, ...): in the process that asked for the trial.
if TYPE_CHECKING:
    import numpy as np

    from pinarray.schedule import PulseList, TargetList

__all__ = ["SOON", "Onset", "OnsetAfter", "OnsetAt", "Suspended", "check_limits", "play_prepared",
           "play_trial", "prepare_trial"]

# Time between "go" and the first frame, so frame 0 is not late by construction.
DEFAULT_LEAD_NS = 20_000_000
# Read-backs stop this long before the next frame is due, so they never delay it.
GUARD_NS = 300_000
# After the trial's end, read-backs may go on this long to confirm the last changes.
SETTLE_NS = 200_000_000
# Generations 0 and 1 (`gc.collect`'s argument): what a trial leaves behind, not the process.
YOUNG_GENERATIONS = 1


@dataclass(frozen=True)
class OnsetAfter:
    """The trial's time zero ``lead_ns`` after playback is asked for (a session's trials)."""

    lead_ns: int = DEFAULT_LEAD_NS


@dataclass(frozen=True)
class OnsetAt:
    """The trial's time zero at ``onset_ns`` on the player's clock: a stimulus armed by a
    script for a moment of its choosing (a screen flip). Frames are played from there, so a
    script's visual and tactile onsets share one time line."""

    onset_ns: int


Onset = OnsetAfter | OnsetAt
SOON = OnsetAfter()  # the default: a session's trial, `DEFAULT_LEAD_NS` after it is asked for


class PlaybackAborted(PinArrayError):
    """Playback stopped early by a fault (the bus failing mid-stimulus, a servo's error):
    the message says where and how the pins were left; ``safe_stop`` is the `SafeStopReport`
    of the safe stop made on the way out."""

    def __init__(self, message: str, safe_stop: SafeStopReport):
        super().__init__(message)
        self.safe_stop = safe_stop


class OnsetPassed(PlaybackAborted):
    """An onset that had passed by the time playback could begin (the host stalled): refused
    before anything was sent; ``late_ns`` is by how much it had passed."""

    def __init__(self, message: str, late_ns: int):
        super().__init__(message, SafeStopReport((), (), ()))
        self.late_ns = late_ns


class Suspended(PlaybackAborted):
    """The process controlling a player process was suspended (Ctrl-Z, SIGSTOP) while a
    stimulus played or waited for its onset: the player process cut it, rested the pins and
    released torque rather than play on with nobody able to stop it.

    ``noticed_ns`` is when the player saw it (``time.monotonic_ns()``): whether the stimulus
    had begun by then says whether it was cut or never started.
    """

    def __init__(self, message: str, safe_stop: SafeStopReport, noticed_ns: int):
        super().__init__(message, safe_stop)
        self.noticed_ns = noticed_ns


@dataclass(frozen=True, eq=False)
class PlaybackReport:
    """What happened when one trial was played.

    Attributes
    ----------
    onset_ns : int
        Clock time of the trial's time zero, in nanoseconds.
    due_ns, written_ns : array.array
        Per frame, when it was due and when its write returned, both relative to onset, in
        nanoseconds (``array('q')``, as the player keeps them): the sender's view; the bench
        measures the servo's. `scheduled_ns` and `sent_ns` are the same as numpy arrays.
    goals_written : int
        Servo goals sent by the frames (a frame carries only the servos whose goal changed).
    bytes_written, bytes_read : int
        Bytes the host put on and took off the wire during the trial, read-backs included.
    retries : int
        Transient failures retried during the trial.
    delivery : DeliveryRecord
        Which goal changes were confirmed on their servo, healed or missing.
    telemetry : tuple of Telemetry
        Readings taken right after the trial.
    safe_stop : SafeStopReport or None
        Result of resting and releasing the pins, when the trial ended with it.
    markers_sent : int
        Markers announced for the trial (0, 1 or 2; 0 when none were asked for).
    marker_problem : str
        Empty unless a marker asked for could not be sent: what went wrong (the trial is
        played all the same).
    samples : tuple of PinTrace or PinSamples
        The moving pins' sampled positions as the verifier kept them (empty: not sampled, or
        the servos cannot say); `trace` is the same as numpy arrays.
    """

    onset_ns: int
    due_ns: array
    written_ns: array
    goals_written: int
    bytes_written: int
    bytes_read: int
    retries: int
    delivery: DeliveryRecord
    telemetry: tuple[Telemetry, ...] = ()
    safe_stop: SafeStopReport | None = None
    markers_sent: int = 0
    marker_problem: str = ""
    samples: tuple[Samples, ...] = ()

    # The numpy views of the columns, made once where first read (never in the player process).
    @cached_property
    def scheduled_ns(self) -> np.ndarray:
        """When each frame was due, ns after onset (int64)."""
        return _int64s(self.due_ns)

    @cached_property
    def sent_ns(self) -> np.ndarray:
        """When each frame's write returned, ns after onset (int64)."""
        return _int64s(self.written_ns)

    @cached_property
    def errors_ns(self) -> np.ndarray:
        """How late each frame's write returned, in ns (int64)."""
        errors: np.ndarray = self.sent_ns - self.scheduled_ns
        return errors

    @cached_property
    def trace(self) -> tuple[PinTrace, ...]:
        """The moving pins' sampled positions as numpy arrays (see `samples`)."""
        return tuple(t if isinstance(t, PinTrace) else PinTrace.of(t) for t in self.samples)

    @property
    def frames_sent(self) -> int:
        return len(self.written_ns)

    @property
    def bytes_on_wire(self) -> int:
        return self.bytes_written + self.bytes_read

    @classmethod
    def merged(cls, reports: list[PlaybackReport]) -> PlaybackReport:
        """Several trials as one report (frame times stay relative to each trial's onset)."""

        def joined(name: str) -> array:
            column = array("q")
            for report in reports:
                column.extend(getattr(report, name))
            return column

        records = [r.delivery for r in reports]
        delivery = DeliveryRecord(
            scheduled=sum(d.scheduled for d in records),
            confirmed=sum(d.confirmed for d in records),
            healed=sum(d.healed for d in records),
            missing=sum(d.missing for d in records),
            worst_lateness_ns=max((d.worst_lateness_ns for d in records), default=0),
            tolerance_ns=records[0].tolerance_ns if records else DEFAULT_TOLERANCE_NS,
            problem=next((d.problem for d in records if d.problem), ""),
        )
        return cls(
            onset_ns=reports[0].onset_ns if reports else 0,
            due_ns=joined("due_ns"),
            written_ns=joined("written_ns"),
            goals_written=sum(r.goals_written for r in reports),
            bytes_written=sum(r.bytes_written for r in reports),
            bytes_read=sum(r.bytes_read for r in reports),
            retries=sum(r.retries for r in reports),
            delivery=delivery,
            telemetry=tuple(t for r in reports for t in r.telemetry),
            markers_sent=sum(r.markers_sent for r in reports),
            marker_problem=next((r.marker_problem for r in reports if r.marker_problem), ""),
        )

    def deadline_error_ns(self, percentile: float) -> int:
        """Lateness of the frames' writes at ``percentile`` (0-100), in nanoseconds."""
        if not len(self.errors_ns):
            return 0
        import numpy as np

        return int(np.percentile(self.errors_ns, percentile, method="higher"))

    def summary(self) -> str:
        """One line: frames, bytes, write lateness p50/p99/max, delivery."""
        p50, p99, worst = (self.deadline_error_ns(p) / 1e6 for p in (50, 99, 100))
        return (
            f"{self.frames_sent} frames, {self.bytes_on_wire} bytes on the wire, "
            f"write lateness p50 {p50:.3f} ms, p99 {p99:.3f} ms, max {worst:.3f} ms; "
            f"{self.delivery.summary()}"
        )


def prepare_trial(bus: ArrayDriver, targets: TargetList,
                  pulses: PulseList | None = None) -> PreparedTrial:
    """The driver's frames for a trial, encoded before onset (see `ArrayDriver.prepare`).

    Without ``pulses`` (a bare list of goal changes), a family that places pulses plays
    every change at its own pulse rate.
    """
    return bus.prepare(targets, pulses if pulses is not None else _no_pulses())


def _no_pulses() -> PulseList:
    import numpy as np

    from pinarray.schedule import PulseList

    return PulseList(np.zeros(0, dtype=np.int16), np.zeros(0, dtype=np.int64),
                     np.zeros(0, dtype=np.int64))


def _int64s(column: array) -> np.ndarray:
    """An ``array('q')`` as a numpy array of its own."""
    import numpy as np

    return np.frombuffer(column, dtype=np.int64).copy()


@contextmanager
def gc_paused() -> Iterator[None]:
    """Keep the garbage collector out of the trial (a pass can take milliseconds).

    Only the young generations are collected first: a full pass over a process that holds the
    UI took 100 ms before every trial, and the old objects it walks are not the trial's. The
    collector's own thresholds see to the rest between trials.
    """
    enabled = gc.isenabled()
    gc.collect(YOUNG_GENERATIONS)
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def play_prepared(
    bus: ArrayDriver,
    trial: PreparedTrial,
    clock: Clock,
    *,
    onset: Onset = SOON,
    tolerance_ns: int = DEFAULT_TOLERANCE_NS,
    guard_ns: int = GUARD_NS,
    release_at_end: bool = True,
    markers: TrialMarkers | None = None,
    announcer: Announcer | None = None,
    stroke_tolerance: Fraction = DEFAULT_STROKE_TOLERANCE,
    sample_motion: bool = True,
) -> PlaybackReport:
    """Play a prepared trial against absolute deadlines, verifying every goal change.

    Parameters
    ----------
    bus : ArrayDriver
        A connected array (torque on), e.g. a Feetech bus from
        `pinarray.hardware.feetech.transport.open_bus`.
    trial : PreparedTrial
        From `prepare_trial`.
    clock : Clock
        The clock the bus uses too, or one that wraps it and raises `Interrupted` when a
        stop is requested (`pinarray.stop.StoppableClock`).
    onset : Onset
        When the trial's time zero is: a lead after the call (`OnsetAfter`, in ns), or a
        time on ``clock`` (`OnsetAt`). One that has passed by the time playback can begin is
        refused before anything is sent (`PlaybackAborted`, nothing touched).
    tolerance_ns : int
        How late a goal change may reach its servo and still count as delivered.
    guard_ns : int
        Read-backs end this long before the next frame is due.
    release_at_end : bool
        After a normal end, rest and release torque (True), or leave the pins holding rest
        for the next trial (False; the caller makes them safe at the end).
    markers, announcer : TrialMarkers and Announcer, optional
        Announce ``markers`` through ``announcer`` (opened on ``clock``): the onset marker
        after the write of the first frame at or after onset, as soon as the slack before the
        next frame allows (at once in practice), the offset marker at ``trial.end_ns``.
    stroke_tolerance : Fraction
        A moving pin whose achieved stroke is below this share of its commanded stroke
        makes the trial not delivered as specified.
    sample_motion : bool
        Sample the moving pins' positions in the slack (False: read-backs only, as for a
        benchmark's comparison; the delivery record then has no strokes).

    Returns
    -------
    PlaybackReport
        Including its `DeliveryRecord`; a trial not delivered as scheduled is reported, not
        raised: the caller marks it invalid.
    """
    setup = bus.setup
    frames = trial.frames
    count = len(frames)
    scheduled = array("q", [f.time_ns for f in frames])
    sent = array("q", bytes(8 * count))
    ledger = DeliveryLedger(trial.changes, tolerance_ns)
    push = MarkerPush(announcer, markers) if announcer is not None and markers is not None else None
    # The onset frame: the first at or after time zero (none: the onset marker goes at the end).
    onset_frame = next((k for k, f in enumerate(frames) if f.time_ns >= 0), count)
    before = bus.stats()
    index = 0
    with gc_paused():
        onset_ns = _onset_ns(onset, clock)
        verifier = bus.verifier(clock, trial, onset_ns, ledger)
        try:
            bus.begin(trial, onset_ns)
            for index in range(count):
                frame = frames[index]
                deadline_ns = onset_ns + frame.time_ns
                verifier.work_until(deadline_ns - guard_ns)
                if sample_motion:
                    verifier.sample_until(deadline_ns - guard_ns)
                clock.sleep_until_ns(deadline_ns)
                bus.send_goals(frame.packet, frame.goals)
                sent[index] = clock.now_ns() - onset_ns
                verifier.sent(frame, sent[index])
                if push is not None and not push.onset_sent and index >= onset_frame:
                    next_ns = onset_ns + (frames[index + 1].time_ns if index + 1 < count
                                          else trial.end_ns)
                    if clock.now_ns() < next_ns - guard_ns:  # else after the next frame's write
                        push.onset(onset_ns)
            index = count
            end_ns = onset_ns + trial.end_ns
            verifier.work_until(end_ns)
            if sample_motion:
                verifier.sample_until(end_ns)
            clock.sleep_until_ns(end_ns)
            if push is not None:
                if not push.onset_sent:
                    push.onset(onset_ns)
                push.offset(end_ns)
            verifier.work_until(end_ns + SETTLE_NS)
            if verifier.pending:
                # A change of the trial's end never confirmed may have left a pin up.
                _rest(bus, tuple(verifier.pending))
            readings = _checked(_telemetry(bus, setup.servo_ids), setup)
            trace = verifier.trace() if sample_motion else ()
        except Interrupted as stopped:
            # Asked to stop: pins first, then let the caller wind down (knowing how they were left).
            stopped.safe_stop = bus.rest_and_release()
            raise
        except PinArrayError as error:
            safe = bus.rest_and_release()
            where = f"at frame {index + 1} of {count}" if index < count else "after the last frame"
            raise PlaybackAborted(f"playback stopped {where}: {error}; {safe.describe()}",
                                  safe) from error
        except BaseException:
            bus.rest_and_release()  # Ctrl-C and anything unexpected: pins first, then re-raise
            raise
    safe_stop = bus.rest_and_release() if release_at_end else None
    after = bus.stats()
    return PlaybackReport(
        onset_ns=onset_ns,
        due_ns=scheduled,
        written_ns=sent,
        goals_written=after.goals_written - before.goals_written,
        bytes_written=after.bytes_written - before.bytes_written,
        bytes_read=after.bytes_read - before.bytes_read,
        retries=after.retries - before.retries,
        delivery=ledger.record(
            measure_trial(trace, trial.changes, trial.end_ns, stroke_tolerance) if trace else None),
        telemetry=readings,
        safe_stop=safe_stop,
        markers_sent=push.sent if push is not None else 0,
        marker_problem=push.problem if push is not None else "",
        samples=trace,
    )


def _onset_ns(onset: Onset, clock: Clock) -> int:
    """The trial's time zero on ``clock``; an armed one that has passed is refused."""
    match onset:
        case OnsetAfter(lead_ns=lead_ns):
            return clock.now_ns() + lead_ns
        case OnsetAt(onset_ns=onset_ns):
            late_ns = clock.now_ns() - onset_ns
            if late_ns > 0:
                raise OnsetPassed(
                    f"the onset asked for had passed {late_ns / 1e6:.1f} ms before playback "
                    f"could begin: arm a stimulus at least {DEFAULT_LEAD_NS / 1e6:g} ms ahead",
                    late_ns)
            return onset_ns
    raise AssertionError(onset)


def play_trial(bus: ArrayDriver, targets: TargetList, clock: Clock, *,
               release_at_end: bool = True) -> PlaybackReport:
    """`prepare_trial` then `play_prepared` (default timing), in this process."""
    return play_prepared(bus, prepare_trial(bus, targets), clock, release_at_end=release_at_end)


def _rest(bus: ArrayDriver, unconfirmed: tuple[int, ...]) -> None:
    """Every pin to rest, confirmed; a servo left unconfirmed that does not get there is a fault."""
    at_rest = bus.move_to_rest()
    stuck = [i for i in unconfirmed if i not in at_rest]
    if stuck:
        raise BusError(f"servo(s) {', '.join(map(str, stuck))} did not confirm their last goal "
                       "of the trial nor return to rest")


def _telemetry(bus: ArrayDriver, servo_ids: tuple[int, ...]) -> tuple[Telemetry, ...]:
    """Each servo's state after the trial; one that does not answer now is skipped (the
    delivery record already says what reached it, and the next trial's read-backs will tell)."""
    readings: list[Telemetry] = []
    for servo_id in servo_ids:
        try:
            readings.extend(bus.read_telemetry((servo_id,)))
        except PortLost:
            raise
        except BusError:
            continue
    return tuple(readings)


def _checked(readings: tuple[Telemetry, ...], setup: ArraySetup) -> tuple[Telemetry, ...]:
    faulty = [r for r in readings if r.errors]
    if faulty:
        pins = {s.servo_id: s.pin for s in setup.servos}
        text = ", ".join(
            f"servo {r.servo_id} (pin {pins.get(r.servo_id)}) reports {r.errors.describe()}"
            for r in faulty
        )
        raise BusError(f"servo fault: {text}")
    return readings


@contextmanager
def pins_made_safe(bus: ArrayDriver) -> Iterator[None]:
    """Around a whole session: however it ends, pins go to rest and torque off."""
    try:
        yield
    finally:
        bus.rest_and_release()
