"""At 80x24 (tmux on a lab laptop) as at 120x40, every screen in every phase shows each button,
each answer, each key hint and what it says whole: nothing off screen, cut, or behind a scroll.

Issue 24: at 80x24 the pre-flight's last buttons were off screen yet focusable, its table a
scrollbar; the run screen cut the summary and hid the notice, the last answer and two of the four
motion answers.
"""

import html
import re
import threading
from itertools import cycle

import pytest
from textual.content import Content
from textual.errors import NoWidget
from textual.widgets import Button, Static

from pinarray.errors import BusError
from pinarray.player.rig import Rig
from pinarray.player.timing import PortFigures, WakeUps, judge
from pinarray.protocol.imaging import SyncOverrides, parse_trigger
from pinarray.session.trials import Phase
from pinarray.tui.app import PinArrayApp, TuiOptions
from pinarray.tui.confirm import Confirm
from pinarray.tui.end_screen import EndScreen
from pinarray.tui.error_screen import ErrorScreen
from pinarray.tui.outcome import Crashed
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.scanner_screen import ScannerScreen
from tests.many_ways import write_many_ways
from tests.test_adaptive_runs import read_writer_paths
from tests.tui.conftest import (
    LOCALISATION,
    MOTION,
    PROTOCOLS,
    SMALL,
    both_sizes,
    fill_start,
    make_app,
    settle,
    to_run_screen,
)

PARADIGMS = pytest.mark.parametrize("protocol", [LOCALISATION, MOTION],
                                    ids=["localisation", "motion"])
# Read by scrolling on purpose: the pre-flight's news of the array above the table.
SCROLLS = frozenset({"preflight-info", "end-info"})


def shown_text(widget) -> str:
    return str(widget.render()).strip() if isinstance(widget, Static) else "control"


def meant_to_show(widget) -> bool:
    return all(node.display and node.visible for node in (widget, *widget.ancestors)
               if hasattr(node, "display"))


def unseen(screen) -> list[str]:
    """Each button, key hint and line of text of ``screen`` that is not wholly in view, and why."""
    problems = []
    for widget in screen.query("*"):
        if not isinstance(widget, Static | Button) and type(widget).__name__ != "FooterKey":
            continue
        if not meant_to_show(widget) or not shown_text(widget):
            continue
        if any(node.id in SCROLLS for node in widget.ancestors):
            continue
        name = f"{type(widget).__name__} {widget.id or shown_text(widget)[:40]!r}"
        try:
            where = screen.find_widget(widget)
        except NoWidget:
            problems.append(f"{name}: not on the screen")
            continue
        region = where.region
        if region.area == 0:
            problems.append(f"{name}: no room at all")
            continue
        if region.intersection(screen.region) != region:
            problems.append(f"{name}: {region} partly off the screen {screen.region}")
            continue
        if region.intersection(where.clip) != region:
            problems.append(f"{name}: {region} cut by its container (shows {where.clip})")
            continue
        corners = {(region.x, region.y), (region.right - 1, region.y), (region.x, region.bottom - 1),
                   (region.right - 1, region.bottom - 1), region.center}
        for x, y in corners:
            top, _ = screen.get_widget_at(int(x), int(y))
            if top is not widget and widget not in top.ancestors:
                problems.append(f"{name}: covered by {type(top).__name__} at {x},{y}")
                break
        box = widget.content_region
        if isinstance(widget, Button):
            label = Content.from_text(widget.label).cell_length
            if label + 2 > box.width:  # the label and a space either side (line-pad)
                problems.append(f"{name}: label of {label} columns in {box.width}")
        elif isinstance(widget, Static):
            needed = widget.get_content_height(widget.size, screen.size, box.width)
            if needed > box.height:
                problems.append(f"{name}: {needed} lines of text in {box.height}")
    return problems


def on_screen(app) -> str:
    """The characters the terminal shows, row after row."""
    svg = app.export_screenshot()
    return html.unescape(re.sub(r"<[^>]+>", "", svg)).replace("\xa0", " ")


