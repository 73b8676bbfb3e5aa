"""Results files as the lab relies on them: BIDS names, rows on disk at once, safe resume."""

import errno
import json
import multiprocessing
import os
import signal
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.errors import PinArrayError, ResultsError
from pinarray.journal.manifest import (
    RunStatus,
    find_unfinished,
    read_manifest,
    remaining_plan,
    set_status,
    write_manifest,
)
from pinarray.journal.paths import LabelError, RunPaths
from pinarray.journal.records import LEGACY_EVENT_LAYOUT, LEGACY_LAYOUT, AdaptiveCells
from pinarray.journal.rows import read_trials, split_torn_tail
from pinarray.journal.writer import RunWriter
from pinarray.paradigms.apparent_motion.rows import MotionRecord
from pinarray.paradigms.localisation.rows import LocalisationRecord
from tests.runs import VIRTUAL, localisation_plan, motion_entry, start_run

S = 1_000_000_000  # ns per s
PLAN = localisation_plan((4, 10), (7, 3), (10, 5), (1, 10), (16, 3))
MOTION_PLAN = (motion_entry(1, 2, "left"),)  # a run of apparent motion


def start(root, subject="S01", session=1, task="localisation", plan=PLAN):
    return start_run(root, subject, task, plan, session=session)


def localisation(trial, status="ok", response=None, **more):
    """Trial ``trial`` of `PLAN` (its pin and frequency), answered ``response`` (default: its
    pin, right)."""
    entry = PLAN[(trial - 1) % len(PLAN)]
    pin = entry["pin"]
    response = str(pin) if response is None else response
    return LocalisationRecord(trial=trial, block=1, task="localisation", onset_ns=12_500_000_000 * trial,
                              duration_ns=10 * S, status=status, response=response,
                              response_time_ns=1_500_000_000, pin=pin,
                              frequency_hz=float(entry["frequency_hz"]),
                              error_class="correct" if response == str(pin) else None, **more)


@pytest.mark.parametrize("label", ["../x", "a b", "a/b", "", "sub_1", "x-1", "é1", None])
def test_a_label_that_is_not_alphanumeric_is_refused_naming_the_label(tmp_path, label):
    with pytest.raises(LabelError) as refused:
        start(tmp_path, subject=label)
    assert isinstance(refused.value, PinArrayError)
    assert repr(label) in str(refused.value) and "letters and digits" in str(refused.value)
    assert not any(tmp_path.iterdir())


def test_a_run_is_laid_out_as_bids_and_the_next_run_gets_the_next_number(tmp_path):
    first = start(tmp_path)
    first.finish()
    beh = tmp_path / "sub-S01" / "ses-1" / "beh"
    assert first.paths.beh_tsv == beh / "sub-S01_ses-1_task-localisation_run-1_beh.tsv"
    assert first.paths.events_tsv.name == "sub-S01_ses-1_task-localisation_run-1_events.tsv"
    second = start(tmp_path)
    second.close()
    assert second.paths.run == 2
    assert RunPaths.from_file(second.paths.manifest) == second.paths
    assert second.paths.manifest == (tmp_path / "sourcedata" / "sub-S01" / "ses-1" / "beh"
                                      / "sub-S01_ses-1_task-localisation_run-2_manifest.json")


def test_the_sidecar_describes_every_column_with_units_or_levels(tmp_path):
    writer = start(tmp_path)
    writer.close()
    sidecar = json.loads(writer.paths.beh_json.read_text())
    columns = {k: v for k, v in sidecar.items() if k in LEGACY_LAYOUT}
    assert list(columns) == list(LEGACY_LAYOUT)
    assert all(entry["Description"] for entry in columns.values())
    assert sidecar["stimulus_onset"]["Units"] == "s" and sidecar["frequency_hz"]["Units"] == "Hz"
    assert set(sidecar["status"]["Levels"]) == {"ok", "redone", "aborted", "invalid"}
    events = json.loads(writer.paths.events_json.read_text())
    assert [k for k in events if k in (*LEGACY_EVENT_LAYOUT, "trial_type")] == list(LEGACY_EVENT_LAYOUT)


def test_the_manifest_holds_the_plan_and_the_provenance_before_trial_one(tmp_path):
    writer = start(tmp_path)
    manifest = read_manifest(writer.paths.manifest)
    writer.close()
    assert manifest.plan == PLAN
    assert manifest.status is RunStatus.RUNNING and manifest.seed == 42
    assert manifest.provenance.servo_models == ("STS3215",) and manifest.provenance.port == "sim://"
    assert manifest.machine["hostname"] and manifest.software_version
    assert manifest.started_at[-6] in "+-"  # an explicit UTC offset, e.g. +02:00


