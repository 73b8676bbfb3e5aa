"""The run screen of the lab's paradigms, at 80x24 as at 120x40: the pad offers the
paradigm's answers (patterns as small grids, first or second, the pin that came first), each
one in view and answered by its key, and the stimulus line says what played."""

import pytest

from pinarray.session.trials import Phase
from tests.lab_protocols import short_copy
from tests.tui.conftest import SIZE, SMALL, make_app, resize, settle, to_run_screen
from tests.tui.test_small_terminal import says, unseen

# (protocol, the keys of its answers in the pad's order, the answers they record, what the
# stimulus line of its first trial starts with)
PARADIGMS = {
    "shapes": ("1234567", ["across", "upright", "rising", "falling", "L", "T", "square"],
               "stimulus: pattern "),
    "flutter_2ifc": ("12", ["first", "second"], "stimulus: frequency "),
    "toj": ("lr", ["6", "7"], "stimulus: pin "),
    "two_point": ("12", ["one", "two"], "stimulus: pin"),
}


# Shapes at 120x40 too (the most answers, drawn: the layout that changes most with the size),
# the same screen resized.
SIZES = {name: (SMALL, SIZE) if name == "shapes" else (SMALL,) for name in PARADIGMS}


@pytest.mark.parametrize("name", PARADIGMS)
async def test_every_answer_of_the_paradigm_is_in_view_and_answered_by_its_key(
        results, tmp_path, name):
    keys, answers, stimulus = PARADIGMS[name]
    app = make_app(results, protocol=short_copy(name, tmp_path))
    async with app.run_test(size=SMALL) as pilot:
        await to_run_screen(pilot)
        screen = app.screen
        await pilot.press("space")
        await settle(pilot)
        await pilot.press("space")
        await settle(pilot)
        assert screen.session.phase is Phase.RESPONSE
        for size in SIZES[name]:
            await resize(pilot, size)
            offered = [str(w.id).removeprefix("answer-") for w in screen.query("#pad .answer")]
            assert offered == answers
            assert says(screen, "#stimulus").startswith(stimulus)
            assert unseen(screen) == [], size
        await pilot.press("x")  # not an answer: the notice says which keys are
        assert screen.notice.text.startswith("not an answer")
        await pilot.press(keys[-1])
        await settle(pilot)
        assert screen.session.last.record.response == answers[-1]
        assert says(screen, "#last").startswith("last: practice 1")
