"""The run: present trials, take answers, pause, redo, retry after a fault, abort."""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Footer, ProgressBar, Static

from pinarray.journal.records import LocalisationRecord
from pinarray.player import DEFAULT_LEAD_NS
from pinarray.protocol import DIRECTION_OF_WAVE, Condition, LocalisationCondition, Paradigm
from pinarray.session import Phase, Session, SessionError
from pinarray.tui.confirm import Confirm
from pinarray.tui.lab import Lab
from pinarray.tui.live import LiftTimeline, LiveCounts
from pinarray.tui.pin_grid import PinGrid
from pinarray.tui.response_pad import ResponsePad

if TYPE_CHECKING:
    from pinarray.tui.app import PinArrayApp

# Redraws of the moving pins per second while a stimulus plays.
GRID_FPS = 20
ABORT_REASON = "aborted by the experimenter"

PHASE_HINT = {
    Phase.INSTRUCTIONS: "Give the subject the instructions, then Space to begin.",
    Phase.READY: "Space (or Enter) presents the next trial.",
    Phase.STIMULUS: "Stimulus playing…",
    Phase.PAUSED: "PAUSED · p resumes.",
    Phase.DONE: "Run complete.",
    Phase.ABORTED: "Run aborted.",
}


class RunScreen(Screen):
    """One run of a session, driven by the experimenter.

    Parameters
    ----------
    lab : Lab
        Owns the rig; presents trials in a worker thread.
    session : Session
        The open run; its changes arrive here as `RunScreen.Changed` messages.
    """

    BINDINGS = [
        Binding("space", "present", "present"),
        Binding("p", "pause", "pause/resume"),
        Binding("d", "redo", "redo trial"),
        Binding("t", "retry", "retry"),
        Binding("a", "abort", "abort"),
    ]

    class Changed(Message):
        """The session moved to ``phase``; ``at_ns`` is when, on the session clock."""

        def __init__(self, phase: Phase, at_ns: int):
            super().__init__()
            self.phase = phase
            self.at_ns = at_ns

    def __init__(self, lab: Lab, session: Session):
        super().__init__()
        self.lab = lab
        self.session = session
        self.localisation = session.protocol.design.paradigm is Paradigm.LOCALISATION
        self._timeline: LiftTimeline | None = None
        self._active: frozenset[int] = frozenset()
        self._onset_ns = 0
        self._ending = False

    def compose(self) -> ComposeResult:
        protocol, request = self.session.protocol, self.lab.request
        assert request is not None
        used = {pin for c in protocol.design.conditions for pin in _pins_of(self.session, c)}
        yield Static(f"{protocol.name} · sub-{request.subject} ses-{request.session} · "
                     f"run {self.session.writer.paths.run}", id="title")
        with Horizontal(id="run-body"):
            with Vertical(id="array-side"):
                yield Static("the array as the subject feels it", classes="caption")
                yield PinGrid(self.session.grid, used, id="pins")
                yield Static(id="stimulus")
            with Vertical(id="control-side"):
                yield Static(id="trial")
                yield ProgressBar(total=self.session.total, show_eta=False, id="progress")
                yield Static(id="phase")
                yield ResponsePad(self.localisation, self.session.grid.pin_count, id="pad")
                yield Static(id="problem")
                yield Static(id="counts")
                yield Static(id="last")
        yield Footer()

    def on_mount(self) -> None:
        clock = self.lab.clock
        assert clock is not None
        self.clock = clock

        def changed(session: Session) -> None:
            # Called from the worker thread too; post_message is safe from any thread.
            self.post_message(self.Changed(session.phase, clock.now_ns()))

        self.session.on_change = changed
        self._ticker = self.set_interval(1 / GRID_FPS, self._tick, pause=True)
        self.query_one(ResponsePad).focus()
        self._draw()

    # -- drawing ------------------------------------------------------------------------------

    def _draw(self) -> None:
        session = self.session
        phase, current = session.phase, session.current
        trial = self.query_one("#trial", Static)
        if current is None:
            trial.update(f"{session.done_count} of {session.total} trials done")
        elif current.practice:
            trial.update(f"PRACTICE trial {current.trial} of {session.total} · not counted")
        else:
            trial.update(f"Trial {current.trial} of {session.total} · block {current.block}")
        trial.set_class(current is not None and current.practice, "-practice")
        self.query_one(ProgressBar).update(total=session.total, progress=session.done_count)
        self.query_one("#stimulus", Static).update(self._describe_stimulus())
        hint = PHASE_HINT.get(phase, "")
        if phase is Phase.INSTRUCTIONS:
            if session.writer.resumed:
                hint = (f"Resumed: {session.done_count} of {session.total} trials were done; the "
                        f"other {len(session.queue)} follow in plan order.\n{hint}")
            hint = f"{session.protocol.description}\n{hint}"
        elif phase is Phase.RESPONSE:
            hint = ("Subject's answer: pin number + Enter, or click a pin." if self.localisation
                    else "Subject's answer: l / r / n (no motion) / u (unsure).")
            hint += "  d: redo the trial"
        elif phase is Phase.FAULT:
            hint = (f"STIMULUS FAILED (logged invalid): {session.fault}\n"
                    "t: present the trial again · a: abort the run")
        phase_line = self.query_one("#phase", Static)
        phase_line.update(hint)
        phase_line.set_class(phase is Phase.FAULT, "-fault")
        phase_line.set_class(phase is Phase.PAUSED, "-paused")
        pad = self.query_one(ResponsePad)
        pad.accepting = phase is Phase.RESPONSE
        counts = LiveCounts.of(session.records).lines(self.localisation)
        self.query_one("#counts", Static).update("\n".join(counts))
        self.query_one("#last", Static).update(self._describe_last())
        self._draw_grid(frozenset())

    def _draw_grid(self, lifted: frozenset[int]) -> None:
        chosen = None
        entry = self.query_one(ResponsePad).entry
        if self.localisation and entry.isdigit():
            chosen = int(entry)
        showing = self.session.phase in (Phase.STIMULUS, Phase.RESPONSE)
        active = self._active if showing else frozenset()
        self.query_one(PinGrid).show(lifted, active, chosen)

    def _describe_stimulus(self) -> str:
        current = self.session.current
        if current is None:
            return ""
        condition = current.condition
        if isinstance(condition, LocalisationCondition):
            return f"stimulus: pin {condition.pin} at {condition.frequency_hz} Hz"
        pins = " ".join(map(str, _pins_of(self.session, condition)))
        direction = DIRECTION_OF_WAVE[condition.direction]
        if direction == "none":
            return f"stimulus: no wave (centre alternates with sides) on pins {pins}"
        return f"stimulus: {direction}wards wave on pins {pins}"

    def _describe_last(self) -> str:
        if self.session.last is None:
            return ""
        record = self.session.last.record
        if isinstance(record, LocalisationRecord):
            answer = "nothing felt" if record.nothing_felt else f"pin {record.response}"
            return (f"last: trial {record.trial}, pin {record.pin} → {answer} "
                    f"({record.category})")
        return f"last: trial {record.trial}, {record.direction} wave → {record.response}"

    def _tick(self) -> None:
        if self._timeline is not None:
            elapsed_ns = self.clock.now_ns() - self._onset_ns
            self._draw_grid(self._timeline.lifted_at(elapsed_ns))

    # -- session changes ----------------------------------------------------------------------

    @on(Changed)
    def _changed(self, message: Changed) -> None:
        if message.phase is Phase.STIMULUS:
            self._onset_ns = message.at_ns + DEFAULT_LEAD_NS  # the player's own lead
            self._ticker.resume()
        else:
            self._ticker.pause()
        self._draw()
        if message.phase is Phase.STIMULUS:
            self._tick()
        if message.phase is Phase.DONE:
            self._end("")

    # -- actions ------------------------------------------------------------------------------

    def action_present(self) -> None:
        session = self.session
        if session.phase is Phase.INSTRUCTIONS:
            session.begin()
            return
        if session.phase is not Phase.READY:
            # Space pressed twice, or during the stimulus: harmless, so said only where useful.
            advice = {Phase.PAUSED: "p resumes first",
                      Phase.FAULT: "t retries the trial, a aborts the run"}.get(session.phase)
            if advice:
                self.query_one("#problem", Static).update(advice)
            return
        self.query_one("#problem", Static).update("")
        schedule = session.current_schedule()
        device = session.protocol.device
        rest = {pin: device.calibration(pin).rest_steps for pin in schedule.active_pins}
        self._timeline = LiftTimeline.from_targets(schedule.targets, rest)
        self._active = frozenset(schedule.active_pins)
        self.query_one(ResponsePad).clear()
        self.run_worker(self.lab.present, thread=True, group="stimulus", name="present")

    def _try(self, action) -> None:
        """Run a session action; one it cannot take now is explained, never raised."""
        problem = self.query_one("#problem", Static)
        try:
            action()
        except SessionError as error:
            problem.update(str(error))
            return
        problem.update("")

    def action_pause(self) -> None:
        paused = self.session.phase is Phase.PAUSED
        self._try(self.session.resume if paused else self.session.pause)

    def action_redo(self) -> None:
        self._try(self.session.redo)

    def action_retry(self) -> None:
        self._try(self.session.retry)

    def action_abort(self) -> None:
        if self._ending:
            return

        def confirmed(yes: bool | None) -> None:
            if yes:
                self._end(ABORT_REASON)

        self.app.push_screen(Confirm("Abort this run?\nRows logged so far stay; the run can be "
                                     "resumed later from the start screen."), confirmed)

    @on(ResponsePad.Proceed)
    def _proceed(self) -> None:
        if self.session.phase in (Phase.INSTRUCTIONS, Phase.READY):
            self.action_present()

    @on(ResponsePad.Typed)
    def _typed(self) -> None:
        self._draw_grid(frozenset())

    @on(PinGrid.Selected)
    def _pin_clicked(self, message: PinGrid.Selected) -> None:
        self.query_one(ResponsePad).choose(message.pin)

    @on(ResponsePad.Answered)
    def _answered(self, message: ResponsePad.Answered) -> None:
        problem = self.query_one("#problem", Static)
        answer = "none" if message.answer in ("0", "none") else message.answer
        try:
            self.session.respond(answer)
        except SessionError as error:
            problem.update(str(error))  # e.g. pin 17: the entry stays for correcting
            return
        problem.update("")
        self.query_one(ResponsePad).clear()

    def _end(self, reason: str) -> None:
        """Close the run (abort it if unfinished), rest the pins, then show the end screen."""
        if self._ending:
            return
        self._ending = True
        self._ticker.pause()
        self.query_one("#phase", Static).update("Closing the run; pins to rest…")
        cast("PinArrayApp", self.app).finish_run(self.session, reason)


def _pins_of(session: Session, condition: Condition) -> tuple[int, ...]:
    if isinstance(condition, LocalisationCondition):
        return (condition.pin,)
    wave = session.protocol.wave(condition.stimulus)
    return tuple(sorted({d.pin for d in wave.drives()}))