def test_each_row_is_fsynced_before_write_trial_returns(tmp_path, monkeypatch):
    writer = start(tmp_path)
    synced = []
    real_fsync = os.fsync

    def spy(fd):
        synced.append(os.readlink(f"/proc/self/fd/{fd}") if os.path.exists("/proc") else fd)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", spy)
    writer.write_trial(localisation(1))
    # A separate reader sees the row while the writer is still open.
    assert [r.trial for r in read_trials(writer.paths.beh_tsv)] == [1]
    writer.close()
    if os.path.exists("/proc"):
        assert synced == [str(writer.paths.beh_tsv), str(writer.paths.events_tsv)]
    else:
        assert len(synced) == 2


def test_a_torn_last_line_is_left_out_and_resume_drops_it_keeping_every_earlier_row(tmp_path):
    writer = start(tmp_path)
    for n in (1, 2, 3):
        writer.write_trial(localisation(n))
    writer.close()
    with open(writer.paths.beh_tsv, "a") as handle:
        handle.write("4\t1\tlocalisation\t4\tn/a\tn/a\t10\t")
    assert [r.trial for r in read_trials(writer.paths.beh_tsv)] == [1, 2, 3]
    resumed = RunWriter.resume(writer.paths)
    assert resumed.repaired.startswith("4\t1\tlocalisation")
    assert [e.trial for e in resumed.remaining()] == [4, 5]
    resumed.write_trial(localisation(4))
    resumed.close()
    text = writer.paths.beh_tsv.read_text()
    assert text.endswith("\n") and text.count("\n") == 5
    assert [r.trial for r in read_trials(writer.paths.beh_tsv)] == [1, 2, 3, 4]


def test_split_torn_tail_only_ever_cuts_the_last_row():
    header = "\t".join(LEGACY_LAYOUT).encode() + b"\n"
    row = b"\t".join([b"1"] * len(LEGACY_LAYOUT)) + b"\n"
    whole = header + row + row
    assert split_torn_tail(whole, len(LEGACY_LAYOUT)) == (len(whole), b"")
    assert split_torn_tail(whole + b"1\t2", len(LEGACY_LAYOUT)) == (len(whole), b"1\t2")
    assert split_torn_tail(whole + b"\0\0\0", len(LEGACY_LAYOUT))[0] == len(whole)
    short = b"1\t2\n"
    assert split_torn_tail(whole + short, len(LEGACY_LAYOUT)) == (len(whole), short)
    assert split_torn_tail(header[:5], len(LEGACY_LAYOUT)) == (0, header[:5])


def test_resume_rebuilds_the_events_row_a_crash_left_out(tmp_path):
    writer = start(tmp_path)
    for n in (1, 2):
        writer.write_trial(localisation(n))
    writer.close()
    lines = writer.paths.events_tsv.read_text().splitlines(keepends=True)
    writer.paths.events_tsv.write_text("".join(lines[:-1]) + lines[-1][:7])
    RunWriter.resume(writer.paths).close()
    rebuilt = writer.paths.events_tsv.read_text().splitlines()
    assert rebuilt == [line.rstrip("\n") for line in lines]


def test_resume_runs_exactly_the_unfinished_trials_in_plan_order_and_marks_them(tmp_path):
    writer = start(tmp_path)
    writer.write_trial(localisation(1))
    writer.write_trial(localisation(2, status="redone"))
    writer.write_trial(localisation(2))
    writer.write_trial(localisation(3, status="invalid"))
    writer.write_trial(localisation(4, status="aborted"))
    writer.close()
    resumed = RunWriter.resume(writer.paths)
    # trial 3's stimulus failed (invalid) and trial 4 was cut short: both are presented again
    assert [e.trial for e in resumed.remaining()] == [3, 4, 5]
    written = resumed.write_trial(localisation(4))
    resumed.finish()
    assert written.resumed
    rows = read_trials(writer.paths.beh_tsv)
    assert [r.resumed for r in rows] == [False] * 5 + [True]
    manifest = read_manifest(writer.paths.manifest)
    assert manifest.status is RunStatus.COMPLETED and len(manifest.sittings) == 2


def test_practice_trials_do_not_finish_main_trials_with_the_same_number():
    from dataclasses import replace

    plan = (replace(PLAN[0], practice=True, block=0), *PLAN[:2])
    left = remaining_plan(plan, [localisation(1, practice=True)])
    assert left == list(PLAN[:2])


