"""Which runs count: incomplete runs are listed and left out, a trial finished twice is
refused, a run copied or linked inside the results counts once."""

import shutil
from dataclasses import replace

import pytest

from pinarray.analysis.load import (
    DamagedResults,
    ManifestState,
    countable_on_request,
    load_runs,
    scan,
    select_runs,
)
from pinarray.journal.manifest import RunPaths
from pinarray.journal.rows import trial_row
from tests.analysis.conftest import localisation_row
from tests.runs import localisation_plan, start_run


def test_an_aborted_run_with_no_counted_trials_is_listed_and_left_out(tmp_path, write_run):
    root = tmp_path / "results"
    write_run(root, "A", "localisation", [localisation_row(1, 4, "4")])
    write_run(root, "B", "localisation", [localisation_row(1, 4, "4", practice=True)],
              status="aborted")
    runs = select_runs(load_runs([root]))
    assert [r.paths.subject for r in runs.included] == ["A"]
    (left_out,) = runs.excluded
    assert left_out.paths.subject == "B" and left_out.counted == 0
    assert left_out.incomplete_reason == "manifest says aborted"
    # Even when asked for incomplete runs, one with nothing counted adds no subject.
    assert [r.paths.subject for r in select_runs(load_runs([root]), True).included] == ["A"]


def test_an_aborted_run_with_answers_is_left_out_unless_incomplete_runs_are_asked_for(
        tmp_path, write_run):
    root = tmp_path / "results"
    write_run(root, "A", "localisation", [localisation_row(1, 4, "4")])
    write_run(root, "C", "localisation", [localisation_row(1, 4, "4"), localisation_row(2, 4, "3")],
              status="crashed")
    default = select_runs(load_runs([root]))
    assert [r.paths.subject for r in default.excluded] == ["C"]
    asked = select_runs(load_runs([root]), include_incomplete=True)
    assert [r.paths.subject for r in asked.included] == ["A", "C"]
    assert [r.paths.subject for r in asked.incomplete_included] == ["C"]
    assert len(asked.trials) == 3


def test_a_completed_run_whose_rows_are_all_practice_or_redone_is_left_out(tmp_path, write_run):
    root = tmp_path / "results"
    write_run(root, "D", "localisation", [localisation_row(1, 4, "4", practice=True),
                                          localisation_row(2, 4, "3", status="redone")])
    (run,) = select_runs(load_runs([root])).excluded
    assert run.incomplete_reason == "no counted trials"


def test_a_run_killed_outright_still_says_running_and_is_left_out(tmp_path, write_run):
    root = tmp_path / "results"
    write_run(root, "E", "localisation", [localisation_row(1, 4, "4")], status="running")
    (run,) = select_runs(load_runs([root])).excluded
    assert run.state is ManifestState.UNFINISHED and run.status == "running"


def test_a_trial_finished_twice_in_one_run_is_refused_naming_both_rows(tmp_path, write_run):
    # Which of two answers counts is for a person to say (as resume refuses it too).
    root = tmp_path / "results"
    paths = write_run(root, "F", "localisation", [localisation_row(1, 4, "4"),
                                                  localisation_row(2, 10, "10")])
    with open(paths.beh_tsv, "a", encoding="utf-8") as handle:  # a second writer's copy
        handle.write("\t".join(trial_row(localisation_row(1, 4, "3"))) + "\n")
    with pytest.raises(DamagedResults) as raised:
        load_runs([root])
    assert str(raised.value) == (f"{paths.beh_tsv}:4: trial 1 is logged ok twice (lines 2, 4); "
                                 "a trial counts once: delete the row that should not count")


def test_a_results_file_without_its_manifest_counts_with_a_note(tmp_path, write_run):
    root = tmp_path / "results"
    paths = write_run(root, "G", "localisation", [localisation_row(1, 4, "4")])
    paths.manifest.unlink()
    runs = select_runs(load_runs([RunPaths.from_file(paths.beh_tsv).beh_tsv]))
    (run,) = runs.included
    assert run.state is ManifestState.MISSING and runs.without_manifest == (run,)


def test_an_unreadable_manifest_makes_the_run_incomplete_with_the_reason(tmp_path, write_run):
    root = tmp_path / "results"
    paths = write_run(root, "H", "localisation", [localisation_row(1, 4, "4")])
    paths.manifest.write_text("{not json")
    (run,) = select_runs(load_runs([root])).excluded
    assert run.state is ManifestState.UNREADABLE
    assert run.incomplete_reason.startswith("manifest unreadable (") and ":1:2:" in run.status


