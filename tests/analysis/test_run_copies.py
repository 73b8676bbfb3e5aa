"""Which files are a dataset's runs: the raw runs under its sub- folders, each counted once
whatever backups, copies and links of it lie around, distinct runs never passed over."""

import os
import shutil
from dataclasses import replace
from datetime import UTC, datetime, timedelta

import pytest

from pinarray.analysis.load import DamagedResults, ManifestState, load_runs, scan, select_runs
from pinarray.journal.paths import RunPaths
from tests.analysis.conftest import localisation_row
from tests.runs import localisation_plan, start_run

T0 = datetime(2026, 11, 28, 9, 0, tzinfo=UTC)


def timed_run(root, subject, trials, *, finish="completed", minutes=0, session=1, then=None):
    """A run with its time zero on the wall clock (``minutes`` after 9:00), ``trials`` rows;
    ``then(paths)`` is called after all but the last row (a backup taken mid-run)."""
    plan = localisation_plan(*[(4, 10.0)] * trials)
    writer = start_run(root, subject, "localisation", plan, session=session,
                       wall=lambda: T0 + timedelta(minutes=minutes))
    writer.set_time_zero(0, 0)
    for trial in range(1, trials + 1):
        if trial == trials and then is not None:
            then(writer.paths)
        writer.write_trial(localisation_row(trial, 4, "4"))
    if finish:
        writer.finish(finish)
    return writer.paths


def copy_files(paths, to_folder, run=None):
    """The run's beh.tsv and beh.json copied into ``to_folder`` (as run ``run`` if given)."""
    to_folder.mkdir(parents=True, exist_ok=True)
    stem = paths.stem if run is None else replace(paths, run=run).stem
    for source in (paths.beh_tsv, paths.beh_json):
        shutil.copy(source, to_folder / source.name.replace(paths.stem, stem))
    return to_folder / f"{stem}_beh.tsv"


def sources(found):
    return [run.source for run in found.runs]


def test_a_backup_taken_mid_run_is_passed_over_and_the_finished_run_counted_once(tmp_path):
    root = tmp_path / "results"
    copies = {}

    def backup(paths):  # two rows of three written: the lab saves what is there
        for folder in ("sourcedata/backup", "derivatives/snap", "backup"):
            shutil.copytree(root / "sub-A", root / folder / "sub-A")
        copies["run-2"] = copy_files(paths, paths.beh_dir, run=2)

    paths = timed_run(root, "A", 3, then=backup)
    found = scan([root])
    assert sources(found) == [paths.beh_tsv] and found.damaged == ()
    (run,) = found.runs
    assert run.state is ManifestState.COMPLETED and run.counted == 3
    (said,) = found.passed_over  # the folders outside sub-* are no raw data: not searched
    assert said.startswith(f"{copies['run-2']}: passed over: a copy of the run {paths.beh_tsv} "
                           "(the same time zero 2026-11-28T09:00:00.000000+00:00); that file "
                           "is the run, read with its manifest")


def test_a_backup_of_an_aborted_run_is_never_counted_in_its_place(tmp_path):
    root = tmp_path / "results"
    paths = timed_run(root, "A", 2, finish="aborted")
    for folder in ("backup", "sourcedata/backup", "derivatives/old"):
        shutil.copytree(root / "sub-A", root / folder / "sub-A")
    copy_files(paths, paths.source_dir)  # beside its manifest
    renamed = [copy_files(paths, paths.beh_dir, run=2)]
    for source in (paths.beh_tsv, paths.beh_json):  # run-01: its number spelt otherwise
        shutil.copy(source, source.with_name(source.name.replace("run-1_", "run-01_")))
    renamed.append(paths.beh_tsv.with_name(paths.beh_tsv.name.replace("run-1_", "run-01_")))
    for subject, session in (("a", "1"), ("A", "01")):  # a copy under another label
        other = RunPaths(root, subject, session, paths.task, 1)
        target = copy_files(paths, other.beh_dir.parent / "tmp")
        os.renames(target.parent, other.beh_dir)
        for name in os.listdir(other.beh_dir):
            os.rename(other.beh_dir / name, other.beh_dir / name.replace(paths.stem, other.stem))
        renamed.append(other.beh_tsv)
    found = scan([root])
    assert sources(found) == [paths.beh_tsv] and found.damaged == ()
    assert sorted(line.split(":")[0] for line in found.passed_over) == sorted(map(str, renamed))
    assert all(f"a copy of the run {paths.beh_tsv} " in line for line in found.passed_over)
    runs = select_runs(found.runs, include_incomplete=False)
    assert runs.included == () and runs.excluded[0].incomplete_reason == "manifest says aborted"


