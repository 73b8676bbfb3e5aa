"""The pins' measured motion in the results: beh.tsv's stroke columns and the motion recording."""

import errno
import gzip
import json
import os
import subprocess
import sys
import textwrap
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.errors import PinArrayError, ResultsError
from pinarray.journal.columns import tsv_line
from pinarray.journal.manifest import read_manifest
from pinarray.journal.physio import (
    MotionSample,
    motion_lines,
    motion_recording_path,
    read_motion,
)
from pinarray.journal.records import LEGACY_LAYOUT, StrokeCounts
from pinarray.journal.rows import read_trials, trial_row
from pinarray.journal.timebase import seconds_text
from pinarray.journal.writer import RunWriter
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.protocol.load import parse_protocol
from tests.runs import REPO, localisation_plan, start_run

S = 1_000_000_000


# The frequencies of the plans below, trial by trial: a row read back is checked against its
# run's plan.
FREQUENCIES = (10.0, 3.0, 5.0)


def localisation(trial, **more):
    return LocalisationRecord(trial=trial, block=1, task="localisation", onset_ns=12 * S * trial,
                              duration_ns=10 * S, response="4", pin=4,
                              frequency_hz=FREQUENCIES[trial - 1], error_class="correct", **more)


def samples(trial, count=50):
    return [MotionSample(12 * S * trial + k * 1_000_000, trial, 4, 2048 + k, 2162)
            for k in range(count)]


def test_a_trial_s_stroke_is_written_and_read_back_with_not_measured_as_n_a(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10), (4, 3)))
    writer.write_trial(localisation(1, stroke=StrokeCounts(114, 80, 80.5, 64_000_000, 9)))
    writer.write_trial(localisation(2, stroke=StrokeCounts(114)))  # too few samples to judge
    writer.close()
    first, second = read_trials(writer.paths.beh_tsv)
    assert first.stroke == StrokeCounts(114, 80, 80.5, 64_000_000, 9)
    assert second.stroke == StrokeCounts(114)
    header, row, _ = writer.paths.beh_tsv.read_text().split("\n", 2)
    cells = dict(zip(header.split("\t"), row.split("\t"), strict=True))
    assert [cells[c] for c in ("stroke_commanded", "stroke_achieved", "stroke_median",
                               "motion_lag", "cycles_short")] == ["114", "80", "80.5", "0.064", "9"]
    # Appended after every earlier column (later ones, motion_samples and the lab's
    # paradigms', after them): an older run resumed gets them as n/a cells.
    start = LEGACY_LAYOUT.index("stroke_commanded")
    assert start > LEGACY_LAYOUT.index("guess_rate")
    assert LEGACY_LAYOUT[start:start + 6] == ("stroke_commanded", "stroke_achieved",
                                          "stroke_median", "motion_lag", "cycles_short",
                                          "motion_samples")
    described = json.loads(writer.paths.beh_json.read_text())
    assert described["stroke_achieved"]["Units"] == "steps" and "Description" in described["motion_lag"]


@given(st.lists(st.builds(MotionSample, st.integers(-10**13, 10**13), st.integers(1, 999),
                          st.integers(1, 64), st.integers(-30719, 30719),
                          st.none() | st.integers(-30719, 30719))))
def test_a_recording_line_times_its_sample_as_every_results_file_writes_times(recorded):
    lines = motion_lines(recorded).decode("ascii").splitlines()
    assert lines == [
        f"{seconds_text(s.time_ns)}\t{s.trial}\t{s.pin}\t{s.position_steps}\t"
        f"{'n/a' if s.goal_steps is None else s.goal_steps}" for s in recorded]


def test_results_written_before_the_stroke_columns_still_read(tmp_path):
    older = LEGACY_LAYOUT[: LEGACY_LAYOUT.index("stroke_commanded")]
    row = trial_row(localisation(1))[: len(older)]
    path = tmp_path / "sub-01_ses-1_task-localisation_run-1_beh.tsv"
    path.write_text(tsv_line(older) + tsv_line(row))
    (record,) = read_trials(path)
    assert record.stroke is None and record.trial == 1


def test_each_trial_s_samples_go_to_a_bids_motion_recording_beside_beh_tsv(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10), (4, 3)))
    writer.write_trial(localisation(1), samples(1))
    writer.write_trial(localisation(2), samples(2))
    writer.close()
    path = motion_recording_path(writer.paths)
    assert path.parent == writer.paths.beh_tsv.parent
    assert path.name == "sub-01_ses-1_task-localisation_run-1_recording-motion_physio.tsv.gz"
    text = gzip.decompress(path.read_bytes()).decode()  # one whole gzip file, no header line
    assert text.splitlines()[0] == "12\t1\t4\t2048\t2162"
    assert read_motion(path) == samples(1) + samples(2)
    sidecar = json.loads(path.with_name(path.name.replace(".tsv.gz", ".json")).read_text())
    assert sidecar["Columns"] == ["timestamp", "trial", "pin", "position", "goal"]
    assert sidecar["SamplingFrequency"] == 1000 and sidecar["StartTime"] == 0
    # recommended by BIDS for a physio recording: the task's name as beh.json gives it
    manifest = json.loads(writer.paths.manifest.read_text())
    assert (sidecar["TaskName"], sidecar["PhysioType"]) == (manifest["task_info"]["name"], "generic")


KILLED_MID_RUN = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    from tests.runs import localisation_plan, start_run
    from tests.test_motion_results import localisation, samples
    writer = start_run(Path(sys.argv[1]), "01", "localisation", localisation_plan((4, 10), (4, 3), (4, 5)))
    writer.write_trial(localisation(1), samples(1))
    writer.write_trial(localisation(2), samples(2))
    os.kill(os.getpid(), signal.SIGKILL)
