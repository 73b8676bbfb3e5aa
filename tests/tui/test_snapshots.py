"""What the experimenter sees: start, run and end screens, fixed seed and virtual time."""

from pathlib import Path

import pytest
from textual.widgets import Input

from pinarray.session.trials import Phase
from tests.runs import write_short_localisation
from tests.tui.conftest import SIZE, fill_start, make_app, settle, to_run_screen


@pytest.fixture
def app(tmp_path, monkeypatch):
    # Results under the working folder, so the end screen shows the same short paths each time.
    monkeypatch.chdir(tmp_path)
    return make_app(Path("results"))


async def still(pilot):
    for entry in pilot.app.screen.query(Input):
        entry.cursor_blink = False
    await settle(pilot)


SMALL = (80, 24)  # the smallest terminal a lab laptop opens: everything needed must show


@pytest.mark.parametrize("size", [SIZE, SMALL], ids=["120x40", "80x24"])
def test_start_screen(app, snap_compare, size):
    async def run_before(pilot):
        await fill_start(pilot, subject="07")
        pilot.app.screen.query_one("#experimenter").focus()
        await pilot.press("J", "K")
        await still(pilot)

    assert snap_compare(app, terminal_size=size, run_before=run_before)


@pytest.mark.parametrize("size", [SIZE, SMALL], ids=["120x40", "80x24"])
def test_run_screen_with_a_pin_typed_after_two_practice_trials(app, snap_compare, size):
    async def run_before(pilot):
        await to_run_screen(pilot)
        session = pilot.app.screen.session
        await pilot.press("space")
        for answer in ("1", "none"):
            await pilot.press("space")
            await settle(pilot)
            session.respond(answer)
        await pilot.press("space")
        await settle(pilot)
        await pilot.press("1")
        await still(pilot)
        assert session.phase is Phase.RESPONSE

    assert snap_compare(app, terminal_size=size, run_before=run_before)


@pytest.mark.long
def test_end_screen_of_a_whole_localisation_run(tmp_path, monkeypatch, snap_compare):
    # The seed's plan with 1 s stimuli: the end screen shows the answers, not the stimuli's
    # length, and ten seconds of simulated servos per trial were most of this test's time.
    monkeypatch.chdir(tmp_path)
    app = make_app(Path("results"), protocol=write_short_localisation(tmp_path))

    async def run_before(pilot):
        await to_run_screen(pilot)
        session = pilot.app.screen.session
        session.begin()
        while session.phase is Phase.READY:  # the keys are tested elsewhere; here the result
            session.present()
            pin = session.current.condition.pin
            session.respond(pin if session.current.trial % 3 else pin % 16 + 1)
        await still(pilot)

    assert snap_compare(app, terminal_size=SIZE, run_before=run_before)
