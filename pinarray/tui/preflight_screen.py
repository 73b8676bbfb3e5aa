"""Pre-flight: connect, show every servo's state and return delay, wiggle pins, then begin the
run."""

from __future__ import annotations

import math
import threading

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, VerticalScroll
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Button, DataTable, Input, Static

from pinarray.errors import PinArrayError
from pinarray.hardware.feetech import packets
from pinarray.hardware.feetech.feetech import FeetechBus
from pinarray.hardware.feetech.registers import Register
from pinarray.hardware.pca9685.driver import Pca9685Array
from pinarray.player.timing import CheckSkipped, Verdict
from pinarray.session.sitting import SessionRequest, Sitting
from pinarray.session.trials import Session
from pinarray.tui.confirm import Confirm
from pinarray.tui.footer import KeyFooter
from pinarray.tui.notice import KeyNotices, Notice

# Two-line headings: the whole table fits an 80-column terminal, units still in the names.
COLUMNS = ("servo", "pin", "answers", "model", "position\n(steps)", "volts", "temp.\n(°C)",
           "return\ndelay (µs)", "errors")
# A goal's read-back on the wire: the READ request and the status packet carrying the goal.
GOAL = Register.GOAL_POSITION
READBACK_BYTES = len(packets.read(1, GOAL.address, GOAL.size)) + packets.status_size(GOAL.size)
BEGIN_LABEL = "Begin run (b)"


