"""A study's dataset as a lab hands it to a journal: the official validator, time, every trial once.

Four subjects do both tasks with `pinarray batch` (simulated array, simulated observer):
sub-01 and sub-04 in one go; sub-02's localisation run is killed with SIGKILL mid-run and
resumed; sub-03's is killed, then resumed by two processes at once (the second is refused,
the first is stopped with SIGTERM) and finished by a third. The runs killed or stopped are
processes of their own, forked from the test's; the others run in the test's process
(tests/commands.py), the other subjects' beside sub-03's first resumer. The dataset is built once for the module; the
official BIDS validator runs once on it.
"""

import csv
import itertools
import signal
import socket
import sys
import time
import warnings
from collections import Counter
from types import SimpleNamespace

import pytest

from pinarray.journal.lock import lock_holder
from pinarray.journal.manifest import RunStatus, entry_key, read_manifest
from pinarray.journal.paths import RunPaths
from pinarray.journal.records import TrialStatus
from pinarray.journal.rows import read_trials
from pinarray.journal.timebase import ClockKind, seconds_text
from pinarray.paradigms.localisation.rows import LocalisationRecord
from tests.bids_validator import VALIDATOR, validate
from tests.commands import Forked, pinarray_here
from tests.runs import REPO, write_short_localisation

# One worker builds the module's fixture once (make test runs --dist loadgroup).
pytestmark = pytest.mark.xdist_group("study")

MOTION = REPO / "protocols" / "apparent_motion.yaml"
SUBJECTS = ("01", "02", "03", "04")


def batch_command(root, subject, *files, more=()):
    return [sys.executable, "-m", "pinarray", "batch", *map(str, files), "--subject", subject,
            "--observer", "default", "--seed", str(100 + int(subject)), "--results", str(root),
            *more]


def batch(root, subject, *files, more=()):
    """`pinarray batch` in this process (``batch_command``'s arguments)."""
    return pinarray_here(*batch_command(root, subject, *files, more=more)[3:])


def localisation_run(root, subject):
    return RunPaths(root, subject, "1", "localisation", 1)


def wait_for(condition, process, what, timeout_s=90.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert process.poll() is None, f"the batch ended before {what}"
        assert time.monotonic() < deadline, f"no {what} after {timeout_s} s"
        time.sleep(0.01)


def rows_on_disk(paths):
    return read_trials(paths.beh_tsv) if paths.beh_tsv.exists() else []


def kill_when(process, paths, rows):
    """SIGKILL ``process`` once ``rows`` of its run are on disk; the rows it left."""
    wait_for(lambda: len(rows_on_disk(paths)) >= rows, process, f"{rows} rows")
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=30)
    return rows_on_disk(paths)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    root = tmp_path_factory.mktemp("study") / "results"
    # The seed's localisation with 1 s stimuli: what the files hold is the point, not ten
    # seconds of simulated servos per trial.
    localisation = write_short_localisation(root.parent)

    def background(subject, *files, more=()):
        """`pinarray batch` in a process forked from this one (tests/commands.py)."""
        folder = root.parent / f"sub-{subject}-{len(list(root.parent.glob('sub-*')))}"
        return Forked(folder, *batch_command(root, subject, *files, more=more)[3:], cwd=REPO)

    # sub-02 and sub-03 begin their localisation, paced at 50x real time, and are killed.
    killed = background("02", localisation, more=["--time-scale", "50"])
    killed3 = background("03", localisation, more=["--time-scale", "50"])
    paths3 = localisation_run(root, "03")
    before_kill = kill_when(killed, localisation_run(root, "02"), rows=6)
    kill_when(killed3, paths3, rows=3)

    # sub-02 resumes; then two processes resume sub-03 at once.
    resumed = batch(root, "02", localisation, more=["--resume"])
    first = background("03", localisation, more=["--resume", "--time-scale", "1"])
    wait_for(lambda: getattr(lock_holder(paths3.lock), "pid", None) == first.pid, first,
             "the first resumer holding the run")
    second = batch(root, "03", localisation, more=["--resume"])
    # Beside the first resumer, on the same results folder as in a lab: sub-01 and sub-04 do
    # both tasks, sub-02 and sub-03 their motion task.
    others = [resumed, batch(root, "01", localisation, MOTION), batch(root, "04", localisation, MOTION),
              batch(root, "02", MOTION), batch(root, "03", MOTION)]
    assert first.poll() is None, "the first resumer ended before it was stopped"
    first.send_signal(signal.SIGTERM)  # the experimenter stops the first one ...
    _, first_stderr = first.communicate(timeout=60)
    last = batch(root, "03", localisation, more=["--resume"])  # ... and finishes the run later
    assert last.returncode == 0, last.stderr
    assert [done.returncode for done in others] == [0] * len(others), [
        done.stderr for done in others]
    return SimpleNamespace(root=root, killed=killed, before_kill=before_kill,
                           resumed_stderr=resumed.stderr, killed3=killed3, first=first,
                           first_stderr=first_stderr, second=second)