""")


def test_a_run_killed_mid_run_keeps_every_trial_s_samples_and_resumes_the_recording(tmp_path):
    subprocess.run([sys.executable, "-c", KILLED_MID_RUN, str(tmp_path)], cwd=REPO, check=False,
                   env=os.environ | {"PYTHONPATH": str(REPO)}, timeout=120)
    writer = RunWriter.resume(start_paths(tmp_path))
    path = motion_recording_path(writer.paths)
    assert read_motion(path) == samples(1) + samples(2)  # no end written, nothing lost
    writer.write_trial(localisation(3), samples(3))
    writer.close()
    assert read_motion(path) == samples(1) + samples(2) + samples(3)
    gzip.decompress(path.read_bytes())  # a whole gzip file again


def start_paths(root):
    from pinarray.journal.paths import RunPaths
    return RunPaths(root, "01", "1", "localisation", 1)


# -- a row is ok only when its samples are on disk ----------------------------------------------

def three_trials(root):
    return start_run(root, "01", "localisation", localisation_plan((4, 10), (4, 3), (4, 5)))


def test_each_row_says_how_many_samples_of_its_presentation_the_recording_holds(tmp_path):
    writer = three_trials(tmp_path)
    writer.write_trial(localisation(1), samples(1, 30))
    writer.write_trial(localisation(2))  # none taken (a PWM array, a stimulus that never played)
    writer.close()
    assert [r.motion_samples for r in read_trials(writer.paths.beh_tsv)] == [30, 0]


def test_a_disk_that_fills_as_a_trials_samples_are_synced_leaves_no_ok_row_and_resume_plays_it_again(
        tmp_path, monkeypatch):
    writer = three_trials(tmp_path)
    writer.write_trial(localisation(1), samples(1))
    recording = motion_recording_path(writer.paths)
    sync = os.fsync

    def full_for_the_recording(fd):  # ext4 says ENOSPC at fsync, the data never on disk
        if os.readlink(f"/proc/self/fd/{fd}") == str(recording):
            raise OSError(errno.ENOSPC, "No space left on device")
        sync(fd)

    monkeypatch.setattr(os, "fsync", full_for_the_recording)
    with pytest.raises(ResultsError, match=f"{recording}.*No space left on device"):
        writer.write_trial(localisation(2), samples(2))
    monkeypatch.setattr(os, "fsync", sync)  # space freed
    writer.close()
    assert [r.trial for r in read_trials(writer.paths.beh_tsv)] == [1]  # no row claims trial 2
    again = RunWriter.resume(start_paths(tmp_path))
    assert [entry.trial for entry in again.remaining()] == [2, 3]  # played again
    again.write_trial(localisation(2), samples(2))
    again.close()
    assert read_motion(recording) == samples(1) + samples(2)  # the failed attempt's dropped


def test_a_recording_deleted_mid_run_ends_the_sitting_before_the_row_and_resume_refuses_honestly(
        tmp_path):
    writer = three_trials(tmp_path)
    writer.write_trial(localisation(1), samples(1))
    recording = motion_recording_path(writer.paths)
    recording.unlink()  # a tidy-minded colleague, mid-run
    with pytest.raises(ResultsError, match="the run's motion recording was deleted or replaced"):
        writer.write_trial(localisation(2), samples(2))
    writer.close()
    assert [r.trial for r in read_trials(writer.paths.beh_tsv)] == [1]
    with pytest.raises(ResultsError) as refused:
        RunWriter.resume(start_paths(tmp_path))
    assert str(refused.value) == (
        f"{recording}: is missing, but the rows of the run's beh.tsv claim 50 (trial 1's are "
        "not all there): the motion recording was deleted, cut or replaced; put it back as it "
        "was to resume this run, or start a new run (this one is left as it is)")
    assert len(read_manifest(writer.paths.manifest).sittings) == 1  # nothing changed


def test_a_recording_cut_short_while_the_run_was_stopped_is_refused_on_resume(tmp_path):
    writer = three_trials(tmp_path)
    writer.write_trial(localisation(1), samples(1))
    writer.write_trial(localisation(2), samples(2))
    writer.close()
    recording = motion_recording_path(writer.paths)
    recording.write_bytes(gzip.compress(gzip.decompress(recording.read_bytes())[:1500]))
    with pytest.raises(ResultsError, match="trial 2's are not all there"):
        RunWriter.resume(start_paths(tmp_path))


@pytest.mark.parametrize("value", ["120", "-5", "lots"])
def test_a_stroke_tolerance_outside_0_to_100_percent_is_a_located_error(value):
    text = (REPO / "protocols" / "localisation.yaml").read_text().replace(
        '  port: "sim://"\n', f'  port: "sim://"\n  stroke_tolerance_percent: {value}\n')
    with pytest.raises(PinArrayError) as refused:
        parse_protocol(text, "p.yaml")
    assert str(refused.value).startswith("p.yaml:10:")
    assert "stroke tolerance" in str(refused.value)


def test_a_protocol_sets_its_stroke_tolerance_in_percent():
    text = (REPO / "protocols" / "localisation.yaml").read_text().replace(
        '  port: "sim://"\n', '  port: "sim://"\n  stroke_tolerance_percent: 65\n')
    assert parse_protocol(text, "p.yaml").device.stroke_tolerance == Fraction(65, 100)
    assert parse_protocol((REPO / "protocols" / "localisation.yaml").read_text(),
                          "p.yaml").device.stroke_tolerance == Fraction(8, 10)

