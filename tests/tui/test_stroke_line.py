"""Issue 27: once a stimulus has played, the run screen says how far the pin moved against how
far it was commanded, in steps and mm, marks a trial whose pin fell short, and says nothing
where the servos report no position (PWM boards); whole at 80x24 as at 120x40."""

from pinarray.journal.records import TrialStatus
from pinarray.journal.rows import read_trials
from pinarray.session.trials import Phase
from pinarray.tui.run_screen import RunScreen
from tests.tui.conftest import PROTOCOLS, SIZE, SMALL, both_sizes, make_app, settle, to_run_screen
from tests.tui.test_small_terminal import says, unseen

SLOW_SERVOS = "sim://?speed=1500"  # half the seed's speed: 65 steps at 10 Hz fall short


async def _first_stimulus(pilot) -> RunScreen:
    await to_run_screen(pilot)
    screen = pilot.app.screen
    assert isinstance(screen, RunScreen)
    await pilot.press("space")  # leave the instructions
    await settle(pilot)
    assert says(screen, "#stroke") == ""  # nothing has played yet
    await pilot.press("space")
    await settle(pilot)
    return screen


# The stroke achieved of the commanded after a stimulus that kept up ("stroke 65/65 steps
# (1.00 mm)", not marked short) is checked at both sizes on the walk through every phase of a run
# (test_small_terminal.py::test_every_phase_of_a_run_shows_every_key_answer_and_notice_whole).


async def test_a_pin_that_fell_short_is_marked_on_the_run_screen_with_its_row_s_numbers(
        results, short_localisation):
    # 1 s stimuli: ten cycles of 10 Hz fall short as a hundred do, for a tenth of the servos'
    # simulation.
    app = make_app(results, protocol=short_localisation, sim_url=SLOW_SERVOS)
    async with app.run_test(size=SMALL) as pilot:
        screen = await _first_stimulus(pilot)
        session = screen.session
        while session.phase is Phase.RESPONSE:  # the 5 Hz practice trial keeps up
            await pilot.press(str(session.current.condition.pin), "enter")
            await settle(pilot)
            await pilot.press("space")
            await settle(pilot)
        assert session.phase is Phase.FAULT
        shown = says(screen, "#stroke")
        async for size in both_sizes(pilot):
            assert says(screen, "#stroke") == shown
            assert screen.query_one("#stroke").has_class("-short")
            assert unseen(screen) == [], size
        await pilot.press("q")
        await settle(pilot)
    (beh,) = results.rglob("*_beh.tsv")
    short = [r for r in read_trials(beh) if r.status is TrialStatus.INVALID][-1]
    stroke = short.stroke
    assert stroke.achieved_steps < stroke.commanded_steps
    assert shown.startswith(f"stroke {stroke.achieved_steps}/{stroke.commanded_steps} steps (")
    assert shown.endswith(f" of 1.00 mm) · SHORT in {stroke.short_cycles} cycles")


async def test_the_run_screen_shows_no_stroke_where_the_servos_report_no_position(results):
    app = make_app(results, protocol=PROTOCOLS / "localisation_pwm.yaml")
    async with app.run_test(size=SIZE) as pilot:
        screen = await _first_stimulus(pilot)
        assert screen.session.phase is Phase.RESPONSE
        assert says(screen, "#stroke") == ""
        await pilot.press("q")
        await settle(pilot)