@pytest.fixture(scope="module")
def validation(study):
    if not VALIDATOR.exists():
        pytest.skip(f"the official BIDS validator is not installed ({VALIDATOR} missing): it "
                    "comes with the dev extra, pip install -e '.[dev]'")
    report, result = validate(study.root, "--max-rows", "-1")
    if report is None:
        pytest.fail(f"bids-validator-deno gave no JSON report (exit {result.returncode}): "
                    f"{result.stderr.strip() or result.stdout.strip()}")
    return report


@pytest.mark.long
def test_the_dataset_passes_the_official_bids_validator_with_no_errors(validation):
    issues = validation["issues"]["issues"]
    errors = [i for i in issues if i["severity"] == "error"]
    assert errors == []
    summary = validation["summary"]
    assert sorted(summary["subjects"]) == list(SUBJECTS)
    assert sorted(summary["tasks"]) == ["apparent_motion", "localisation"]
    assert summary["dataTypes"] == ["beh"]
    # What the validator recommends and only the lab can give (authors, licence, institution,
    # Cognitive Atlas terms): warnings, listed in the test output.
    found = Counter(f"{i['code']}" + (f" ({i['subCode']})" if i.get("subCode") else "")
                    for i in issues if i["severity"] == "warning")
    assert "BEH_ONSET_DURATION" not in found  # onset and duration are the events files'
    if found:
        warnings.warn("BIDS validator warnings (not errors), schema "
                      f"{summary['schemaVersion']}: "
                      + "; ".join(f"{code} x{n}" for code, n in sorted(found.items())),
                      stacklevel=1)


def _runs(root):
    return sorted((RunPaths.from_file(p) for p in root.rglob("sub-*_beh.tsv")),
                  key=lambda p: (p.subject, p.task, p.run))


def test_every_run_is_complete_with_every_trial_once_and_onsets_that_only_grow(study):
    runs = _runs(study.root)
    assert [(p.subject, p.task, p.run) for p in runs] == [
        (s, t, 1) for s in SUBJECTS for t in ("apparentmotion", "localisation")]
    for paths in runs:
        manifest = read_manifest(paths.manifest)
        rows = read_trials(paths.beh_tsv)
        assert manifest.status is RunStatus.COMPLETED, paths.label
        ok = [r.key for r in rows if r.status is TrialStatus.OK]
        assert sorted(ok) == sorted(entry_key(e) for e in manifest.plan), paths.label
        assert any(practice for _, practice in ok)  # both protocols begin with practice
        onsets = [r.onset_ns for r in rows]
        assert onsets[0] == 0 and all(b > a for a, b in itertools.pairwise(onsets)), paths.label
        with open(paths.events_tsv, newline="") as handle:
            events = list(csv.DictReader(handle, delimiter="\t"))
        assert [e["onset"] for e in events] == [seconds_text(r.onset_ns) for r in rows]