def test_a_run_whose_manifest_cannot_be_read_is_not_counted_even_on_request(tmp_path, write_run):
    # Its rows can only be checked against the manifest (the plan, the answers offered): a
    # pin or an answer edited to one the run never had would be counted unchecked.
    root = tmp_path / "results"
    paths = write_run(root, "H", "localisation", [localisation_row(1, 4, "4")])
    paths.manifest.write_text("[]")
    runs = select_runs(load_runs([root]), include_incomplete=True)
    assert runs.included == ()
    (run,) = runs.excluded
    assert run.state is ManifestState.UNREADABLE and not countable_on_request(run)
    assert "not counted, even with --include-incomplete" in run.incomplete_reason


# -- a run is counted once, whatever copies and links of its files lie beside it -----------

def test_copies_of_a_runs_folders_in_the_results_are_passed_over_and_said(tmp_path, write_run):
    root = tmp_path / "results"
    paths = write_run(root, "A", "localisation", [localisation_row(1, 4, "4")])
    for copy in ("sub-A copy", "sub-A.bak", "sub-A_old"):  # what a file manager or a lab names
        shutil.copytree(root / "sub-A", root / copy)
    shutil.copytree(root / "sourcedata" / "sub-A", root / "sourcedata" / "sub-A copy")
    shutil.copytree(root / "sub-A" / "ses-1", root / "sub-A" / "ses-2")
    shutil.copytree(paths.beh_dir, paths.beh_dir.with_name("beh copy"))
    found = scan([root])
    assert [run.source for run in found.runs] == [paths.beh_tsv] and found.damaged == ()
    said = "\n".join(found.passed_over)
    for copy in ("sub-A copy/ses-1/beh", "sub-A.bak/ses-1/beh", "sub-A_old/ses-1/beh",
                 "sub-A/ses-1/beh copy", "sub-A/ses-2/beh"):
        assert f"{root / copy / paths.beh_tsv.name}: passed over: a file of {paths.label} " \
               f"belongs in sub-A/ses-1/beh/, not in {copy}/ (a copy?)" in said
    assert len(found.passed_over) == 5
    assert [r.source for r in load_runs([root])] == [paths.beh_tsv]


def test_one_results_file_reached_twice_through_links_is_read_once(tmp_path, write_run):
    root = tmp_path / "results"
    paths = write_run(root, "A", "localisation", [localisation_row(1, 4, "4")])
    run_2 = paths.beh_tsv.with_name(paths.beh_tsv.name.replace("run-1", "run-2"))
    run_2.symlink_to(paths.beh_tsv.name)
    linked = tmp_path / "linked"
    linked.symlink_to(root)
    found = scan([root, linked])
    assert [run.source for run in found.runs] == [paths.beh_tsv]
    assert sorted(found.passed_over) == sorted(
        f"{other}: the same file as {paths.beh_tsv} (reached through a link); read once"
        for other in (run_2, linked / paths.relative_dir / paths.beh_tsv.name,
                      linked / paths.relative_dir / run_2.name))


def test_a_run_copied_under_another_runs_name_with_its_manifest_is_refused(tmp_path, write_run):
    root = tmp_path / "results"
    paths = write_run(root, "A", "localisation", [localisation_row(1, 4, "4")])
    copy = RunPaths(root, "B", "1", "localisation", 1)
    for folder in (copy.beh_dir, copy.source_dir):
        folder.mkdir(parents=True)
    shutil.copy(paths.beh_tsv, copy.beh_tsv)
    shutil.copy(paths.manifest, copy.manifest)
    with pytest.raises(DamagedResults) as raised:
        load_runs([root])
    assert str(raised.value) == (
        f"{copy.beh_tsv}: its manifest {copy.manifest} says it is {paths.label}, the file's "
        f"name says {copy.label} (a copy of another run, renamed?); keep each run under its "
        "own name, or remove the copy")


@pytest.mark.parametrize("manifest", ["kept", "left out"])
def test_a_run_copied_to_the_next_run_number_is_counted_once(tmp_path, manifest):
    root = tmp_path / "results"
    writer = start_run(root, "A", "localisation", localisation_plan((4, 10.0)))
    writer.set_time_zero(0, 0)
    writer.write_trial(localisation_row(1, 4, "4"))
    writer.finish("completed")
    paths = writer.paths
    copy = replace(paths, run=2)
    shutil.copy(paths.beh_tsv, copy.beh_tsv)
    shutil.copy(paths.beh_json, copy.beh_json)
    if manifest == "kept":  # renamed inside too: only the run's time and rows tell
        copy.manifest.write_text(paths.manifest.read_text().replace('"run": 1', '"run": 2'))
    else:  # a dataset shared without sourcedata/: the sidecars say the time zero
        shutil.rmtree(root / "sourcedata")
    found = scan([root])
    assert [run.source for run in found.runs] == [paths.beh_tsv]
    (said,) = found.passed_over
    assert said.startswith(f"{copy.beh_tsv}: passed over: a copy of the run {paths.beh_tsv} "
                           "(the same time zero ")
