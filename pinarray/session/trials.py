"""The session engine: one subject's run through a plan, as a state machine. No UI code.

    instructions -> [ready -> stimulus -> response] x N -> done
                     pause/resume from ready, stimulus or response; redo from response;
                     abort (with a reason) from anywhere before done

A pause asked for while a trial is being presented (the inter-trial interval or the stimulus)
takes effect when `present` returns: the caller cuts the stimulus short through its stop
request, the trial is logged as cut short, and after resume the same trial is ready again.
Without a stop the stimulus plays to its end and the run holds at the answer.

Each trial row is written (and fsync'd) by the `RunWriter` the moment the trial ends, so the
engine can be killed at any point and resumed with exactly the remaining trials. The engine
is driven by a caller: `pinarray batch` loops over it, the TUI calls it from a worker. It
waits only through its `Clock` (the inter-trial interval) and the `Stimulator` (the stimulus).

Times are integer nanoseconds on the run's time base (`pinarray.journal.timebase`): from the
run's time zero, which is the first trial's stimulus onset unless the session is told another
(``time_zero_ns``, a time on its clock); a resumed sitting continues where the writer says its
clock joins the run.

Past 400 lines on purpose: the state machine's transitions and the rows they write are one
thing to read (a trial's row is written by the transition that ends it).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, NamedTuple
from typing import Protocol as Interface

from pinarray.clock import Clock
from pinarray.errors import Interrupted, PinArrayError
from pinarray.grid import Grid
from pinarray.hardware.delivery import DeliveryRecord, Presentation
from pinarray.hardware.motion import PinTrace, TrialStrokes, goal_at
from pinarray.journal.manifest import RunStatus
from pinarray.journal.physio import MotionColumns
from pinarray.journal.records import (
    DeliveryCounts,
    StrokeCounts,
    TrialFields,
    TrialRecord,
    TrialStatus,
)
from pinarray.journal.timebase import FIRST_TRIAL_ONSET
from pinarray.journal.writer import RunWriter
from pinarray.plan import PlannedTrial, TrialPlan
from pinarray.protocol.adapted import adapted
from pinarray.protocol.drives import trial_drives
from pinarray.protocol.load import task_label as protocol_task_label
from pinarray.protocol.model import Condition, Protocol
from pinarray.schedule import TrialSchedule, compile_drives
from pinarray.stop import deferred_signals

if TYPE_CHECKING:  # an adaptive design's procedures are imported by the session that has one
    from pinarray.adaptive.questplus import QuestPlus as QuestPlusMachine
    from pinarray.session.procedures import Presented, Procedures

PAUSE_CUT_SHORT = "cut short by a pause"  # the reason logged for a stimulus a pause stopped


def _stroke(strokes: TrialStrokes | None) -> StrokeCounts | None:
    """What the results keep of the pins' measured motion: the pin that moved least, by share."""
    if strokes is None or not strokes.pins:
        return None
    pin = strokes.worst or strokes.pins[0]
    return StrokeCounts(pin.commanded_steps, pin.achieved_steps, pin.median_steps, pin.lag_ns,
                        pin.short_cycles if pin.measured else None)


def _samples(trial: int, onset_ns: int, traces: tuple[PinTrace, ...],
             schedule: TrialSchedule) -> MotionColumns:
    """A trial's sampled positions as rows of the run's motion recording, in time order (then
    pin, position and goal, as `MotionSample` tuples sort)."""
    import numpy as np  # the traces are numpy arrays already; the engine itself needs none

    times, pins, positions, goals = [], [], [], []
    for trace in traces:
        mine = schedule.targets.pin == trace.pin
        changes = list(zip(schedule.targets.time_ns[mine].tolist(),
                           schedule.targets.position_steps[mine].tolist(), strict=True))
        goals.append(goal_at(changes, trace.time_ns))  # -1 before the first change
        times.append(trace.time_ns + onset_ns)
        pins.append(np.full(len(trace.time_ns), trace.pin, np.int64))
        positions.append(trace.position_steps.astype(np.int64))
    time_ns, pin, position, goal = (np.concatenate(column)
                                    for column in (times, pins, positions, goals))
    order = np.lexsort((goal, position, pin, time_ns))
    goal = goal[order]
    return MotionColumns(time_ns[order], np.full(len(order), trial, np.int64), pin[order],
                         position[order], goal, goal >= 0)


