"""The run: present trials, take answers, pause, redo, retry after a fault, abort.

Keys are the experimenter's, typed with a participant waiting: each one is acted on or
answered on the notice line (`KeyNotices`), a repeated key does what it did once, and the
footer lists only what is possible now (`check_action`).

Past 400 lines on purpose: one screen's keys, its refusals and what it draws for each phase of
the session must agree; the pin grid and the live counts already live in their own modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.message import Message
from textual.screen import Screen
from textual.widgets import ProgressBar, Static
from textual.worker import Worker, WorkerState

from pinarray.journal.records import StrokeCounts
from pinarray.protocol import Condition
from pinarray.protocol.drives import trial_drives
from pinarray.session.sitting import MAX_ATTEMPTS, Sitting
from pinarray.session.trials import PAUSE_CUT_SHORT, Phase, Session, SessionError
from pinarray.tui.confirm import Confirm
from pinarray.tui.footer import KeyFooter
from pinarray.tui.live import LiftTimeline, live_lines, track_lines
from pinarray.tui.notice import KeyNotices, Notice
from pinarray.tui.pin_grid import PinGrid
from pinarray.tui.response_pad import ResponsePad, answer_keys
from pinarray.units import NS_PER_S

if TYPE_CHECKING:
    from pinarray.tui.app import PinArrayApp

# Redraws of the moving pins per second while a stimulus plays.
GRID_FPS = 20
# A lift is drawn only when it lasts at least this many frames.
FRAMES_PER_LIFT = 2
ABORT_REASON = "aborted by the experimenter"
PRESENT, CUT_SHORT = "present", "cut short"  # worker names


class RunScreen(KeyNotices, Screen):
    """One run of a session, driven by the experimenter.

    Parameters
    ----------
    sitting : Sitting
        Owns the rig; presents trials in a worker thread.
    session : Session
        The open run; its changes arrive here as `RunScreen.Changed` messages.
    """

    BINDINGS = [
        Binding("space", "begin", "begin"),
        Binding("space", "present", "present"),
        Binding("p", "pause", "pause"),
        Binding("p", "resume", "resume"),
        Binding("d", "redo", "redo trial"),
        Binding("t", "retry", "present again"),
        Binding("a", "abort", "abort run"),
        Binding("q", "quit_run", "quit"),
    ]

    class Changed(Message):
        """The session moved to ``phase``; ``at_ns`` is when, on the session clock."""

        def __init__(self, phase: Phase, at_ns: int):
            super().__init__()
            self.phase = phase
            self.at_ns = at_ns

    def __init__(self, sitting: Sitting, session: Session):
        super().__init__()
        self.sitting = sitting
        self.session = session
        design = session.protocol.design
        self.answers = design.paradigm.pad(design, session.grid)
        self.localisation = self.answers.typed  # answers typed: a pin (or a count), then Enter
        self.pins_answer = self.answers.pins
        self._by_trial = {t.trial: t for t in session.plan.trials}
        self._timeline: LiftTimeline | None = None
        self._active: frozenset[int] = frozenset()
        self._stimulus_ns = 0  # the length of the stimulus presented last
        self._shown_playing = ""  # the stimulus's progress as last shown
        self._presenting = False  # a present worker runs (the interval, then the stimulus)
        self._cutting = False  # a pause is cutting the stimulus short
        self._ending = False
        self._lines: dict[str, str] = {}  # what each line of text shows (`_show`)

    def compose(self) -> ComposeResult:
        protocol, request = self.session.protocol, self.sitting.request
        assert request is not None
        used = {pin for c in protocol.design.conditions for pin in _pins_of(self.session, c)}
        yield Static(f"{protocol.name} · sub-{request.subject} ses-{request.session} · "
                     f"run {self.session.writer.paths.run}", id="title")
        with Horizontal(id="run-body"):
            with Vertical(id="array-side"):
                yield Static("the array as the subject feels it", classes="caption")
                yield PinGrid(self.session.grid, used, id="pins")
                yield Static(id="stimulus")
                yield Static(id="stroke")  # how far the pins moved, once the stimulus played
                yield Static(id="last")  # beside the array: the other side is full at 80x24
            with Vertical(id="control-side"):
                yield Static(id="trial")
                yield ProgressBar(total=self.session.total, show_eta=False, id="progress")
                yield Static(id="phase")
                yield ResponsePad(self.answers, self.session.grid.pin_count, id="pad")
                yield Notice()
                yield Static(id="counts")
        yield KeyFooter()

    def on_mount(self) -> None:
        clock = self.sitting.clock
        assert clock is not None
        self.clock = clock

        def changed(session: Session) -> None:
            # Called from the worker thread too; post_message is safe from any thread.
            self.post_message(self.Changed(session.phase, clock.now_ns()))

        self.session.on_change = changed
        self._ticker = self.set_interval(1 / GRID_FPS, self._tick, pause=True)
        self.query_one(ResponsePad).focus()
        self._draw()

    # -- what is possible now -----------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        phase, busy = self.session.phase, self._ending
        match action:
            case "begin":
                return phase is Phase.INSTRUCTIONS and not busy
            case "present":
                return phase is Phase.READY and not (busy or self._presenting)
            case "pause":
                return (phase in (Phase.READY, Phase.STIMULUS, Phase.RESPONSE)
                        and not (busy or self.session.pausing))
            case "resume":
                return phase is Phase.PAUSED and not (busy or self._cutting)
            case "redo":
                return phase is Phase.RESPONSE and not busy
            case "retry":  # once the sitting has counted the failed attempt
                return phase is Phase.FAULT and not (busy or self._presenting)
            case "abort":
                return phase not in (Phase.DONE, Phase.ABORTED) and not busy
        return True

    def refusal(self, actions: tuple[str, ...]) -> str:
        """Why the key's action is not possible now, and what is."""
        phase, current = self.session.phase, self.session.current
        trial = str(self.session.number_of(current)) if current is not None else "the trial"
        if self._ending:
            return "the run is closing: pins to rest…"
        if self.session.pausing or self._cutting:
            return "pausing: the stimulus is being cut short, pins to rest…"
        if phase is Phase.PAUSED:
            return "paused: p resumes first"
        if phase is Phase.FAULT:
            return "the stimulus failed: t presents it again, a aborts the run"
        if "begin" in actions or "present" in actions:
            if phase is Phase.STIMULUS:
                return f"{trial} is playing"
            if phase is Phase.READY:
                return f"{trial} starts after the inter-trial interval"
            return f"waiting for the answer to {trial} (d presents it again)"
        if "pause" in actions:
            return "nothing to pause yet: Space begins"
        if "redo" in actions:
            return "d presents a trial again once it has played and awaits its answer"
        if "retry" in actions:
            return "nothing failed: t presents again a trial whose stimulus failed"
        return ""

    def unbound(self, key: str) -> str:
        phase = self.session.phase
        if phase is Phase.RESPONSE:
            return ("not an answer: a pin number + Enter, 0 or n for nothing felt"
                    if self.pins_answer else "not an answer: " + self.answers.hint)
        if key not in answer_keys(self.answers) and key != "enter":
            return ""
        if phase is Phase.STIMULUS:
            return "the stimulus is still playing: answer once it ends"
        if phase is Phase.PAUSED:
            return "paused: p resumes, then the answer"
        return "no trial is waiting for an answer"

    # -- drawing ------------------------------------------------------------------------------

    def _draw(self) -> None:
        session = self.session
        phase, current = session.phase, session.current
        counted = f"{session.done_of(practice=False)} of {len(self._kind(False))} done"
        if current is None:
            self._show("#trial", counted)
        else:
            number = session.number_of(current)
            where = " · not counted" if current.practice else self._block(current.block)
            self._show("#trial", f"{str(number).capitalize()}{where} · #{current.trial} in the "
                                 f"plan\n{counted}")
        self.query_one("#trial").set_class(current is not None and current.practice, "-practice")
        self.query_one(ProgressBar).update(total=session.total, progress=session.done_count)
        self._show("#stimulus", self._describe_stimulus())
        stroke = session.played_stroke
        self._show("#stroke", self._describe_stroke(stroke))
        self.query_one("#stroke").set_class(stroke is not None and bool(stroke.short_cycles),
                                            "-short")
        self._show("#phase", self._hint())
        phase_line = self.query_one("#phase")
        phase_line.set_class(phase is Phase.FAULT, "-fault")
        phase_line.set_class(phase is Phase.PAUSED or session.pausing, "-paused")
        pad = self.query_one(ResponsePad)
        pad.accepting = phase is Phase.RESPONSE
        counts = live_lines(session.writer.rows, session.records)
        if session.procedures is not None:
            counts = [*counts, *track_lines(session.records)]
        self._show("#counts", "\n".join(counts))
        self._show("#last", self._describe_last())
        self._draw_grid(frozenset())
        self.refresh_keys()

    def _show(self, line: str, text: str, layout: bool = True) -> None:
        """Put ``text`` on the Static ``line`` (a selector) unless it says that already: an
        update lays the screen out again, and a phase's change redraws every line."""
        if self._lines.get(line) != text:
            self._lines[line] = text
            self.query_one(line, Static).update(text, layout=layout)

    def _hint(self) -> str:
        session, phase = self.session, self.session.phase
        if session.pausing or self._cutting:
            return "PAUSING · cutting the stimulus short, pins to rest…"
        match phase:
            case Phase.INSTRUCTIONS:
                hint = f"{session.protocol.description}\nGive the instructions, then Space to begin."
                if session.writer.resumed:
                    hint = (f"Resumed: {session.done_count} of {session.total} trials were done; "
                            f"the other {len(session.queue)} follow in plan order.\n{hint}")
                return hint
            case Phase.READY if self._presenting:
                return "Starting after the inter-trial interval…"
            case Phase.READY:
                return "Space (or Enter) presents the trial."
            case Phase.STIMULUS:
                return self._playing()
            case Phase.RESPONSE:
                return f"Subject's answer: {self.answers.hint}."
            case Phase.PAUSED:
                return "PAUSED · p resumes."
            case Phase.FAULT:
                failed = self.sitting.failed
                next_try = (f" (attempt {failed.attempt + 1} of {MAX_ATTEMPTS})"
                            if failed is not None else "")
                return (f"STIMULUS FAILED (logged invalid): {session.fault}\n"
                        f"t: present the trial again{next_try} · a: abort the run")
            case Phase.DONE:
                return "Run complete."
        return "Run aborted."

    def _cut_short_note(self) -> str:
        """After a pause: whether it cut the trial short (then presented again after p)."""
        session, records = self.session, self.session.records
        cut = (session.phase is Phase.PAUSED and records and session.current is not None
               and records[-1].trial == session.current.trial
               and records[-1].status_reason == PAUSE_CUT_SHORT)
        if not cut:
            return ""
        assert session.current is not None
        return (f"{str(session.number_of(session.current)).capitalize()} was cut short (logged); "
                "pins at rest. It is presented again after p.")

    def _kind(self, practice: bool) -> list:
        return [t for t in self.session.plan.trials if t.practice == practice]

    def _block(self, block: int) -> str:
        return f" · block {block}" if self.session.protocol.design.blocks > 1 else ""

    def _draw_grid(self, lifted: frozenset[int]) -> None:
        chosen = None
        entry = self.query_one(ResponsePad).entry
        if self.pins_answer and entry.isascii() and entry.isdigit():
            chosen = int(entry)
        showing = self.session.phase in (Phase.STIMULUS, Phase.RESPONSE)
        active = self._active if showing else frozenset()
        self.query_one(PinGrid).show(lifted, active, chosen)

    def _describe_stimulus(self) -> str:
        current = self.session.current
        if current is None:
            return ""
        presented = self.session.presented
        adaptive = self.session.protocol.design.adaptive
        if presented is not None and adaptive is not None:
            value = ("its own stimulus" if presented.value is None else
                     f"{adaptive.parameter.quantity} {float(presented.value):g} "
                     f"{adaptive.parameter.unit}")
            return f"{self._condition_text(current.condition)} · {presented.procedure}: {value}"
        return self._condition_text(current.condition)

    def _condition_text(self, condition: Condition) -> str:
        return self.session.protocol.design.paradigm.screen_line(
            condition, _pins_of(self.session, condition))

    def _describe_stroke(self, stroke: StrokeCounts | None) -> str:
        """``stroke 65/65 steps (1.00 mm)``: achieved of commanded, in mm through the pins'
        lever (when the moving pins share one); '' where not measured (PWM servos)."""
        current = self.session.current
        if stroke is None or current is None:
            return ""
        device = self.session.protocol.device
        unit = device.servo.position_unit
        commanded, achieved = stroke.commanded_steps, stroke.achieved_steps
        if achieved is None:
            return f"stroke n/a of {commanded} {unit} (too few samples to measure)"
        per_step = {device.mm_per_step(pin) for pin in _pins_of(self.session, current.condition)}
        mm = ""
        if len(per_step) == 1:
            (factor,) = per_step
            mm = (f" ({achieved * factor:.2f} mm)" if achieved == commanded else
                  f" ({achieved * factor:.2f} of {commanded * factor:.2f} mm)")
        short = f" · SHORT in {stroke.short_cycles} cycles" if stroke.short_cycles else ""
        return f"stroke {achieved}/{commanded} {unit}{mm}{short}"

    def _describe_last(self) -> str:
        if self.session.last is None:
            return ""
        record = self.session.last.record
        planned = self._by_trial.get(record.trial)
        name = str(self.session.number_of(planned)) if planned else f"trial #{record.trial}"
        return f"last: {name}{self.session.writer.rows.last_line(record)}"

    def _tick(self) -> None:
        if self._timeline is not None:
            onset_ns = self._playing_from()
            elapsed_ns = -1 if onset_ns is None else self.clock.now_ns() - onset_ns
            self._draw_grid(self._timeline.lifted_at(elapsed_ns))
        if self.session.phase is Phase.STIMULUS and not (self.session.pausing or self._cutting):
            playing = self._playing()
            if playing != self._shown_playing:  # a tenth of a second on
                self._shown_playing = playing
                # One line whose length hardly changes: no layout of the screen for it.
                self._show("#phase", playing, layout=False)

    def _playing_from(self) -> int | None:
        """The time zero of the stimulus the array is playing now (None: it has not begun)."""
        rig = self.sitting.rig
        return None if rig is None else rig.playing_from_ns

    def _playing(self) -> str:
        """The stimulus's own progress, seconds played of its length, once the array plays it;
        until then, that it waits."""
        onset_ns = self._playing_from()
        if onset_ns is None:
            return "Stimulus starting: waiting for the array…"
        length_ns = self._stimulus_ns
        played_ns = min(length_ns, max(0, self.clock.now_ns() - onset_ns))
        return f"Stimulus playing: {played_ns / 1e9:.1f} of {length_ns / 1e9:.1f} s"

    # -- session changes ----------------------------------------------------------------------

    @on(Changed)
    def _changed(self, message: Changed) -> None:
        if message.phase is Phase.STIMULUS:
            self._ticker.resume()
        else:
            self._ticker.pause()
        if not self._cutting:
            self.notice.clear()  # what it said was about the phase that just ended
        self._draw()
        if message.phase is Phase.STIMULUS:
            self._tick()
        if message.phase is Phase.DONE:
            self._end("")
        if self.is_current:
            self.query_one(ResponsePad).focus()  # answers go to the pad whatever was clicked

    @on(Worker.StateChanged)
    def _worker_changed(self, event: Worker.StateChanged) -> None:
        if event.state not in (WorkerState.SUCCESS, WorkerState.ERROR, WorkerState.CANCELLED):
            return
        if event.worker.name == PRESENT:
            self._presenting = False
            refused = event.worker.result if event.state is WorkerState.SUCCESS else None
            if refused:
                self.notice.say(refused)
            failed = self.sitting.failed
            if failed is not None and failed.last:
                # The trial failed its last attempt: the sitting stopped the run, naming it.
                self._end(failed.reason)
                return
        elif event.worker.name == CUT_SHORT:
            self._cutting = False
            self.notice.say(self._cut_short_note())
        else:
            return
        self._draw()

    # -- actions ------------------------------------------------------------------------------

    def action_begin(self) -> None:
        self._try(self.session.begin)

    def action_present(self) -> None:
        session = self.session
        self.notice.clear()
        schedule = session.current_schedule()
        device = session.protocol.device
        rest = {pin: device.calibration(pin).rest_steps for pin in schedule.active_pins}
        timeline = LiftTimeline.from_targets(schedule.targets, rest)
        # Lifts faster than the screen's frames (a 10 Hz train, or any at --speed 20) would
        # flicker at random: the driven pins are shown driven, without the lifts.
        scale = self.app.options.time_scale  # type: ignore[attr-defined]
        shortest_ns = timeline.shortest_change_ns()
        self._timeline = timeline if shortest_ns is None or (
            scale and shortest_ns / scale >= FRAMES_PER_LIFT * NS_PER_S / GRID_FPS) else None
        self._stimulus_ns = schedule.end_ns
        self._active = frozenset(schedule.active_pins)
        self.query_one(ResponsePad).clear()
        self._presenting = True
        self.run_worker(self._present, thread=True, group="stimulus", name=PRESENT)
        self._draw()

    def _present(self) -> str:
        """In a worker thread: present the trial; '' or why the session would not."""
        try:
            self.sitting.present()
        except SessionError as refused:
            # Paused before this worker reached the session: the pause says it all.
            return "" if self.session.phase is Phase.PAUSED else str(refused)
        return ""

    def _try(self, action) -> None:
        """Run a session action; one it cannot take now is explained, never raised."""
        try:
            action()
        except SessionError as error:
            self.notice.say(str(error))
            return
        self.notice.clear()

    def action_pause(self) -> None:
        self._try(self.session.pause)
        if self.session.pausing:
            # The session holds once the stimulus (or the interval before it) ends; the stop
            # request makes that now, the pins going to rest.
            self._cutting = True
            self.run_worker(self.sitting.cut_short, thread=True, group="pause", name=CUT_SHORT)
            self._draw()

    def action_resume(self) -> None:
        self._try(self.session.resume)

    def action_redo(self) -> None:
        current = self.session.current
        assert current is not None
        number = self.session.number_of(current)

        def confirmed(yes: bool | None) -> None:
            if yes:
                self._try(self.session.redo)

        self.app.push_screen(Confirm(f"Present {number} again?\nThis presentation is kept in "
                                     "the results, marked redone."), confirmed)

    def action_retry(self) -> None:
        """Present the failed trial again: re-arm it and present it, in one key."""
        self._try(self.session.retry)
        if self.check_action("present", ()):
            self.action_present()

    async def action_quit_run(self) -> None:
        """Quit; mid-run only once the experimenter says yes (as for abort)."""
        if self.session.phase in (Phase.DONE, Phase.ABORTED) or self._ending:
            await self.app.run_action("quit")
            return

        async def confirmed(yes: bool | None) -> None:
            if yes:
                await self.app.run_action("quit")

        self.app.push_screen(Confirm("Quit now?\nA stimulus in progress is cut short and the pins "
                                     "go to rest; rows logged so far stay, and the exit line "
                                     "says how to resume the run."), confirmed)

    def action_abort(self) -> None:
        def confirmed(yes: bool | None) -> None:
            if yes:
                self._end(ABORT_REASON)

        self.app.push_screen(Confirm("Abort this run?\nRows logged so far stay; the run can be "
                                     "resumed later from the start screen."), confirmed)

    @on(ResponsePad.Proceed, "#pad")
    def _proceed(self) -> None:
        # Enter with nothing to confirm does what Space does, or says why not.
        for action, act in (("begin", self.action_begin), ("present", self.action_present)):
            if self.check_action(action, ()):
                act()
                return
        if self.session.phase is Phase.RESPONSE:
            self.notice.say("type the answer first" + (", or click a pin" if self.pins_answer
                                                        else ""))
        else:
            self.notice.say(self.refusal(("present",)))

    @on(ResponsePad.Typed, "#pad")
    def _typed(self) -> None:
        if self.notice.has_class("-error"):
            self.notice.clear()  # the entry being corrected: the complaint about it goes
        self._draw_grid(frozenset())

    @on(PinGrid.Selected, "#pins")
    def _pin_clicked(self, message: PinGrid.Selected) -> None:
        if self.session.phase is Phase.RESPONSE and not self.pins_answer:
            self.notice.say("not an answer here: " + self.answers.hint)
            return
        if self.session.phase is not Phase.RESPONSE:
            self.notice.say(self.unbound("0"))
            return
        self.query_one(ResponsePad).choose(message.pin)

    @on(ResponsePad.Answered, "#pad")
    def _answered(self, message: ResponsePad.Answered) -> None:
        answer = "none" if message.answer in ("0", "none") else message.answer
        try:
            self.session.respond(answer)
        except SessionError as error:
            self.notice.say(str(error), error=True)  # e.g. pin 17: the entry stays for correcting
            return
        self.notice.clear()
        self.query_one(ResponsePad).clear()

    def _end(self, reason: str) -> None:
        """Close the run (abort it if unfinished), rest the pins, then show the end screen."""
        if self._ending:
            return
        self._ending = True
        self._ticker.pause()
        self._show("#phase", "Closing the run; pins to rest…")
        self.refresh_keys()
        cast("PinArrayApp", self.app).finish_run(self.session, reason)


def _pins_of(session: Session, condition: Condition) -> tuple[int, ...]:
    return tuple(sorted({d.pin for d in trial_drives(session.protocol, condition)}))