def test_a_failed_manifest_update_leaves_the_old_one_whole(tmp_path, monkeypatch):
    writer = start(tmp_path)
    writer.close()
    before = writer.paths.manifest.read_bytes()

    def refuse(*args):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError):
        set_status(writer.paths.manifest, RunStatus.ABORTED, "fire alarm")
    assert writer.paths.manifest.read_bytes() == before
    assert [p.name for p in writer.paths.source_dir.iterdir() if p.name.startswith(".")] == []


def test_a_crash_inside_the_writer_marks_the_manifest_crashed_and_it_can_be_found(tmp_path):
    with pytest.raises(ConnectionError), start(tmp_path) as writer:
        writer.write_trial(localisation(1))
        raise ConnectionError("servo 7 stopped answering")
    finished = start(tmp_path, task="motion")
    finished.finish()
    found = find_unfinished(tmp_path, "S01")
    assert [(p.task, m.status) for p, m in found] == [("localisation", "crashed")]
    assert "servo 7" in found[0][1].abort_reason
    with pytest.raises(ResultsError, match="completed"):
        RunWriter.resume(finished.paths)


def test_a_hand_edited_manifest_with_a_repeated_trial_is_refused(tmp_path):
    writer = start(tmp_path)
    writer.close()
    manifest = read_manifest(writer.paths.manifest)
    data = manifest.to_json()
    data["plan"].append(data["plan"][0])
    writer.paths.manifest.write_text(json.dumps(data))
    with pytest.raises(ResultsError, match="twice"):
        read_manifest(writer.paths.manifest)
    write_manifest(writer.paths.manifest, manifest)
    assert read_manifest(writer.paths.manifest) == manifest


def test_a_protocol_named_in_bytes_the_locale_cannot_read_is_recorded_and_read_back(tmp_path):
    # A protocol in a folder named in Latin-1 on a UTF-8 system (an old share, a USB stick):
    # Python holds its name with a lone surrogate, which UTF-8 cannot encode. The run once
    # failed as it opened, with a traceback; the manifest is still UTF-8 JSON.
    writer = start(tmp_path)
    writer.close()
    manifest = read_manifest(writer.paths.manifest)
    named = replace(manifest, provenance=replace(
        manifest.provenance, protocol_file=os.fsdecode(b"/data/M\xfcller/localisation.yaml")))
    write_manifest(writer.paths.manifest, named)
    assert read_manifest(writer.paths.manifest) == named
    json.loads(writer.paths.manifest.read_bytes().decode("utf-8"))