def _counts(delivery: DeliveryRecord) -> DeliveryCounts:
    """What the results keep of a trial's delivery record (its verdict is the trial's status)."""
    return DeliveryCounts(scheduled=delivery.scheduled, confirmed=delivery.confirmed,
                          healed=delivery.healed, missing=delivery.missing,
                          lateness_ns=delivery.worst_lateness_ns)


class Phase(StrEnum):
    INSTRUCTIONS = "instructions"
    READY = "ready"  # the next trial is waiting to be presented
    STIMULUS = "stimulus"  # the pins are moving
    RESPONSE = "response"  # waiting for the subject's answer
    FAULT = "fault"  # the stimulus failed; retry or abort
    PAUSED = "paused"
    DONE = "done"
    ABORTED = "aborted"


class SessionError(PinArrayError):
    """An action the session cannot take now, or a response it cannot accept."""


class Stimulator(Interface):
    """What presents a compiled trial: real or simulated servos, or nothing at all."""

    def present(self, schedule: TrialSchedule) -> Presentation:
        """Play the trial; return its onset (clock ns) and whether it was delivered as scheduled."""
        ...


class OnsetGate(Interface):
    """What may hold a trial back after its inter-trial interval, e.g. until a scanner volume."""

    def wait_for_onset(self, ready_ns: int) -> None:
        """Return when a trial ready since ``ready_ns`` (session clock ns) may start."""
        ...


MEASURED = object()  # respond(): take the response time from the session's clock


class TrialNumber(NamedTuple):
    """Where a trial stands for the experimenter: practice and counted trials numbered apart."""

    practice: bool
    number: int  # 1-based among the plan's trials of the same kind
    of: int  # how many trials of that kind the plan has

    def __str__(self) -> str:
        return f"{'practice' if self.practice else 'trial'} {self.number} of {self.of}"


@dataclass(frozen=True)
class TrialOutcome:
    """What the last finished trial was, for live counts on a screen."""

    record: TrialRecord
    remaining: int


def task_label(protocol: Protocol) -> str:
    """The BIDS task label: the protocol's name with anything but letters and digits dropped
    (what a protocol file names, `pinarray.protocol.load` has checked)."""
    label = protocol_task_label(protocol.name)
    if not label:
        raise PinArrayError(f"{protocol.source}: the protocol name {protocol.name!r} has no letters or digits for a task label")
    return label


