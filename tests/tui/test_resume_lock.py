"""The start screen's Resume offer honours the run's lock: one writer per run, in the UI too."""

import json
import socket

import pytest

from pinarray.journal.manifest import RunStatus, read_manifest
from pinarray.journal.timebase import Answers
from pinarray.tui import start_screen
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.run_screen import RunScreen
from tests.runs import open_elsewhere, unfinished_batch_run
from tests.tui.conftest import LOCALISATION, SIZE, fill_start, make_app, settle

HOST = socket.gethostname()


def read_lock_since(paths):
    return json.loads(paths.lock.read_text())["since"]


def text(app, selector):
    return str(app.screen.query_one(selector).render())


async def test_a_run_open_in_another_process_is_not_offered_until_it_ends_and_if_taken_after_the_offer_is_refused_in_words(
        results, monkeypatch):
    monkeypatch.setattr(start_screen, "HELD_RECHECK_S", 0.05)
    paths = unfinished_batch_run(results, LOCALISATION, seed=3)
    app = make_app(results)
    async with app.run_test(size=SIZE) as pilot:
        with open_elsewhere(paths) as other:
            await fill_start(pilot)
            assert app.screen.query_one("#resume").disabled
            assert text(app, "#resume-info") == (
                f"Run 1 is open in another process, pid {other.pid} on host {HOST} (this "
                f"computer), since {read_lock_since(paths)}; it can be resumed once that one ends.")
        await pilot.pause(0.5)  # the screen looks again on its own
        assert not app.screen.query_one("#resume").disabled, "not offered once the other ended"
        assert text(app, "#resume-info").startswith("Unfinished run 1: running, 0 of 24 trials (practice 0 of 2) done")
        await pilot.click("#resume")
        await settle(pilot)
        with open_elsewhere(paths) as other:  # ... taken again after the offer, before Begin
            await pilot.press("b")
            await settle(pilot)
            assert isinstance(app.screen, PreflightScreen)
            status = text(app, "#preflight-status")
            assert status.startswith(f"Cannot open the run: sub-01 ses-1 task-localisation run-1 "
                                     f"is open in another process, pid {other.pid} on host {HOST}")
        await pilot.press("b")  # that process has ended: now it resumes
        await settle(pilot)
        assert isinstance(app.screen, RunScreen) and app.screen.session.writer.resumed
        await pilot.press("ctrl+c")
        await settle(pilot)
    manifest = read_manifest(paths.manifest)
    # Started, the other process twice, the UI.
    assert len(manifest.sittings) == 4
    assert manifest.status is RunStatus.ABORTED and manifest.abort_reason == "interrupted (Ctrl-C)"


async def test_a_run_whose_lock_file_cannot_be_used_is_not_offered_and_the_screen_says_why(
        results):
    paths = unfinished_batch_run(results, LOCALISATION, seed=3)
    paths.lock.mkdir()  # what a hand or a sync tool may leave in its place
    app = make_app(results)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        assert app.screen.query_one("#resume").disabled
        assert text(app, "#resume-info") == (
            f"Cannot look for an unfinished run: {paths.lock}: cannot use the run's lock file: "
            "Is a directory")


async def test_a_protocol_file_edited_while_the_start_screen_is_open_is_read_again(
        results, tmp_path):
    # The form looks for an unfinished run at every key typed; it reads the protocol file
    # again only when the file changed, and then sees the task it names now.
    protocol = tmp_path / "localisation.yaml"
    protocol.write_text(LOCALISATION.read_text(encoding="utf-8"), encoding="utf-8")
    unfinished_batch_run(results, protocol, seed=3)
    app = make_app(results, protocol=protocol)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        assert not app.screen.query_one("#resume").disabled
        text_now = protocol.read_text(encoding="utf-8")
        protocol.write_text(text_now.replace("protocol: localisation\n",
                                             "protocol: localisation two\n"), encoding="utf-8")
        await fill_start(pilot, subject="1")  # subject 011: no run of either task
        await fill_start(pilot, subject=["backspace"])  # 01 again, of task localisationtwo
        await settle(pilot)
        assert app.screen.query_one("#resume").disabled
        assert text(app, "#resume-info") == ""
        protocol.write_text(text_now, encoding="utf-8")  # back as it was: offered again
        await fill_start(pilot, subject="1")
        await fill_start(pilot, subject=["backspace"])
        assert not app.screen.query_one("#resume").disabled


@pytest.mark.parametrize(("answers", "how"), [
    (Answers.OBSERVER, "a simulated observer's: resume it with pinarray batch --observer MODEL "
                       "--resume"),
    (Answers.SHEET, "a responses sheet's: resume it with pinarray batch --responses CSV "
                    "--resume")])
async def test_a_rehearsals_run_is_not_offered_and_the_start_screen_says_how_to_resume_it(
        results, answers, how):
    # Started by `pinarray batch`: a person's answers would follow a model's (or a sheet's).
    paths = unfinished_batch_run(results, LOCALISATION, seed=3, answers=answers)
    app = make_app(results)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        assert app.screen.query_one("#resume").disabled
        assert text(app, "#resume-info") == (
            "Unfinished run 1: aborted (stopped before trial 1), 0 of 24 trials (practice 0 of "
            f"2) done, seed 3. Its answers are {how}; Start begins a new run.")
    manifest = read_manifest(paths.manifest)
    assert len(manifest.sittings) == 1 and manifest.status is RunStatus.ABORTED


async def test_a_run_a_rehearsal_took_on_after_the_offer_is_refused_in_words(results):
    # Offered (an earlier pinarray's run: its answers not recorded), then resumed meanwhile by
    # `pinarray batch --observer` and stopped, before Begin: a person's answers would follow.
    paths = unfinished_batch_run(results, LOCALISATION, seed=3)
    app = make_app(results)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        assert not app.screen.query_one("#resume").disabled
        await pilot.click("#resume")
        await settle(pilot)
        manifest = json.loads(paths.manifest.read_text())
        manifest["sittings"].append({**manifest["sittings"][0], "number": 2,
                                     "answers": "observer"})
        paths.manifest.write_text(json.dumps(manifest))
        await pilot.press("b")
        await settle(pilot)
        assert isinstance(app.screen, PreflightScreen)
        assert text(app, "#preflight-status") == (
            f"Cannot open the run: {paths.label}: expected the answers its sittings had (a "
            "simulated observer's), found a subject's, in the UI; resume it with pinarray "
            "batch --observer MODEL --resume")
    manifest = read_manifest(paths.manifest)
    assert len(manifest.sittings) == 2 and manifest.status is RunStatus.ABORTED
