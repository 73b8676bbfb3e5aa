"""Whole sessions driven through the UI by keys and clicks, checked in the results files; the
end screen they reach shows its summary, files and buttons whole at 120x40 and at 80x24."""

import pytest

from pinarray.grid import classify
from pinarray.journal.manifest import read_manifest
from pinarray.journal.rows import read_trials
from pinarray.session.trials import Phase
from pinarray.tui.end_screen import EndScreen
from pinarray.tui.run_screen import RunScreen
from tests.lab_protocols import short_copy
from tests.tui.conftest import MOTION, SIZE, both_sizes, make_app, settle, to_run_screen
from tests.tui.test_small_terminal import unseen

# The seed's localisation protocol (0.4 s stimuli) on four of its eight pins, at its three
# frequencies: a plan of 14 trials in which each way of answering (a pin typed, "none", the pin
# to the right clicked twice) comes four times or more, run whole as the 26 of all eight were.
FOUR_PINS = ("pins: [1, 4, 6, 7, 10, 11, 13, 16]", "pins: [1, 6, 11, 16]")


@pytest.mark.long
async def test_a_whole_localisation_session_by_typing_and_clicking(results, tmp_path):
    app = make_app(results, protocol=short_copy("localisation", tmp_path, FOUR_PINS))
    answers = {}
    async with app.run_test(size=SIZE) as pilot:
        await to_run_screen(pilot)
        screen = app.screen
        assert isinstance(screen, RunScreen)
        session = screen.session
        await pilot.press("space")  # leave the instructions
        await settle(pilot)
        while session.phase is Phase.READY:
            await pilot.press("space")
            await settle(pilot)
            assert session.phase is Phase.RESPONSE
            planned = session.current
            pin = planned.condition.pin
            if planned.trial % 3 == 0:
                answers[planned.trial] = "none"
                await pilot.press("n", "enter")
            elif planned.trial % 3 == 1:
                answers[planned.trial] = str(pin)
                await pilot.press(*str(pin), "enter")
            else:  # the pin to its right on the grid, clicked twice (choose, confirm)
                answers[planned.trial] = str(pin % 16 + 1)
                await pilot.click(f"#pin-{pin % 16 + 1}")
                await pilot.click(f"#pin-{pin % 16 + 1}")
            await settle(pilot)
        await pilot.press("x")  # not a key here: the notice says so, in view too
        async for size in both_sizes(pilot):  # its summary, files and buttons all in view
            assert isinstance(app.screen, EndScreen)
            summary = str(app.screen.query_one("#summary").render())
            assert "Hz:" in summary and "% correct" in summary
            assert unseen(app.screen) == [], size
    (beh,) = results.rglob("*_beh.tsv")
    rows = read_trials(beh)
    assert [r.trial for r in rows] == list(range(1, 15))
    for row in rows:
        assert row.status == "ok" and row.response == answers[row.trial]
        expected = "none" if row.response == "none" else str(classify(row.pin, int(row.response)))
        assert row.category == expected  # the error class, or nothing felt
    assert [r.practice for r in rows[:3]] == [True, True, False]
    (manifest,) = results.rglob("*_manifest.json")
    assert read_manifest(manifest).status == "completed" and read_manifest(manifest).seed == 3


@pytest.mark.long
async def test_a_whole_motion_session_by_keys_and_buttons(results):
    app = make_app(results, protocol=MOTION, seed=5)
    keys = {"left": "l", "right": "r", "none": "n", "unsure": "u"}
    given = {}
    async with app.run_test(size=SIZE) as pilot:
        await to_run_screen(pilot)
        session = app.screen.session
        await pilot.press("enter")  # Enter, like Space, leaves the instructions
        await settle(pilot)
        while session.phase is Phase.READY:
            await pilot.press("enter")
            await settle(pilot)
            planned = session.current
            truth = planned.condition.direction
            answer = truth if planned.trial % 4 else "unsure"
            given[planned.trial] = answer
            if planned.trial % 2:
                await pilot.press(keys[answer])
            else:
                await pilot.click(f"#answer-{answer}")
            await settle(pilot)
        await pilot.press("x")  # not a key here: the notice says so, in view too
        async for size in both_sizes(pilot):  # its summary, files and buttons all in view
            assert isinstance(app.screen, EndScreen)
            assert "motion felt" in str(app.screen.query_one("#summary").render())
            assert unseen(app.screen) == [], size
    (beh,) = results.rglob("*_beh.tsv")
    rows = read_trials(beh)
    assert len(rows) == 13 and all(r.status == "ok" for r in rows)
    for row in rows:
        assert row.response == given[row.trial]
        assert row.perceived_motion is (row.response != "none")
        if row.direction != "none" and row.response != "none":
            assert row.direction_correct is (row.response == row.direction)