def test_a_copy_with_other_line_ends_or_edited_onsets_counts_once(tmp_path):
    root = tmp_path / "results"
    paths = timed_run(root, "A", 2)
    crlf = copy_files(paths, paths.beh_dir, run=2)
    crlf.write_bytes(crlf.read_bytes().replace(b"\n", b"\r\n"))
    shifted = copy_files(paths, paths.beh_dir, run=3)
    lines = shifted.read_text().splitlines(keepends=True)
    header = lines[0].split("\t")
    onset = header.index("stimulus_onset")
    rows = [line.split("\t") for line in lines[1:]]
    for row in rows:
        row[onset] = f"{float(row[onset]) + 1000:.6f}"
    shifted.write_text(lines[0] + "".join("\t".join(row) for row in rows))
    found = scan([root])
    assert sources(found) == [paths.beh_tsv] and found.damaged == ()
    assert sorted(line.split(":")[0] for line in found.passed_over) == [str(crlf), str(shifted)]
    # Shared without sourcedata/: the same rows (line ends aside) are one run; rows that
    # differ with no manifest to tell which is the run are refused in one line, naming both.
    shutil.rmtree(root / "sourcedata")
    shifted.unlink()
    found = scan([root])
    assert sources(found) == [paths.beh_tsv] and found.damaged == ()
    shutil.copy(crlf, shifted)
    shifted.write_text(lines[0] + "".join("\t".join(row) for row in rows))
    crlf.unlink()
    with pytest.raises(DamagedResults) as raised:
        load_runs([root])
    assert str(raised.value) == (
        f"{shifted}: the same run as {paths.beh_tsv} (the same time zero "
        "2026-11-28T09:00:00.000000+00:00), and nothing tells which is the run: their rows "
        "differ and no manifest says which is the run; keep the run's file and move the copy "
        "out of the dataset's sub- folders")


def test_distinct_runs_are_each_counted_with_and_without_their_manifests(tmp_path):
    root = tmp_path / "results"
    made = [timed_run(root, "A", 2), timed_run(root, "B", 2, minutes=1),
            timed_run(root, "A", 2, minutes=2), timed_run(root, "A", 2, minutes=3, session=2)]
    assert [p.run for p in made] == [1, 1, 2, 1]
    assert sources(scan([root])) == sorted(p.beh_tsv for p in made)
    shutil.rmtree(root / "sourcedata")
    found = scan([root])
    assert sources(found) == sorted(p.beh_tsv for p in made)
    assert found.passed_over == () and found.damaged == ()


def test_a_subject_folder_linked_in_is_followed_and_one_gone_is_said(tmp_path):
    root = tmp_path / "results"
    first, second = timed_run(root, "A", 2), timed_run(root, "B", 2, minutes=1)
    elsewhere = tmp_path / "other disk"
    elsewhere.mkdir()
    shutil.move(root / "sub-B", elsewhere / "sub-B")
    (root / "sub-B").symlink_to(elsewhere / "sub-B")
    (root / "sub-B" / "ses-1" / "beh").rename(root / "sub-B" / "ses-1" / "beh_real")
    (root / "sub-B" / "ses-1" / "beh").symlink_to("beh_real")
    found = scan([root])
    assert sources(found) == [first.beh_tsv, second.beh_tsv]
    assert found.passed_over == (
        f"{root}/sub-B/ses-1/beh_real/{second.beh_tsv.name}: the same file as "
        f"{second.beh_tsv} (reached through a link); read once",)
    shutil.rmtree(elsewhere)
    found = scan([root])
    assert sources(found) == [first.beh_tsv]
    assert found.passed_over == (
        f"{second.manifest}: the manifest of {second.label}, but no {second.beh_tsv} (moved "
        "or deleted?): the run is not counted",)


def test_hidden_files_are_passed_over_and_said(tmp_path):
    root = tmp_path / "results"
    paths = timed_run(root, "A", 2)
    apple = paths.beh_dir / f"._{paths.beh_tsv.name}"
    apple.write_bytes(b"\x00\x05\x16\x07 Mac OS X")
    found = scan([root])
    assert sources(found) == [paths.beh_tsv] and found.damaged == ()
    assert found.passed_over == (
        f"{apple}: passed over: a hidden file ('{apple.name}' starts with '.', as the "
        "leftovers of a copy do, such as macOS's ._ files), not a run",)