class Session:
    """One run of a protocol for one subject.

    Parameters
    ----------
    protocol, plan
        What to present, and in which order (the plan saved in the run's manifest).
    writer
        The run's results writer (new or resumed).
    stimulator
        Presents each trial; its exceptions (`PinArrayError`) put the session in FAULT.
    clock
        Measures onsets and response times and waits out the inter-trial interval.
    on_change
        Called with the session after every state change (the UI refreshes from it).
    time_zero_ns
        The run's time zero on ``clock`` (e.g. the first counted scanner volume); None: the
        first trial's stimulus onset. Only a run whose zero is not fixed yet can be told one.
    time_zero_event
        What ``time_zero_ns`` is, in words, for the manifest and the sidecars.
    gate
        Holds each trial, once its interval is over, until it may start (onsets locked to
        scanner volumes); None: trials start when their interval ends.
    """

    def __init__(self, protocol: Protocol, plan: TrialPlan, writer: RunWriter, stimulator: Stimulator,
                 clock: Clock, on_change: Callable[[Session], None] | None = None,
                 time_zero_ns: int | None = None, time_zero_event: str = "a time given to the session",
                 gate: OnsetGate | None = None,
                 prepared: Mapping[str, QuestPlusMachine] | None = None):
        self.protocol = protocol
        self.plan = plan
        self.writer = writer
        self.stimulator = stimulator
        self.clock = clock
        self.on_change = on_change or (lambda session: None)
        self.gate = gate
        self.grid: Grid = protocol.device.grid
        self.task = task_label(protocol)
        remaining = {(entry.trial, entry.practice) for entry in writer.remaining()}
        self.queue: list[PlannedTrial] = [t for t in plan.trials if (t.trial, t.practice) in remaining]
        self.current: PlannedTrial | None = None
        self.phase = Phase.INSTRUCTIONS
        self._paused_from: Phase | None = None
        # The UI pauses from its own thread while a worker presents: transitions take turns.
        self._state = threading.RLock()
        self._in_present = False
        self._pausing = False
        self._sitting_start_ns = clock.now_ns()
        joined = writer.sitting_start_ns
        # The run's time zero on this sitting's clock; None until the first onset fixes it.
        self._zero_ns: int | None = None if joined is None else self._sitting_start_ns - joined
        if time_zero_ns is not None:
            if self._zero_ns is not None:
                raise SessionError(f"{writer.paths.label}: the run's time zero is already fixed; "
                                   "a resumed run keeps it")
            self._fix_zero(time_zero_ns, time_zero_event)
        self._onset_ns = 0
        self._duration_ns = 0
        self._delivery: DeliveryRecord | None = None
        self._trace: tuple[PinTrace, ...] = ()  # written with the row that ends the presentation
        self._compiled: tuple[PlannedTrial, TrialSchedule] | None = None
        adaptive = protocol.design.adaptive
        # An adaptive design's procedures, where the rows on disk leave them.
        self.procedures: Procedures | None = None
        if adaptive is not None:
            from pinarray.session.procedures import Procedures

            self.procedures = Procedures(adaptive, plan.seed, writer.records,
                                         writer.paths.beh_tsv, plan, prepared)
        self._presented: tuple[PlannedTrial, Presented] | None = None
        self._next_allowed_ns = self._sitting_start_ns
        self.fault = ""
        self.last: TrialOutcome | None = None

    # -- what the caller can ask ---------------------------------------------------------------

    @property
    def total(self) -> int:
        return len(self.plan.trials)

    @property
    def done_count(self) -> int:
        return self.total - len(self.queue) - (1 if self.current is not None else 0)

    @property
    def records(self) -> list[TrialRecord]:
        return self.writer.records

    @property
    def pausing(self) -> bool:
        """A pause was asked for while a trial is being presented and waits for it to end."""
        return self._pausing

    def number_of(self, planned: PlannedTrial) -> TrialNumber:
        """``planned``'s place among the plan's practice or counted trials."""
        same = [t for t in self.plan.trials if t.practice == planned.practice]
        return TrialNumber(planned.practice, same.index(planned) + 1, len(same))

    def done_of(self, practice: bool) -> int:
        """Practice (or counted) trials of the plan finished, in this sitting or an earlier one."""
        open_ = {(t.trial, t.practice) for t in self.queue}
        if self.current is not None:
            open_.add((self.current.trial, self.current.practice))
        return sum(1 for t in self.plan.trials
                   if t.practice == practice and (t.trial, t.practice) not in open_)

    def _set(self, phase: Phase) -> None:
        self.phase = phase
        self.on_change(self)

    def _require(self, *phases: Phase) -> None:
        if self.phase not in phases:
            allowed = " or ".join(p.value for p in phases)
            raise SessionError(f"cannot do that now: the session is at {self.phase.value}, expected {allowed}")

    # -- transitions -----------------------------------------------------------------------------

    def begin(self) -> None:
        """Leave the instructions: the first remaining trial becomes ready."""
        self._require(Phase.INSTRUCTIONS)
        self._advance()

    def _advance(self) -> None:
        if self.procedures is not None and self.procedures.finished and self.queue and any(
                not t.practice for t in self.queue):
            # Every procedure has stopped: the plan's later trials are not needed.
            done = [r.trial for r in self.writer.records
                    if r.status is TrialStatus.OK and not r.practice]
            self.writer.not_needed_after(max(done, default=0))
            self.queue = [t for t in self.queue if t.practice]
        if self.queue:
            self.current = self.queue.pop(0)
            self._set(Phase.READY)
        else:
            self.current = None
            self.writer.finish(RunStatus.COMPLETED)
            self._set(Phase.DONE)

    def present(self) -> None:
        """Wait out the inter-trial interval, then play the current trial's stimulus."""
        with self._state:
            self._require(Phase.READY)
            if self._in_present:
                # The phase stays READY through the inter-trial wait: a second call must not
                # present the same trial again from another thread.
                raise SessionError("a trial is already being presented")
            self._in_present = True
        try:
            self._present()
        finally:
            with self._state:
                self._in_present = self._pausing = False

    def current_schedule(self) -> TrialSchedule:
        """The current trial compiled, once per trial (the UI shows it while it plays)."""
        assert self.current is not None
        if self._compiled is None or self._compiled[0] is not self.current:
            protocol, condition = self._presenting()
            self._compiled = (self.current, compile_drives(trial_drives(protocol, condition),
                                                           protocol.device))
        return self._compiled[1]

    @property
    def presented(self) -> Presented | None:
        """What the current trial of an adaptive design presents: whose trial, at which value
        (decided once per trial, from the procedures as the rows leave them); None: a fixed
        design, or no current trial."""
        if self.procedures is None or self.current is None:
            return None
        if self._presented is None or self._presented[0] is not self.current:
            self._presented = (self.current, self.procedures.presented(self.current))
        return self._presented[1]

    @property
    def played_stroke(self) -> StrokeCounts | None:
        """How far the pins moved in the current trial's stimulus, once it has played (awaiting
        the answer, or not delivered), as its row keeps it; None before or while it plays,
        and where not measured (PWM servos)."""
        awaiting = self.phase in (Phase.RESPONSE, Phase.FAULT) or (
            self.phase is Phase.PAUSED and self._paused_from is Phase.RESPONSE)
        if not awaiting or self._delivery is None:
            return None
        return _stroke(self._delivery.strokes)

    def _presenting(self) -> tuple[Protocol, Condition]:
        """The protocol and condition the current trial plays: an adaptive design's at the
        value its procedure chose."""
        assert self.current is not None
        presented = self.presented
        adaptive = self.protocol.design.adaptive
        if presented is None or presented.value is None or adaptive is None:
            return self.protocol, self.current.condition
        return adapted(self.protocol, self.current.condition, adaptive.parameter, presented.value)

    def _present(self) -> None:
        schedule = self.current_schedule()
        try:
            self.clock.sleep_until_ns(self._next_allowed_ns)
            if self.gate is not None:  # the scanner's volume this trial is locked to
                self.gate.wait_for_onset(self.clock.now_ns())
        except Interrupted:
            with self._state:
                if not self._pausing:
                    raise  # not a pause: the caller aborts the run
                self._settle(Phase.READY)  # nothing was presented yet
                return
        with self._state:
            if self._pausing:
                self._settle(Phase.READY)
                return
            self._onset_ns = self.clock.now_ns()
            self._delivery = None
            self._set(Phase.STIMULUS)
        try:
            presentation = self.stimulator.present(schedule)
        except Interrupted:
            with self._state:
                if not self._pausing:
                    raise  # not a stimulus fault: the caller aborts the run
                self._write(TrialStatus.ABORTED, duration_ns=self.clock.now_ns() - self._onset_ns,
                            reason=PAUSE_CUT_SHORT)
                self._settle(Phase.READY)  # presented again after resume
                return
        except PinArrayError as error:
            with self._state:
                self.fault = str(error)
                self._write(TrialStatus.INVALID, duration_ns=self.clock.now_ns() - self._onset_ns,
                            reason=self.fault)
                self._settle(Phase.FAULT)
                return
        with self._state:
            self._onset_ns = presentation.onset_ns
            self._delivery = presentation.delivery
            self._trace = presentation.trace
            self._duration_ns = schedule.end_ns
            if not presentation.delivery.delivered:
                self.fault = f"the stimulus was not delivered as scheduled: {presentation.delivery.problem}"
                self._write(TrialStatus.INVALID, reason=self.fault)
                self._settle(Phase.FAULT)
                return
            self._settle(Phase.RESPONSE)

    def _settle(self, phase: Phase) -> None:
        """End a presentation at ``phase``; a pause asked for meanwhile holds the run there.

        Called with the state lock held, so a `pause` sees either a presentation in progress
        or its end, never the moment between.
        """
        self._in_present = False
        pausing, self._pausing = self._pausing, False
        if pausing and phase is not Phase.FAULT:  # a fault already holds the run
            self._paused_from = phase
            phase = Phase.PAUSED
        self._set(phase)

    def retry(self) -> None:
        """After a fault: present the same trial again (its failed row stays, marked invalid)."""
        self._require(Phase.FAULT)
        self.fault = ""
        self._set(Phase.READY)

    def respond(self, response: str | int | None, response_time_ns: int | None | object = MEASURED) -> TrialOutcome:
        """Record the subject's answer to the current trial and move on.

        The answers the design's paradigm takes (`Design.answers`): localisation a pin number
        (or None / "none" for "nothing felt"), apparent motion none / left / right / unsure,
        identification a pattern's name (or a count), two intervals first / second, temporal
        order the pin that came first; a paradigm of a lab's own, its own. ``response_time_ns`` defaults to the time
        since stimulus onset on the session's clock; None records it as not applicable
        (scripted answers have no response time).
        """
        self._require(Phase.RESPONSE)
        text = self._check_response(response)
        if response_time_ns is MEASURED:
            response_time_ns = self.clock.now_ns() - self._onset_ns
        assert response_time_ns is None or isinstance(response_time_ns, int)
        record = self._write(TrialStatus.OK, response=text, response_time_ns=response_time_ns)
        self._next_allowed_ns = self.clock.now_ns() + self.protocol.design.inter_trial_interval_ns
        self.last = TrialOutcome(record, len(self.queue))
        self._advance()
        return self.last

    def redo(self) -> None:
        """Present the current trial again; its first presentation is logged as redone."""
        self._require(Phase.RESPONSE)
        self._write(TrialStatus.REDONE)
        self._set(Phase.READY)

    def pause(self) -> None:
        """Hold the run. While a trial is being presented the pause waits for `present` to
        return (see the module's docstring); `pausing` says so meanwhile."""
        with self._state:
            self._require(Phase.READY, Phase.STIMULUS, Phase.RESPONSE)
            if self._pausing:
                return
            if self._in_present:
                self._pausing = True
                return
            self._paused_from = self.phase
            self._set(Phase.PAUSED)

    def resume(self) -> None:
        with self._state:
            self._require(Phase.PAUSED)
            assert self._paused_from is not None
            self._set(self._paused_from)
            self._paused_from = None

    def abort(self, reason: str, status: RunStatus = RunStatus.ABORTED) -> None:
        """Stop the run for good (it can still be resumed later); ``status``: aborted or crashed.

        Its last row and the manifest's status are written whole, the stop signals held back
        meanwhile: a third Ctrl-C landing in them left a run aborted on the screen that its
        manifest called crashed."""
        with self._state, deferred_signals():
            if self.phase in (Phase.DONE, Phase.ABORTED):
                return
            reason = reason or "aborted by the experimenter"
            if self.phase is Phase.STIMULUS:
                self._delivery = None  # cut short: what was delivered is not a whole stimulus
                self._write(TrialStatus.ABORTED, duration_ns=self.clock.now_ns() - self._onset_ns, reason=reason)
            elif self.phase is Phase.RESPONSE or (self.phase is Phase.PAUSED and self._paused_from is Phase.RESPONSE):
                self._write(TrialStatus.ABORTED, reason=reason)
            self.writer.finish(status, reason)
            self._set(Phase.ABORTED)

    # -- rows ----------------------------------------------------------------------------------

    def _check_response(self, response: str | int | None) -> str:
        """The answer as the results write it, or a `SessionError` saying what the design
        takes (its paradigm's words: `ParadigmDesign.take_answer`)."""
        design = self.protocol.design
        try:
            return design.paradigm.take_answer(response, design, self.grid)
        except PinArrayError as problem:
            raise SessionError(str(problem)) from None

    def _fix_zero(self, zero_ns: int, event: str) -> None:
        self._zero_ns = zero_ns
        self.writer.set_time_zero(self._sitting_start_ns - zero_ns, self.clock.now_ns() - zero_ns, event)

    def _write(self, status: TrialStatus, response: str | None = None, response_time_ns: int | None = None,
               duration_ns: int | None = None, reason: str | None = None) -> TrialRecord:
        planned = self.current
        assert planned is not None
        if self._zero_ns is None:
            self._fix_zero(self._onset_ns, FIRST_TRIAL_ONSET)
        assert self._zero_ns is not None
        delivery = self._delivery
        common: TrialFields = {
            "trial": planned.trial, "block": planned.block, "task": self.task, "status": status,
            "onset_ns": self._onset_ns - self._zero_ns,
            "duration_ns": self._duration_ns if duration_ns is None else duration_ns,
            "response_time_ns": response_time_ns, "practice": planned.practice,
            "delivery": None if delivery is None else _counts(delivery),
            "status_reason": None if reason is None else " ".join(reason.split()),  # one line
            "stroke": None if delivery is None else _stroke(delivery.strokes),
        }
        presented = self.presented
        if presented is not None:
            assert self.procedures is not None
            common["adaptive"] = (self.procedures.cells(presented) if response is None else
                                  self.procedures.answer(planned, presented, response, status))
        condition = planned.condition
        design = self.protocol.design
        adaptive = design.adaptive
        if presented is not None and presented.value is not None and adaptive is not None:
            # As the row tells it (a frequency adapted is the one played): no protocol rebuilt.
            condition = design.paradigm.adapt(condition, adaptive.parameter, presented.value)
        pins = tuple(sorted({d.pin for d in self.current_schedule().drives}))
        record = self.writer.rows.row(condition, common, response, pins, self.grid)
        traces, self._trace = self._trace, ()
        samples = _samples(planned.trial, self._onset_ns - self._zero_ns, traces,
                           self.current_schedule()) if traces else ()
        return self.writer.write_trial(record, samples)