def says(screen, selector: str) -> str:
    return str(screen.query_one(selector, Static).render())


class ArrayRig(Rig):
    """The simulated array, made to hold a stimulus until released, or to fail one."""

    hold: threading.Event | None = None
    failures = 0

    def present(self, schedule):
        if self.hold is not None:
            self.hold.wait(30)
        if ArrayRig.failures:
            ArrayRig.failures -= 1
            raise BusError("servo 10 (pin 10): no status packet after 3 retries; the cable or "
                           "the servo's power may have come loose")
        return super().present(schedule)

    def check_timing(self, duration_ns=0, period_ns=0, progress=None):
        # A busy laptop's verdict: the longest the pre-flight has to show.
        return judge(WakeUps(2000, 1_200_000, 9_800_000, 32_100_000),
                     "no real-time priority (run `pinarray setup-realtime` once, then log in "
                     "again)", PortFigures("/dev/ttyUSB0", 8, 3_400_000, 16), 10_000_000)


@pytest.fixture(autouse=True)
def fresh_rig():
    ArrayRig.hold, ArrayRig.failures = None, 0


# -- start and pre-flight --------------------------------------------------------------------
# Checked in view on the walks that make them in test_run_controls: the start form saying what
# is wrong and the pre-flight connected (test_mistakes_...), the pre-flight that cannot connect
# (test_a_failed_handshake_...), the aborted run's end screen, the form offering to resume it and
# the resumed run (test_abort_asks_first_...); the pre-flight after a NOT OK timing check in
# test_preflight_verdict.


