"""An adaptive design run from the UI: each trial's procedure and value shown, each track drawn."""

import pytest

from pinarray.journal.rows import read_trials
from pinarray.session.trials import Phase
from pinarray.tui.run_screen import RunScreen
from tests.tui.conftest import PROTOCOLS, SIZE, SMALL, make_app, resize, settle, to_run_screen

QUEST = PROTOCOLS / "quest_stroke.yaml"


@pytest.mark.long
async def test_the_run_screen_shows_the_value_presented_and_each_procedures_track(results):
    app = make_app(results, protocol=QUEST, seed=4)
    async with app.run_test(size=SMALL) as pilot:
        await to_run_screen(pilot)
        screen = app.screen
        assert isinstance(screen, RunScreen)
        session = screen.session
        await pilot.press("space")  # leave the instructions
        await settle(pilot)
        for trial in range(6):  # 2 practice, then the procedure's trials
            # Practice and the procedure's first trial at 80x24, the others at 120x40: each
            # kind of line drawn at both sizes in one run.
            if trial == 3:
                await resize(pilot, SIZE)
            await pilot.press("space")
            await settle(pilot)
            assert session.phase is Phase.RESPONSE
            shown = str(screen.query_one("#stimulus").render())
            presented = session.presented
            value = "its own stimulus" if presented.value is None else \
                f"stroke {float(presented.value):g} steps"
            assert f"{presented.procedure}: {value}" in shown
            pin = session.current.condition.pin
            await pilot.press(*str(pin), "enter")  # felt it, every time
            await settle(pilot)
        for size in (SIZE, SMALL):
            await resize(pilot, size)
            counts = str(screen.query_one("#counts").render())
            assert "quest " in counts and "· est " in counts, size
        await pilot.press("q")
        await settle(pilot)
    (beh,) = results.rglob("*_beh.tsv")
    rows = [r for r in read_trials(beh) if r.status == "ok"]
    assert len(rows) == 6 and all(r.adaptive is not None for r in rows)
    assert [r.adaptive.procedure for r in rows[:2]] == ["practice", "practice"]
