"""One writer per run: a second process is refused by name, a dead one's lock is taken over."""

import errno
import json
import os
import signal
import socket
from pathlib import Path

import pytest

from pinarray.cli import main
from pinarray.errors import ResultsError
from pinarray.journal.lock import RunLocked, lock_holder
from pinarray.journal.manifest import RunStatus, read_manifest
from pinarray.journal.paths import RunPaths
from pinarray.journal.rows import read_trials
from pinarray.journal.writer import RunWriter
from pinarray.paradigms.localisation.rows import LocalisationRecord
from tests.commands import pinarray_here
from tests.runs import (
    REPO,
    VIRTUAL,
    localisation_plan,
    open_elsewhere,
    start_run,
    unfinished_batch_run,
)

MOTION = REPO / "protocols" / "apparent_motion.yaml"
HOST = socket.gethostname()


def ok_row(trial):
    """Trial ``trial`` answered right: pin 4 at 10 Hz."""
    return LocalisationRecord(trial=trial, block=1, task="localisation", onset_ns=trial * 10**10,
                              duration_ns=10**10, response="4", pin=4, frequency_hz=10.0,
                              error_class="correct")


def batch(root, *more, protocol=MOTION):
    """`pinarray batch` in this process: the other process, where there is one, holds the run."""
    return pinarray_here("batch", protocol, "--subject", "01", "--observer", "default",
                         "--seed", "7", "--results", root, *more)


def test_a_second_process_resuming_a_run_in_use_is_refused_in_one_line_naming_the_first(tmp_path):
    paths = unfinished_batch_run(tmp_path, MOTION)
    with open_elsewhere(paths) as first:
        manifest_before = paths.manifest.read_bytes()
        second = batch(tmp_path, "--resume")
        assert second.returncode == 2
        (line,) = second.stderr.splitlines()
        assert f"pid {first.pid} on host {HOST} (this computer)" in line
        assert "is open in another process" in line and "one writer at a time" in line
        assert "Traceback" not in second.stderr
        # The refused process wrote nothing: no row, no sitting, the first one's manifest as it was.
        assert not paths.beh_tsv.exists() or read_trials(paths.beh_tsv) == []
        assert paths.manifest.read_bytes() == manifest_before
    # Once the first process has ended the run resumes.
    done = batch(tmp_path, "--resume")
    assert done.returncode == 0, done.stderr
    assert read_manifest(paths.manifest).status is RunStatus.COMPLETED
    assert not paths.lock.exists()  # given back, not left behind


