"""Which runs count: incomplete runs are listed and left out, a trial finished twice counts once."""

from pinarray.analysis.load import ManifestState, countable_on_request, load_runs, select_runs
from pinarray.journal.manifest import RunPaths
from pinarray.journal.rows import trial_row
from tests.analysis.conftest import localisation_row


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


def test_a_trial_finished_twice_in_one_run_counts_once_the_first_row(tmp_path, write_run):
    root = tmp_path / "results"
    paths = write_run(root, "F", "localisation", [localisation_row(1, 4, "4"),
                                                  localisation_row(2, 10, "10")])
    with open(paths.beh_tsv, "a", encoding="utf-8") as handle:  # a second writer's copy
        handle.write("\t".join(trial_row(localisation_row(1, 4, "3"))) + "\n")
    (run,) = load_runs([root])
    assert run.duplicates == (1,)
    assert [(r.trial, r.response) for r in run.records] == [(1, "4"), (2, "10")]


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