def lock_is_free(paths) -> bool:
    """Whether nobody (this process included: flock is per open file) holds the run's lock."""
    import fcntl

    with open(paths.lock, "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        fcntl.flock(lock, fcntl.LOCK_UN)
    return True


async def test_a_begin_that_fails_says_why_in_view_every_time_and_leaves_the_run_unlocked(
        results):
    from tests.test_adaptive_runs import STAIRCASES, edited_run

    beh, line, trial = edited_run(results)  # its rows refuse to be resumed
    paths = read_writer_paths(results, "staircasemotion")
    app = make_app(results, protocol=STAIRCASES)
    async with app.run_test(size=SMALL) as pilot:
        await fill_start(pilot)
        await pilot.click("#resume")
        await settle(pilot)
        for _ in range(3):  # each press says the same, not "open in another process"
            await pilot.press("b")
            await settle(pilot)
            screen = app.screen
            assert isinstance(screen, PreflightScreen)
            assert screen.notice.text == "Cannot open the run: the reason is at the top, in red"
            assert unseen(screen) == []
            status = screen.query_one("#preflight-status", Static)
            assert says(screen, "#preflight-status").startswith(
                f"Cannot open the run: {beh}:{line}: trial {trial}: correct is ")
            news = screen.query_one("#preflight-info")
            assert status.region.intersection(news.region) == status.region  # all in view
            assert lock_is_free(paths)
    assert len(list(results.rglob("*_beh.tsv"))) == 1  # no new run either
    assert (results / "participants.tsv").read_text().count("sub-01") == 1


async def test_the_scanner_wait_shows_what_it_waits_for_and_how_to_stop(results):
    options = TuiOptions(protocol_path=LOCALISATION, protocols_dir=PROTOCOLS, results_root=results,
                         time_scale=0, seed=3, timing_check_ns=0,
                         sync=SyncOverrides(parse_trigger("serial:/dev/no-such-trigger"), 4))
    app = PinArrayApp(options, list_ports=lambda: [])
    async with app.run_test(size=SMALL) as pilot:
        await fill_start(pilot)
        await pilot.click("#start")
        await settle(pilot)
        await pilot.press("b")
        await settle(pilot)
        async for size in both_sizes(pilot):
            assert isinstance(app.screen, ScannerScreen)
            assert "cannot open the trigger device" in says(app.screen, "#scanner-state")
            assert unseen(app.screen) == [], size


# -- the run ---------------------------------------------------------------------------------


async def answer(pilot, protocol):
    """The trial awaiting its answer gets one (pin 1, or left)."""
    await pilot.press(*(["1", "enter"] if protocol == LOCALISATION else ["l"]))
    await settle(pilot)


@pytest.mark.long
@PARADIGMS
async def test_every_phase_of_a_run_shows_every_key_answer_and_notice_whole(
        results, protocol, short_localisation):
    """One run walked through each phase the experimenter meets: the instructions, a trial
    played (and how far its pins moved), a trial ready, a stimulus playing, the answer awaited,
    each question, a pause and a failed stimulus; in each, at 80x24 and at 120x40, every key,
    answer, notice and line is in view and whole. Localisation with 1 s stimuli: the screens
    are the point, not ten seconds of simulated servos per trial."""
    app = make_app(results, protocol=short_localisation if protocol == LOCALISATION else protocol,
                   rig_factory=ArrayRig)
    async with app.run_test(size=SMALL) as pilot:
        await to_run_screen(pilot)
        screen = app.screen
        session = screen.session
        # The instructions.
        assert session.phase is Phase.INSTRUCTIONS
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size
        # The first trial played and awaiting its answer: how far its pins moved (issue 27).
        await pilot.press("space")
        await settle(pilot)
        assert says(screen, "#stroke") == ""  # nothing has played yet
        await pilot.press("space")
        await settle(pilot)
        assert session.phase is Phase.RESPONSE
        if protocol == LOCALISATION:
            async for size in both_sizes(pilot):
                # The seed rig's 10 mm horn: 65 steps of 4096 a turn lift the pin 1.00 mm.
                assert says(screen, "#stroke") == "stroke 65/65 steps (1.00 mm)", size
                assert not screen.query_one("#stroke").has_class("-short"), size
                assert unseen(screen) == [], size
        await answer(pilot, protocol)
        # A trial ready to present, after the first was answered.
        await pilot.press("x")
        assert session.phase is Phase.READY
        assert says(screen, "#stroke") == ""  # the next trial has not played yet
        assert says(screen, "#last").startswith("last: practice 1")
        assert screen.notice.text.startswith("x does nothing here")
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size
        # Its stimulus asked for, the array not free yet (held until the checks are done):
        # the screen says it waits, never that it plays.
        ArrayRig.hold = threading.Event()
        await pilot.press("space")
        rig = app.sitting.rig
        length_ns = session.current_schedule().end_ns
        into_ns = min(3_250_000_000, length_ns // 2)  # how far into it the array is stopped
        midway, go_on = threading.Event(), threading.Event()

        def stop_midway(packet):  # on the array's own thread, as the bytes reach the servos
            start_ns = rig.playing_from_ns
            if start_ns is not None and packet.end_ns >= start_ns + into_ns and not go_on.is_set():
                midway.set()
                go_on.wait(30)

        rig.bus.sim.packet_listener = stop_midway
        try:
            while session.phase is not Phase.STIMULUS:
                await pilot.pause(0.01)
            await pilot.press("x")
            await pilot.pause(0.2)  # a few frames of the screen's animation
            async for size in both_sizes(pilot):
                assert rig.playing_from_ns is None
                assert says(screen, "#phase") == "Stimulus starting: waiting for the array…"
                assert "playing" not in on_screen(app)
                assert screen.notice.text.startswith("x does nothing here")
                assert says(screen, "#last").startswith("last: practice 1")
                assert unseen(screen) == [], size
            # The array plays it, stopped a while into it: how far it has played of its length.
            ArrayRig.hold.set()
            while not midway.is_set():
                await pilot.pause(0.01)
            await pilot.pause(0.2)
            played_ns = app.sitting.clock.now_ns() - rig.playing_from_ns
            playing = f"Stimulus playing: {played_ns / 1e9:.1f} of {length_ns / 1e9:.1f} s"
            assert played_ns >= into_ns
            async for size in both_sizes(pilot):
                assert says(screen, "#phase") == playing, size
                assert playing in on_screen(app), size
        finally:
            ArrayRig.hold.set()
            go_on.set()
            await settle(pilot)
            rig.bus.sim.packet_listener = None
        # The answer awaited.
        await pilot.press("x")  # not an answer: the notice says what is
        assert session.phase is Phase.RESPONSE
        assert screen.notice.text.startswith("not an answer")
        assert says(screen, "#last").startswith("last: practice 1")
        assert len(screen.query("#pad Button")) == (0 if protocol == LOCALISATION else 4)
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size
        # Each question asked before quitting, aborting or redoing, and both its answers.
        for key in ("q", "a", "d"):
            await pilot.press(key)
            await settle(pilot)
            await pilot.press("x")
            assert isinstance(app.screen, Confirm), key
            assert app.screen.notice.text == "y: yes · n or Escape: no"
            async for size in both_sizes(pilot):
                assert unseen(app.screen) == [], (key, size)
            await pilot.press("n")
            await settle(pilot)
        # A pause.
        await pilot.press("p")
        await settle(pilot)
        await pilot.press("space")
        assert session.phase is Phase.PAUSED
        assert screen.notice.text == "paused: p resumes first"
        assert says(screen, "#last").startswith("last: practice 1")
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size
        await pilot.press("p")
        await settle(pilot)
        await answer(pilot, protocol)
        # A stimulus that failed.
        ArrayRig.failures = 1
        await pilot.press("space")
        await settle(pilot)
        await pilot.press("space")
        assert session.phase is Phase.FAULT
        assert "t: present the trial again" in says(screen, "#phase")
        assert screen.notice.text.startswith("the stimulus failed")
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size


async def test_waves_going_every_way_offer_every_direction_as_an_answer_all_in_view(
        results, tmp_path):
    app = make_app(results, protocol=write_many_ways(tmp_path))
    async with app.run_test(size=SMALL) as pilot:
        await to_run_screen(pilot)
        await pilot.press("space")
        await settle(pilot)
        await pilot.press("space")
        await settle(pilot)
        screen = app.screen
        assert screen.session.phase is Phase.RESPONSE
        answers = [str(b.id).removeprefix("answer-") for b in screen.query("#pad Button")]
        assert answers == ["left", "right", "up", "down", "up-right", "none", "unsure"]
        assert "↑ / ↓ / 1 (up-right)" in says(screen, "#phase")
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size
        await pilot.press("1")  # the first direction a sequence names
        await settle(pilot)
        assert screen.session.last.record.response == "up-right"


# -- the end ---------------------------------------------------------------------------------


@PARADIGMS
async def test_the_end_of_a_whole_run_shows_its_summary_files_and_buttons(results, protocol,
                                                                         short_localisation):
    if protocol == LOCALISATION:
        protocol = short_localisation  # the same plan; the end screen is the point
    app = make_app(results, protocol=protocol)
    async with app.run_test(size=SMALL) as pilot:
        await to_run_screen(pilot)
        session = app.screen.session
        session.begin()
        # Every kind of answer, so that the summary has all its lines: correct, nothing felt,
        # errors of each distance (the keys are tested elsewhere; here the result).
        kinds = cycle(("pin", "none", "1", "16", "6")) if protocol == short_localisation \
            else cycle(("left",))
        while session.phase is Phase.READY:
            session.present()
            kind = next(kinds)
            session.respond(str(session.current.condition.pin) if kind == "pin" else kind)
        await settle(pilot)
        await pilot.press("x")
        assert isinstance(app.screen, EndScreen)
        async for size in both_sizes(pilot):
            assert unseen(app.screen) == [], size


async def test_the_error_screen_shows_what_happened_and_how_to_leave(results):
    app = make_app(results)
    async with app.run_test(size=SMALL) as pilot:
        screen = ErrorScreen(Crashed(
            "RuntimeError: the player process ended without a word (exit status -9) while "
            "presenting practice 1 of 2",
            results / "sourcedata" / "crash-20250101T120000Z-12345.log", bug=True))
        await app.push_screen(screen)
        screen.closed("16 servo(s) at rest, 16 released")
        await pilot.pause()
        await pilot.press("x")
        async for size in both_sizes(pilot):
            assert unseen(screen) == [], size