class PreflightScreen(KeyNotices, Screen):
    """Checks the hardware before the participant arrives.

    Parameters
    ----------
    sitting : Sitting
        Connects the rig (in a worker thread) and later opens the run.
    request : SessionRequest
        What the start screen chose.
    """

    # b and Escape whatever has focus: the pin field takes only digits anyway.
    BINDINGS = [Binding("escape", "back", "back", priority=True),
                Binding("b", "begin", "begin run", priority=True),
                # Said on the timing line while the check measures, not in the footer.
                Binding("s", "skip_timing", "skip timing check", priority=True, show=False)]

    class Measured(Message):
        """The timing check has measured ``done_ns`` of its ``total_ns``."""

        def __init__(self, done_ns: int, total_ns: int):
            super().__init__()
            self.done_ns = done_ns
            self.total_ns = total_ns

    def __init__(self, sitting: Sitting, request: SessionRequest):
        super().__init__()
        self.sitting = sitting
        self.request = request
        self.connected = False
        self._leaving = False
        self._good = ""  # the last status that was not a complaint
        # What the last timing check said when it was not OK (NOT OK, NOT SURE): Begin asks first.
        self._timing_doubt = ""
        # While the check measures: Begin waits for it (it holds the array), s skips it.
        self._measuring = False
        self._skip = threading.Event()
        self._begin_after_check = False

    def compose(self) -> ComposeResult:
        r = self.request
        bus = r.port or "simulated array"
        verb = "resume" if r.resume else "new run"
        yield Static(f"Pre-flight · {r.protocol.name} · sub-{r.subject} ses-{r.session} · "
                     f"{verb} · {bus}", id="title")
        # What is said about the array scrolls if it is long (80x24); the controls stay in view.
        with VerticalScroll(id="preflight-info"):
            yield Static("Connecting…", id="preflight-status")
            yield Static("", id="timing")
        yield DataTable(id="servos", cursor_type="none", zebra_stripes=True, header_height=2)
        with Horizontal(id="test-row"):
            yield Input(placeholder="pin", id="test-pin", type="integer")
            yield Button("Test pin", id="test", disabled=True)
            yield Static("wiggles one pin 3 times so you can feel or see it move", classes="hint")
        with Horizontal(id="preflight-buttons"):
            yield Button(BEGIN_LABEL, id="begin", variant="primary", disabled=True)
            yield Button("Connect again", id="reconnect", disabled=True)
            yield Button("Rest + torque off", id="release", disabled=True)
            yield Button("Lower return delay", id="lower-delay", disabled=True)
            yield Button("Back (Esc)", id="back")
        yield Notice()
        yield KeyFooter()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "begin":
            return self.connected and not self._leaving
        if action == "back":
            return not self._leaving
        if action == "skip_timing":
            return self._measuring and not self._skip.is_set()
        return True

    def refusal(self, actions: tuple[str, ...]) -> str:
        if self._leaving:
            return "leaving: pins to rest, torque off…"
        return "not connected: the run can begin once the array answers"

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        for label in COLUMNS:
            table.add_column(label)  # as wide as its heading or its widest value
        self._connect()

    def _status(self, text: str, problem: bool = False) -> None:
        status = self.query_one("#preflight-status", Static)
        status.update(text)
        status.set_class(problem, "-problem")
        if not problem:
            self._good = text

    def _ready(self, connected: bool) -> None:
        self.connected = connected
        self.query_one("#begin", Button).disabled = not connected
        self.query_one("#test", Button).disabled = not connected
        self.query_one("#reconnect", Button).disabled = connected
        self.query_one("#release", Button).disabled = not connected
        self.query_one("#lower-delay", Button).disabled = not connected
        self.refresh_keys()

    # -- hardware work, in threads -----------------------------------------------------------

    @work(thread=True, exclusive=True, group="hardware")
    def _connect(self) -> None:
        try:
            rig = self.sitting.connect(self.request)
            readings = rig.telemetry()
        except PinArrayError as problem:
            self.app.call_from_thread(self._failed, str(problem))
            return
        note = "; ".join(rig.warnings)
        self.app.call_from_thread(self._connected, readings, note)
        self.app.call_from_thread(self._check_timing)

    def _check_timing(self) -> None:
        duration_ns = self.app.options.timing_check_ns  # type: ignore[attr-defined]
        if duration_ns != 0:
            self._timing_line("Timing: measuring this machine" + (
                "…" if duration_ns is None else f" for {duration_ns / 1e9:g} s…"))
            self._measuring = True
            self._skip.clear()
            self.refresh_keys()
            self._timing(duration_ns)

    @work(thread=True, exclusive=True, group="timing")
    def _timing(self, duration_ns: int | None) -> None:
        def measured(done_ns: int, total_ns: int) -> bool:
            # Posted, not waited for: the check holds the port, and an event loop held by a
            # terminal that stopped reading would hold the check with it, and every close
            # after it (the UI never left on SIGTERM, the port held).
            self.post_message(self.Measured(done_ns, total_ns))
            return not self._skip.is_set()

        try:
            verdict = self.sitting.check_timing(duration_ns, measured)
        except PinArrayError as problem:  # not connected any more, among others
            self.app.call_from_thread(self._timing_line, f"Timing: not checked ({problem})", True)
            verdict = None
        self.app.call_from_thread(self._timing_done, verdict)

    @on(Measured)
    def _measured(self, message: Measured) -> None:
        """A slice of the check measured: the seconds left, and what Begin and s do now."""
        done_ns, total_ns = message.done_ns, message.total_ns
        if not self._measuring or self._skip.is_set():
            return
        left_s = math.ceil((total_ns - done_ns) / 1e9)
        text = f"Timing: measuring this machine, {left_s} s left (s skips the check)"
        if self._begin_after_check:
            text += "\nThe run begins when the check ends."
        self._timing_line(text)

    def _timing_done(self, outcome: Verdict | CheckSkipped | None) -> None:
        self._measuring = False
        self.refresh_keys()
        match outcome:
            case Verdict():
                self._timing_doubt = "" if outcome.deliverable else outcome.judgement.value
                # The answer first: at 80x24 the measurements' lines wrap longer as the machine
                # is busier, and would push it below what the box shows.
                self._timing_line("Timing: " + "\n".join(outcome.judgement_first),
                                  not outcome.deliverable)
            case CheckSkipped():
                # A verdict measured before (a re-check after Lower return delay) still
                # stands: what it doubted, Begin still asks about.
                earlier = f"; the last verdict: {self._timing_doubt}" if self._timing_doubt else ""
                self._timing_line(f"Timing: {outcome.describe()}{earlier} (written in the "
                                  "run's records)", bool(self._timing_doubt))
        if self._begin_after_check:
            self._begin_after_check = False
            self.query_one("#begin", Button).label = BEGIN_LABEL
            if outcome is not None:
                self.action_begin()
            elif not self._leaving:  # the check failed or was stopped: say so, not silence
                self.notice.say("Begin cancelled: the timing check ended without a verdict; "
                                "b begins without it")

    def action_skip_timing(self) -> None:
        if self._measuring:
            self._skip.set()
            self.refresh_keys()
            self._timing_line("Timing: skipping the check…")

    def _timing_line(self, text: str, problem: bool = False) -> None:
        line = self.query_one("#timing", Static)
        line.update(text)
        line.display = bool(text)  # no blank lines before the check (or without one)
        line.set_class(problem, "-problem")
        # At 80x24 the news above the table scrolls: the verdict, said last, is what to see.
        self.call_after_refresh(line.scroll_visible, top=True, animate=False)

    @work(thread=True, exclusive=True, group="hardware")
    def _test(self, pin: int) -> None:
        try:
            self.sitting.test_pin(pin)
            readings = self.sitting.connected().telemetry()
        except PinArrayError as problem:
            self.app.call_from_thread(self._status, f"Test of pin {pin} failed: {problem}", True)
            return
        self.app.call_from_thread(self._connected, readings, f"pin {pin} tested")

    # -- results, on the UI thread -----------------------------------------------------------

    def _connected(self, readings, note: str) -> None:
        bus = self.sitting.connected().bus
        if isinstance(bus, Pca9685Array):
            self._board_connected(bus, note)
            return
        table = self.query_one(DataTable)
        table.clear()
        by_id = {t.servo_id: t for t in readings}
        model = self.request.protocol.device.servo.model
        # Return delays are the Feetech family's (read by its handshake); others show none.
        delays_ns = bus.link.return_delay_ns if isinstance(bus, FeetechBus) else {}
        for servo in self.sitting.connected().setup.servos:
            t = by_id.get(servo.servo_id)
            delay = (str(delays_ns[servo.servo_id] // 1000) if servo.servo_id in delays_ns
                     else "")
            if t is None:
                table.add_row(str(servo.servo_id), str(servo.pin), "no", model, "", "", "",
                              delay, "")
            else:
                table.add_row(str(servo.servo_id), str(servo.pin), "yes", model,
                              str(t.position_steps), f"{t.voltage_v:.1f}", str(t.temperature_c),
                              delay, t.errors.describe())
        faulty = [t.servo_id for t in readings if t.errors.describe() != "none"]
        where = self.request.port or "the simulated array"
        servos = self.sitting.connected().setup.servos
        text = (f"Connected to {where}: {len(readings)} of {len(servos)} "
                f"servos answer, all {model} (checked at connect).")
        if faulty:
            text += f" Servo(s) {', '.join(map(str, faulty))} report errors."
        text += (f" Which trains the pins can follow: "
                 f"{self.request.protocol.device.feasibility_basis()}.")
        # A servo that waits longer before answering than the read-back itself takes on the
        # wire slows every delivery check more than the wire does.
        wire_ns = bus.wire_ns(READBACK_BYTES) if isinstance(bus, FeetechBus) else 0
        slow = sorted(i for i, ns in delays_ns.items() if ns > wire_ns)
        if slow:
            text += (f" Servo(s) {', '.join(map(str, slow))} wait longer before answering than "
                     f"a read-back takes on the wire ({wire_ns // 1000} µs): Lower return delay "
                     "(0 µs until power-off) makes delivery checks faster.")
        if note:
            text += f" ({note})"
        self._status(text, bool(faulty))
        self._ready(True)

    def _board_connected(self, board: Pca9685Array, note: str) -> None:
        """A PWM board: hobby servos report nothing, so the table says what each pin is sent."""
        table = self.query_one(DataTable)
        table.clear()
        model = self.request.protocol.device.servo.model
        for servo in board.setup.servos:
            table.add_row(f"ch {servo.servo_id}", str(servo.pin), "no feedback", model,
                          f"{servo.rest_steps} us", "", "", "", "")
        self.query_one("#lower-delay", Button).display = False
        where = self.request.port or "the simulated board"
        setup = board.setup
        text = (f"Connected to {where}: PCA9685 at 0x{setup.address:02x}, its oscillator "
                f"{setup.osc_hz / 1e6:g} MHz as the protocol states it, {len(setup.servos)} "
                f"{model} hobby servos holding rest. Hobby servos report nothing back: the "
                "table shows each pin's channel and rest width, not where it is; each trial's "
                "board rate and drift are checked before it plays.")
        if note:
            text += f" ({note})"
        self._status(text)
        self._ready(True)

    def _failed(self, problem: str) -> None:
        self._status(f"Could not connect: {problem}\nCheck power and cables, then Connect again, "
                     "or Back to choose another array.", True)
        self._ready(False)

    # -- buttons -----------------------------------------------------------------------------

    @on(Input.Changed, "#test-pin")
    def _pin_edited(self) -> None:
        if self.query_one("#preflight-status", Static).has_class("-problem") and self.connected:
            self._status(self._good)  # the complaint about the last entry is out of date

    @on(Button.Pressed, "#test")
    @on(Input.Submitted, "#test-pin")
    def _test_pressed(self) -> None:
        text = self.query_one("#test-pin", Input).value.strip()
        if not self.connected:
            return
        try:
            pin = self.request.protocol.device.grid.check_pin(int(text))
        except (ValueError, PinArrayError):
            count = self.request.protocol.device.grid.pin_count
            self._status(f"Test pin: expected a pin from 1 to {count}, found {text!r}", True)
            return
        self._status(f"Testing pin {pin}…")
        self._test(pin)

    @on(Button.Pressed, "#reconnect")
    def _reconnect(self) -> None:
        self._status("Connecting…")
        self._connect()

    @on(Button.Pressed, "#release")
    def _release_pressed(self) -> None:
        self._start(self._release, "Pins to rest, torque off…")

    def _start(self, job, status: str) -> None:
        """A hardware job on the connected array; the buttons wait until it is done."""
        if not self.connected:
            return
        self._ready(False)
        self._status(status)
        job()

    @work(thread=True, exclusive=True, group="hardware")
    def _release(self) -> None:

        # Lets go of the array (as `pinarray servos rest` does), e.g. to adjust a horn by hand.
        safe = self.sitting.release("rest and torque off from the pre-flight")
        text = "nothing was connected" if safe is None else safe.describe()
        self.app.call_from_thread(
            self._status, f"Released: {text}, port closed. Connect again to go on.",
            safe is None or not safe.complete)

    @on(Button.Pressed, "#lower-delay")
    def _lower_delay_pressed(self) -> None:
        self._start(self._lower_delay,
                    "Lowering every servo's return delay to 0 µs (until power-off)…")

    @work(thread=True, exclusive=True, group="hardware")
    def _lower_delay(self) -> None:
        try:
            result = self.sitting.lower_return_delay(0)
            readings = self.sitting.connected().telemetry()
        except PinArrayError as problem:
            self.app.call_from_thread(self._failed, f"lowering the return delay: {problem}")
            return
        if result is None:
            return  # stopped: the screen is being left
        changes, failures = result
        note = f"return delay 0 µs until power-off on {len(changes)} servo(s)"
        if failures:
            note += "; " + "; ".join(f.problem for f in failures)
        self.app.call_from_thread(self._connected, readings, note)
        # Read-backs are faster now: the timing verdict is measured again for them.
        self.app.call_from_thread(self._check_timing)

    @on(Button.Pressed, "#begin")
    def action_begin(self) -> None:
        if not self.connected or self._leaving:
            return
        if self._measuring:
            # The check holds the array: a stimulus now would wait for it in silence.
            self._begin_after_check = True
            self.query_one("#begin", Button).label = "After check…"
            self._timing_line("Timing: measuring this machine; the run begins when the check "
                              "ends (s skips the check: written in the run's records)")
            return
        if not self._timing_doubt:
            self._begin()
            return

        def confirmed(yes: bool | None) -> None:
            if yes and self.connected and not self._leaving:
                self._begin()

        self.app.push_screen(Confirm(
            f"Begin although the timing check said {self._timing_doubt}?\nOn this machine now, "
            "stimuli may be reported not delivered (each is then presented again, up to 3 "
            "times)."),
            confirmed)

    def _begin(self) -> None:
        from pinarray.tui.run_screen import RunScreen
        from pinarray.tui.scanner_screen import ScannerScreen, scanner_settings

        self._leaving = True  # b twice: one run
        try:
            sync = scanner_settings(self.request, self.app.options.sync)  # type: ignore[attr-defined]
            if sync is not None:  # the run opens at the scanner's first counted volume
                self.app.push_screen(ScannerScreen(self.sitting, sync), self._scanner_done)
                return
            session = self.sitting.open_session()
        except PinArrayError as problem:
            self._leaving = False
            self._status(f"Cannot open the run: {problem}", True)
            # The reason at the top of the news, in view (it scrolls at 80x24), and a word on
            # the notice line, so that a press of b is never met by nothing visible.
            self.query_one("#preflight-info").scroll_home(animate=False)
            self.query_one(Notice).say("Cannot open the run: the reason is at the top, in red",
                                       error=True)
            return
        self.app.switch_screen(RunScreen(self.sitting, session))

    def _scanner_done(self, session: Session | None) -> None:
        from pinarray.tui.run_screen import RunScreen

        if session is None:
            self._leaving = False  # back on this screen: b may begin again
            self.refresh_keys()
            self._status("Stopped waiting for the scanner; no run was started.")
        else:
            self.app.switch_screen(RunScreen(self.sitting, session))

    @on(Button.Pressed, "#back")
    def action_back(self) -> None:
        if self._leaving:
            return
        self._leaving = True
        self.refresh_keys()
        self._status("Leaving: pins to rest, torque off…")
        self._leave()

    @work(thread=True, exclusive=True, group="leave")
    def _leave(self) -> None:
        # Stops a test pin or a timing check first, then pins to rest, torque off.
        self.sitting.release()
        self.app.call_from_thread(self.app.pop_screen)