def test_the_run_killed_outright_continues_its_time_base_when_resumed(study):
    paths = localisation_run(study.root, "02")
    rows = read_trials(paths.beh_tsv)
    before = study.before_kill
    assert study.killed.returncode == -signal.SIGKILL and len(before) >= 6
    assert rows[: len(before)] == before  # nothing on disk was lost or changed
    after = rows[len(before):]
    assert after and all(r.resumed for r in after) and not any(r.resumed for r in before)
    assert min(r.onset_ns for r in after) > max(r.end_ns for r in before)
    stale = next(line for line in study.resumed_stderr.splitlines() if "took over the lock" in line)
    assert f"left by pid {study.killed.pid} on host {socket.gethostname()}" in stale
    sittings = read_manifest(paths.manifest).sittings
    assert [(s.clock.kind, s.clock.factor) for s in sittings] == [
        (ClockKind.PACED, 50.0), (ClockKind.VIRTUAL, None)]
    assert sittings[0].pid == study.killed.pid


def test_a_second_process_resuming_the_same_run_at_once_was_refused_naming_the_first(study):
    assert study.second.returncode == 2
    (line,) = study.second.stderr.splitlines()
    assert line == (f"pinarray: sub-03 ses-1 task-localisation run-1 is open in another "
                    f"process, pid {study.first.pid} on host {socket.gethostname()} (this "
                    f"computer), since {line.split(', since ')[1].split(';')[0]}; a run has one "
                    "writer at a time: wait for that one to end, or end it, then try again")
    assert study.first.returncode == 128 + signal.SIGTERM, study.first_stderr
    manifest = read_manifest(localisation_run(study.root, "03").manifest)
    # started (killed), the first resumer (stopped), the last: the refused one left no sitting
    assert [s.pid for s in manifest.sittings][:2] == [study.killed3.pid, study.first.pid]
    assert len(manifest.sittings) == 3


def test_participants_lists_every_subject_once(study):
    with open(study.root / "participants.tsv", newline="") as handle:
        rows = list(csv.reader(handle, delimiter="\t"))
    assert rows[0] == ["participant_id"]
    assert sorted(rows[1:]) == [[f"sub-{s}"] for s in SUBJECTS]  # in the order they started


def test_analyse_gives_subject_level_numbers_counting_every_trial_once(study, tmp_path):
    result = pinarray_here("analyse", study.root, "--out", tmp_path,
                           "--bootstrap-resamples", "1000", "--no-figures")
    assert result.returncode == 0, result.stderr

    def table(name):
        with open(tmp_path / name, newline="") as handle:
            return list(csv.DictReader(handle))

    runs = table("runs.csv")
    assert len(runs) == 8 and {r["included"] for r in runs} == {"yes"}
    assert {(r["task"], r["counted_trials"]) for r in runs} == {("localisation", "24"),
                                                                ("apparentmotion", "12")}
    assert {r["trials_finished_twice"] for r in runs} == {""}
    # Each subject's own numbers, from the rows on disk, counted here independently.
    per_subject = {(r["subject"], r["frequency_hz"]): r for r in table("localisation_per_subject.csv")}
    for subject in SUBJECTS:
        rows = [r for r in read_trials(localisation_run(study.root, subject).beh_tsv) if r.counts]
        assert all(isinstance(r, LocalisationRecord) for r in rows)
        for frequency in (3, 5, 10):
            at = [r for r in rows if r.frequency_hz == frequency]
            line = per_subject[(subject, str(frequency))]
            assert (int(line["trials"]), int(line["correct"])) == (
                8, sum(r.category == "correct" for r in at))
    level = {(r["frequency_hz"], r["category"]): r for r in table("localisation_subject_level.csv")}
    correct_10hz = level[("10", "correct")]
    assert correct_10hz["subjects"] == "4" and correct_10hz["trials"] == "32"
    assert correct_10hz["bootstrap95_low_pct"] != "n/a"
    assert 0 <= float(correct_10hz["bootstrap95_low_pct"]) <= float(
        correct_10hz["bootstrap95_high_pct"]) <= 100
    assert {r["subject"] for r in table("motion_per_subject.csv")} == set(SUBJECTS)
