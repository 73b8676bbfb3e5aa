"""A run resumes answered as it started: a subject's run (in the UI) is never finished by a
simulated observer or a sheet, nor a rehearsal's by a person, so a run's answers are all one
kind's. The manifest names each sitting's answers; a resume answered otherwise is refused in one
line that says how to resume it, every file of the run left as it was."""

import json
from dataclasses import replace

import pytest

from pinarray.cli import main
from pinarray.clock import VirtualClock
from pinarray.errors import ResultsError
from pinarray.journal.manifest import read_manifest
from pinarray.journal.timebase import Answers
from pinarray.session.sitting import SessionRequest
from pinarray.stop import Stopped
from tests.lab_protocols import PROTOCOLS
from tests.test_resume_files import snapshot
from tests.test_sitting import RigStoppedMidStimulus, sitting_on


def a_subjects_run_stopped_mid_stimulus(results, answers=Answers.SUBJECT):
    """As the UI leaves it (``answers``: as batch with them does): a subject answering, the
    run stopped (a signal) at its first stimulus; its protocol file."""
    sitting, request = sitting_on(results, rig_factory=RigStoppedMidStimulus)
    with pytest.raises(Stopped), sitting:
        sitting.connect(replace(request, answers=answers), VirtualClock())
        session = sitting.open_session()
        sitting.run_scripted(lambda question: 1)
    return session.writer.paths, request.protocol.source


def run(capsys, *argv) -> tuple[int, str]:
    try:
        status = main([str(a) for a in argv])
    except SystemExit as stop:
        status = stop.code
    return status, capsys.readouterr().err


def a_sheet_answering_every_trial(paths, sheet):
    trials = [entry.trial for entry in read_manifest(paths.manifest).plan]
    sheet.write_text("trial,response\n" + "".join(f"{trial},1\n" for trial in trials))
    return sheet


@pytest.mark.parametrize("kind", ["observer", "responses"])
def test_a_subjects_run_is_not_resumed_by_a_model_or_a_sheet(tmp_path, capsys, kind):
    paths, protocol = a_subjects_run_stopped_mid_stimulus(tmp_path)
    assert [s.answers for s in read_manifest(paths.manifest).sittings] == ["subject"]
    answers, found = {
        "observer": (["--observer", "default"], "a simulated observer's"),
        "responses": (["--responses", a_sheet_answering_every_trial(paths, tmp_path / "a.csv")],
                      "a responses sheet's"),
    }[kind]
    before = snapshot(tmp_path)
    status, err = run(capsys, "batch", protocol, "--subject", "01", "--session", "1",
                      "--results", tmp_path, *answers, "--resume")
    assert status == 2
    assert err.splitlines() == [
        f"pinarray: {paths.label}: expected the answers its sittings had (a subject's, in the "
        f"UI), found {found}; resume it in the UI (Resume on the start screen of pinarray tui)"]
    assert snapshot(tmp_path) == before



def test_a_batch_refused_one_resume_runs_none_of_its_protocols(tmp_path, capsys):
    # The subject's run comes second: the model's run of the first would be written, whole,
    # before the refusal, were the answers not checked with the seeds and locks, up front.
    paths, protocol = a_subjects_run_stopped_mid_stimulus(tmp_path)
    before = snapshot(tmp_path)
    status, err = run(capsys, "batch", PROTOCOLS / "apparent_motion.yaml", protocol,
                      "--subject", "01", "--session", "1", "--results", tmp_path,
                      "--observer", "default", "--resume")
    assert status == 2
    assert err.splitlines() == [
        f"pinarray: {paths.label}: expected the answers its sittings had (a subject's, in the "
        "UI), found a simulated observer's; resume it in the UI (Resume on the start screen "
        "of pinarray tui)"]
    assert snapshot(tmp_path) == before

def test_a_subjects_run_resumes_as_a_subjects(tmp_path):
    paths, protocol = a_subjects_run_stopped_mid_stimulus(tmp_path)
    sitting, request = sitting_on(tmp_path)
    with sitting:
        sitting.connect(SessionRequest(request.protocol, "01", "1", "", None, None, None, True),
                        VirtualClock())
        session = sitting.open_session()
        sitting.run_scripted(lambda question: 1)
    manifest = json.loads(paths.manifest.read_text())
    assert manifest["status"] == "completed"
    assert [s["answers"] for s in manifest["sittings"]] == ["subject", "subject"]
    assert session.writer.paths == paths


def test_a_rehearsals_run_is_not_resumed_by_a_subject(tmp_path):
    # Started by `batch --observer`, then Resume on the UI's start screen.
    paths, _ = a_subjects_run_stopped_mid_stimulus(tmp_path, Answers.OBSERVER)
    before = snapshot(tmp_path)
    sitting, request = sitting_on(tmp_path)
    with sitting, pytest.raises(ResultsError) as refused:
        sitting.connect(replace(request, resume=True), VirtualClock())
        sitting.open_session()
    assert str(refused.value) == (
        f"{paths.label}: expected the answers its sittings had (a simulated observer's), found "
        "a subject's, in the UI; resume it with pinarray batch --observer MODEL --resume")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(("typed", "found"), [("Subject", "'Subject'"), (3, "a number"),
                                              (None, "null"), (["subject"], "a list")])
def test_a_sittings_answers_typed_by_hand_as_no_kind_are_refused_in_words(tmp_path, capsys,
                                                                           typed, found):
    paths, protocol = a_subjects_run_stopped_mid_stimulus(tmp_path)
    manifest = json.loads(paths.manifest.read_text())
    manifest["sittings"][0]["answers"] = typed
    paths.manifest.write_text(json.dumps(manifest))
    before = snapshot(tmp_path)
    status, err = run(capsys, "batch", protocol, "--subject", "01", "--session", "1",
                      "--results", tmp_path, "--observer", "default", "--resume")
    assert status == 2
    assert err.splitlines() == [
        f"pinarray: {paths.manifest}: expected a pinarray run manifest, found a damaged one "
        "(sitting 1's answers: expected one of subject, responses, observer, script, unknown, "
        f"found {found})"]
    assert snapshot(tmp_path) == before


def test_a_sitting_whose_answers_a_hand_removed_goes_with_any(tmp_path, capsys):
    # As an earlier pinarray wrote it: who answered is not known, so any resume may take it on.
    paths, protocol = a_subjects_run_stopped_mid_stimulus(tmp_path)
    manifest = json.loads(paths.manifest.read_text())
    del manifest["sittings"][0]["answers"]
    paths.manifest.write_text(json.dumps(manifest))
    status, err = run(capsys, "batch", protocol, "--subject", "01", "--session", "1",
                      "--results", tmp_path, "--observer", "default", "--resume")
    assert (status, err) == (0, "")
    manifest = json.loads(paths.manifest.read_text())
    assert manifest["status"] == "completed"
    assert [s.get("answers") for s in manifest["sittings"]] == [None, "observer"]
    sidecar = json.loads(paths.beh_tsv.with_suffix(".json").read_text())
    assert [s["AnsweredBy"] for s in sidecar["TimeBase"]["Sittings"]] == ["unknown", "observer"]