def test_the_writer_refuses_a_second_writer_in_the_same_process_too(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    writer.close()
    first = RunWriter.resume(writer.paths, VIRTUAL)
    try:
        with pytest.raises(RunLocked, match=f"pid {os.getpid()} on host {HOST}"):
            RunWriter.resume(writer.paths, VIRTUAL)
    finally:
        first.close()
    RunWriter.resume(writer.paths, VIRTUAL).close()  # free again


def test_a_stale_lock_left_by_a_killed_process_is_explained_and_taken_over(tmp_path):
    paths = unfinished_batch_run(tmp_path, MOTION)
    with open_elsewhere(paths) as killed:
        killed.send_signal(signal.SIGKILL)
        killed.wait(timeout=30)
    # The file still names the dead process, but nobody holds the lock.
    assert json.loads(paths.lock.read_text())["pid"] == killed.pid
    assert lock_holder(paths.lock) is None
    resumed = batch(tmp_path, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    warning = next(line for line in resumed.stderr.splitlines() if "took over the lock" in line)
    assert f"left by pid {killed.pid} on host {HOST} (this computer)" in warning
    assert "no longer running (killed or crashed)" in warning
    manifest = read_manifest(paths.manifest)
    assert manifest.status is RunStatus.COMPLETED
    assert [s.pid for s in manifest.sittings][-1] != killed.pid


def test_a_lock_left_on_another_computer_is_refused_naming_the_file_to_delete(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    writer.close()
    lock = writer.paths.lock
    lock.write_text(json.dumps({"pid": 4242, "host": "other-pc", "since": "2024-05-01T14:03:07+02:00",
                                "command": "pinarray batch ..."}))
    with pytest.raises(RunLocked) as refused:
        RunWriter.resume(writer.paths, VIRTUAL)
    message = str(refused.value)
    assert "pid 4242 on host other-pc" in message and "this computer cannot see" in message
    assert f"delete {lock}" in message and "\n" not in message
    lock.unlink()
    RunWriter.resume(writer.paths, VIRTUAL).close()


def make_unusable(lock: Path, kind: str) -> None:
    """Put something that cannot serve as a lock file at ``lock``."""
    lock.parent.mkdir(parents=True, exist_ok=True)
    lock.unlink(missing_ok=True)
    match kind:
        case "folder":
            lock.mkdir()
        case "symlink loop":
            other = lock.with_name("other.lock")
            os.symlink(other, lock)
            os.symlink(lock, other)
        case "dangling link":  # followed, the lock would be created where it points
            os.symlink(lock.with_name("nowhere.lock"), lock)
        case "FIFO":
            os.mkfifo(lock)


def results_files(root: Path) -> dict[str, bytes]:
    """Every regular file under ``root`` with its bytes."""
    return {str(f): f.read_bytes() for f in root.rglob("*") if f.is_file() and not f.is_symlink()}


UNUSABLE = {"folder": "Is a directory",
            "symlink loop": "expected a regular file, found a symbolic link to {folder}/other.lock",
            "dangling link": "expected a regular file, found a symbolic link to {folder}/nowhere.lock",
            "FIFO": "expected a regular file, found a FIFO (named pipe)"}


@pytest.mark.parametrize("kind", UNUSABLE)
def test_resuming_a_run_whose_lock_file_cannot_be_used_is_refused_in_one_line(tmp_path, kind):
    paths = unfinished_batch_run(tmp_path, MOTION)
    make_unusable(paths.lock, kind)
    before = results_files(tmp_path)
    refused = batch(tmp_path, "--resume")
    assert refused.returncode == 2
    assert refused.stderr == (f"pinarray: {paths.lock}: cannot use the run's lock file: "
                              f"{UNUSABLE[kind].format(folder=paths.lock.parent)}\n")
    assert results_files(tmp_path) == before  # nothing written, nothing touched


@pytest.mark.parametrize("kind", ["folder", "dangling link", "FIFO"])
def test_a_new_run_whose_lock_file_cannot_be_used_is_refused_in_one_line(tmp_path, kind):
    paths = RunPaths(tmp_path, "01", "1", "apparentmotion", 1)
    make_unusable(paths.lock, kind)
    refused = batch(tmp_path)
    assert refused.returncode == 2
    assert refused.stderr == (f"pinarray: {paths.lock}: cannot use the run's lock file: "
                              f"{UNUSABLE[kind].format(folder=paths.lock.parent)}\n")
    assert not paths.manifest.exists() and not paths.beh_tsv.exists()
    assert not paths.lock.with_name("nowhere.lock").exists()  # no link was followed


@pytest.mark.parametrize("kind", ["folder", "dangling link", "FIFO"])
def test_a_dataset_lock_file_that_is_no_regular_file_is_refused_in_one_line(tmp_path, kind):
    # Issue 46's re-run: a dangling link there had batch create a file at its target, outside
    # the results folder; a FIFO there was taken as the lock.
    lock = tmp_path / "sourcedata" / "dataset.lock"
    make_unusable(lock, kind)
    refused = batch(tmp_path)
    assert (refused.returncode, refused.stdout) == (2, "")
    assert refused.stderr == (f"pinarray: {lock}: cannot use the dataset's lock file: "
                              f"{UNUSABLE[kind].format(folder=lock.parent)}\n")
    assert not lock.with_name("nowhere.lock").exists()  # no link was followed
    assert results_files(tmp_path) == {}  # nor any of the dataset's files written


@pytest.mark.parametrize("error", [errno.EROFS, errno.EACCES])
def test_resuming_where_the_lock_file_cannot_be_opened_for_writing_is_refused_in_one_line(
        tmp_path, monkeypatch, capsys, error):
    # A read-only file system, or a file even root may not write (immutable): as root, chmod
    # stops nothing, so the system's answer is played by os.open.
    paths = unfinished_batch_run(tmp_path, MOTION)
    before = results_files(tmp_path)
    system_open = os.open

    def refusing_open(path, flags, *args, **kwargs):
        if Path(path) == paths.lock and flags & (os.O_RDWR | os.O_WRONLY | os.O_CREAT):
            raise OSError(error, os.strerror(error), str(path))
        return system_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", refusing_open)
    status = main(["batch", str(MOTION), "--subject", "01", "--observer", "default",
                   "--results", str(tmp_path), "--resume"])
    assert status == 2
    assert capsys.readouterr().err == (f"pinarray: {paths.lock}: cannot use the run's lock "
                                       f"file: {os.strerror(error)}\n")
    assert results_files(tmp_path) == before


def _duplicate_the_first_row(beh: Path) -> None:
    lines = beh.read_text().splitlines(keepends=True)
    beh.write_text("".join([*lines, lines[1]]))


def test_a_trial_logged_ok_twice_is_refused_on_resume_with_its_lines(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10), (7, 3)))
    writer.write_trial(ok_row(1))
    writer.close()
    _duplicate_the_first_row(writer.paths.beh_tsv)
    with pytest.raises(ResultsError) as refused:
        RunWriter.resume(writer.paths, VIRTUAL)
    assert str(refused.value) == (
        f"{writer.paths.beh_tsv}:3: trial 1 is logged ok twice (lines 2, 3); a trial counts "
        "once: delete the row that should not count, then resume")
    assert not writer.paths.lock.exists()  # the refusal gave the lock back
    # With the extra row deleted the run resumes; events.tsv again has one row per trial row.
    lines = writer.paths.beh_tsv.read_text().splitlines(keepends=True)
    writer.paths.beh_tsv.write_text("".join(lines[:2]))
    resumed = RunWriter.resume(writer.paths, VIRTUAL)
    assert [e.trial for e in resumed.remaining()] == [2]
    resumed.close()
    assert len(writer.paths.events_tsv.read_text().splitlines()) == 2


def test_batch_refuses_to_resume_a_run_with_a_trial_logged_ok_twice_in_one_line(tmp_path):
    whole = batch(tmp_path)  # a whole run, then marked unfinished as a crash would leave it
    assert whole.returncode == 0, whole.stderr
    (manifest,) = tmp_path.rglob("*_manifest.json")
    data = json.loads(manifest.read_text())
    data["status"] = "crashed"
    manifest.write_text(json.dumps(data))
    (beh,) = tmp_path.rglob("*_beh.tsv")
    _duplicate_the_first_row(beh)
    refused = batch(tmp_path, "--resume")
    assert refused.returncode == 2
    (line,) = refused.stderr.splitlines()
    assert line.startswith(f"pinarray: {beh}:15: practice trial 1 is logged ok twice (lines 2, 15)")
    assert "Traceback" not in refused.stderr


def test_a_second_ok_row_for_a_trial_is_refused_by_the_writer(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    writer.write_trial(ok_row(1))
    with pytest.raises(ResultsError, match="trial 1 is already logged ok; a trial counts once"):
        writer.write_trial(ok_row(1))
    writer.close()
    with pytest.raises(ResultsError, match="the run is closed"):
        writer.write_trial(ok_row(1))
    assert len(read_trials(writer.paths.beh_tsv)) == 1


def test_batch_resume_with_nothing_to_resume_is_exit_2_in_one_line_and_starts_nothing(tmp_path):
    nothing = batch(tmp_path, "--resume")
    assert nothing.returncode == 2
    assert nothing.stderr.splitlines() == [
        f"pinarray: --resume: no unfinished run of apparentmotion for subject 01, session 1 in "
        f"{tmp_path}; run without --resume to start a new one"]
    assert not list(tmp_path.rglob("sub-*"))
    finished = batch(tmp_path)
    assert finished.returncode == 0, finished.stderr
    again = batch(tmp_path, "--resume")  # the only run is completed: still nothing to resume
    assert again.returncode == 2 and len(again.stderr.splitlines()) == 1
    assert [p.name for p in tmp_path.rglob("*_beh.tsv")] == [
        "sub-01_ses-1_task-apparentmotion_run-1_beh.tsv"]


def test_a_seed_other_than_the_runs_own_is_refused_on_resume_and_its_own_is_taken(tmp_path):
    # Issue 46's re-run: --seed 99 --resume resumed the run at its own seed without a word.
    paths = unfinished_batch_run(tmp_path, MOTION, seed=5)
    before = results_files(tmp_path)
    refused = batch(tmp_path, "--resume")  # `batch` asks for --seed 7
    assert (refused.returncode, refused.stdout) == (2, "")
    assert refused.stderr == (f"pinarray: --seed 7 --resume: {paths.label} was planned with seed "
                              "5, which it keeps when resumed; leave --seed out (or start a new "
                              "run without --resume)\n")
    assert results_files(tmp_path) == before
    resumed = pinarray_here("batch", MOTION, "--subject", "01", "--observer", "default",
                            "--seed", "5", "--results", tmp_path, "--resume")
    assert resumed.returncode == 0 and "(seed 5, run 1;" in resumed.stdout
    assert read_manifest(paths.manifest).status == RunStatus.COMPLETED


def hard_link_targets(root: Path, paths: RunPaths) -> dict[str, Path]:
    """Files a lock file could be a second name of: the run's rows, the dataset's participants,
    a file outside the results folder."""
    outside = root.parent / f"{root.name}-outside.txt"
    outside.write_text("precious\n")
    return {"beh.tsv": paths.beh_tsv, "participants.tsv": root / "participants.tsv",
            "outside": outside}


@pytest.mark.parametrize("lock_of", ["run", "dataset"])
@pytest.mark.parametrize("target", ["beh.tsv", "participants.tsv", "outside"])
def test_a_lock_file_that_is_a_hard_link_is_refused_and_nothing_is_written_through_it(
        tmp_path, lock_of, target):
    # Issue 46's fourth pass: a run's lock hard-linked to its beh.tsv, to participants.tsv or
    # to a file outside the results had batch write its lock record into that file.
    root = tmp_path / "results"
    paths = unfinished_batch_run(root, MOTION)
    linked = hard_link_targets(root, paths)[target]
    if not linked.exists():
        linked.write_text("onset\tduration\n")  # a run aborted before trial 1 may have none yet
    lock = paths.lock if lock_of == "run" else root / "sourcedata" / "dataset.lock"
    lock.unlink(missing_ok=True)
    os.link(linked, lock)
    before, linked_before = results_files(root), linked.read_bytes()
    refused = batch(root, "--resume")
    what = "the run's" if lock_of == "run" else "the dataset's"
    assert (refused.returncode, refused.stdout) == (2, "")
    assert refused.stderr == (f"pinarray: {lock}: cannot use {what} lock file: expected a file "
                              "of its own, found a hard link (one file with 2 names: writing "
                              "it would change the others)\n")
    assert linked.read_bytes() == linked_before
    assert results_files(root) == before  # nothing written, nothing touched


def test_a_results_file_hard_linked_to_a_backup_is_written_without_changing_the_backup(
        tmp_path):
    # A backup made with `cp -al` shares its files with the run: rows appended in place (and a
    # torn row cut off in place) would change the backup too. The run's file gets a copy of
    # its own first.
    paths = unfinished_batch_run(tmp_path, MOTION)
    backup = tmp_path / "backup"
    backup.mkdir()
    saved = {}
    for name, path in {"beh": paths.beh_tsv, "events": paths.events_tsv}.items():
        if not path.exists():
            path.write_text("")
        path.write_bytes(path.read_bytes() + b"torn")  # a torn last row, cut on resume
        os.link(path, backup / name)
        saved[name] = path.read_bytes()
    resumed = batch(tmp_path, "--resume", "--speed", "0")
    assert resumed.returncode == 0, resumed.stderr
    assert len(read_trials(paths.beh_tsv)) > 0
    for name, data in saved.items():
        assert (backup / name).read_bytes() == data  # the backup as it was
    assert os.stat(paths.beh_tsv).st_nlink == 1


@pytest.mark.parametrize("link", ["symbolic", "hard"])
def test_the_motion_recordings_temporary_name_is_never_written_through(tmp_path, link):
    # The recording is rewritten under a fixed temporary name, then renamed: a link put at that
    # name had the rewrite go into the file it leads to.
    from pinarray.journal.physio import motion_recording_path

    paths = unfinished_batch_run(tmp_path / "results", MOTION)
    outside = tmp_path / "outside.txt"
    outside.write_text("precious\n")
    temporary = motion_recording_path(paths)
    temporary = temporary.with_name(temporary.name + ".tmp")
    temporary.parent.mkdir(parents=True, exist_ok=True)
    (os.symlink if link == "symbolic" else os.link)(outside, temporary)
    resumed = batch(tmp_path / "results", "--resume", "--speed", "0")
    assert resumed.returncode == 0, resumed.stderr
    assert outside.read_text() == "precious\n"