@pytest.fixture(scope="module")
def runs_root(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("runs")


def fresh_folder(root: Path) -> Path:
    """A new empty folder in ``root`` for one example's run (pytest's numbered folders list
    the whole temporary folder at each one made)."""
    return Path(tempfile.mkdtemp(dir=root))


responses = st.one_of(st.none(), st.sampled_from(["none", "left", "right", "unsure"]))
nanoseconds = st.integers(0, 10**14)


@given(onset=nanoseconds, duration=nanoseconds, response_time=st.one_of(st.none(), nanoseconds),
       response=responses, direction=st.sampled_from(["left", "right", "none"]),
       row=st.integers(1, 4), reason=st.one_of(st.none(), st.text("ab \t,\"'", min_size=1)))
def test_any_motion_row_reads_back_exactly_as_written(
    runs_root, onset, duration, response_time, response, direction, row, reason
):
    record = MotionRecord(trial=3, block=2, task="motion", onset_ns=onset, duration_ns=duration,
                          response=response, response_time_ns=response_time, row=row,
                          direction=direction, status_reason=reason)
    writer = start(fresh_folder(runs_root), task="motion", plan=MOTION_PLAN)
    written = writer.write_trial(record)
    writer.close()
    assert written == replace(record, motion_samples=0)  # no samples: none claimed
    assert read_trials(writer.paths.beh_tsv) == [written]


numbers = st.one_of(st.none(), st.floats(-1e6, 1e6, allow_nan=False))
maybe = st.one_of(st.none(), st.booleans())


@given(procedure=st.sampled_from(["descending", "q1", "catch"]), intensity=numbers,
       guess=st.floats(0, 1), correct=maybe, reversal=maybe, estimate=numbers, low=numbers,
       high=numbers)
def test_any_adaptive_trial_reads_back_exactly_as_written(
    runs_root, procedure, intensity, guess, correct, reversal, estimate, low, high
):
    cells = AdaptiveCells(procedure, "soa_ms", intensity, guess, correct, reversal, estimate,
                          low, high)
    record = MotionRecord(trial=3, block=1, task="motion", onset_ns=0, duration_ns=S,
                          response="left", row=2, direction="left", adaptive=cells)
    writer = start(fresh_folder(runs_root), task="motion", plan=MOTION_PLAN)
    written = writer.write_trial(record)
    writer.close()
    assert written == replace(record, motion_samples=0)  # no samples: none claimed
    assert read_trials(writer.paths.beh_tsv) == [written]


def write_the_run(root: Path, mode: str) -> None:
    """What each writing process does: start the run of 1500 trials (or resume it) and write
    every trial that remains, then finish it."""
    if mode == "start":
        plan = localisation_plan(*((n % 16 + 1, 5) for n in range(1, 1501)))
        writer = start_run(root, "S01", "localisation", plan)
    else:
        writer = RunWriter.resume(RunPaths(root, "S01", "1", "localisation", 1), VIRTUAL)
    for entry in writer.remaining():
        n = entry.trial
        writer.write_trial(LocalisationRecord(
            trial=n, block=1, task="localisation", onset_ns=n * 10**9, duration_ns=10**10,
            response=str(entry["pin"]), pin=entry["pin"], frequency_hz=5.0,
            error_class="correct"))
    writer.finish()


def _run_and_kill(root, mode, rows_before_kill):
    """``write_the_run`` in a process forked from this one, SIGKILLed once its rows pass
    ``rows_before_kill`` (a fresh interpreter's start-up would add nothing but processor)."""
    child = multiprocessing.get_context("fork").Process(target=write_the_run, args=(root, mode))
    child.start()
    beh = RunPaths(root, "S01", "1", "localisation", 1).beh_tsv
    while child.is_alive():
        if beh.exists() and beh.stat().st_size > rows_before_kill * 60:
            os.kill(child.pid, signal.SIGKILL)
            break
        time.sleep(0.001)
    child.join(60)
    return child.exitcode


def test_a_run_sigkilled_while_writing_resumes_with_no_row_lost_or_repeated(tmp_path):
    kills = 0
    for mode, rows in (("start", 200), ("resume", 600), ("resume", 1100)):
        kills += _run_and_kill(tmp_path, mode, rows) == -signal.SIGKILL
    write_the_run(tmp_path, "resume")  # the last sitting, in this process, finishes it
    assert kills >= 1  # the test is only meaningful if a kill landed mid-run
    paths = RunPaths(tmp_path, "S01", "1", "localisation", 1)
    rows = read_trials(paths.beh_tsv)
    assert [r.trial for r in rows] == list(range(1, 1501))
    assert paths.events_tsv.read_text().count("\n") == 1501
    assert read_manifest(paths.manifest).status is RunStatus.COMPLETED
    assert any(r.resumed for r in rows)


def _disk_full(*args):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_disk_that_fills_mid_run_is_one_line_and_leaves_the_rows_before_and_the_lock_free(
        tmp_path, monkeypatch):
    writer = start(tmp_path)
    with pytest.raises(ResultsError) as refused, writer:
        writer.write_trial(localisation(1))
        monkeypatch.setattr(os, "fsync", _disk_full)
        writer.write_trial(localisation(2))
    monkeypatch.undo()
    message = str(refused.value)
    assert message.startswith(f"{writer.paths.beh_tsv}: cannot write results there: "
                              "No space left on device; every row written before is on disk")
    assert "\n" not in message
    # Trial 2's row reached the file but not the disk's guarantee; events.tsv never got it.
    assert [r.trial for r in read_trials(writer.paths.beh_tsv)] == [1, 2]
    assert writer.paths.events_tsv.read_text().count("\n") == 2
    assert not writer.paths.lock.exists()  # given back: the run can be resumed
    resumed = RunWriter.resume(writer.paths)
    resumed.close()
    assert [e.trial for e in resumed.remaining()] == [3, 4, 5]
    assert writer.paths.events_tsv.read_text().count("\n") == 3  # rebuilt from beh.tsv


def test_a_results_folder_that_cannot_be_written_on_resume_is_one_line(tmp_path, monkeypatch):
    writer = start(tmp_path)
    writer.close()
    monkeypatch.setattr(os, "replace", _disk_full)
    with pytest.raises(ResultsError, match="cannot write results there: No space left on device"):
        RunWriter.resume(writer.paths)
    monkeypatch.undo()
    assert not writer.paths.lock.exists()
    assert len(read_manifest(writer.paths.manifest).sittings) == 1  # no sitting was added
