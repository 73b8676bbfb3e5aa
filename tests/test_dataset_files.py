"""The results folder is a BIDS dataset from its first run: root files, participants, sidecars."""

import csv
import json
import stat
import subprocess
import sys

import pytest

from pinarray import __version__
from pinarray.errors import ResultsError
from pinarray.journal import dataset
from pinarray.journal.columns import Cell
from pinarray.journal.records import LEGACY_EVENT_LAYOUT, LEGACY_LAYOUT
from pinarray.journal.rows import read_trials
from pinarray.journal.seam import columns_of, rows_of
from pinarray.journal.writer import RunWriter
from tests.runs import REPO, VIRTUAL, localisation_plan, start_run


def participants(root):
    with open(root / "participants.tsv", newline="") as handle:
        return list(csv.reader(handle, delimiter="\t"))


def test_the_first_run_makes_the_folder_a_bids_dataset(tmp_path):
    start_run(tmp_path, "01", "localisation", localisation_plan((4, 10))).close()
    description = json.loads((tmp_path / "dataset_description.json").read_text())
    assert description["BIDSVersion"] and description["DatasetType"] == "raw"
    assert description["GeneratedBy"] == [dataset.generated_by()]
    assert description["GeneratedBy"][0]["Name"] == "pinarray"
    assert description["GeneratedBy"][0]["Version"] == __version__
    assert "bids-validator-deno" in (tmp_path / "README.md").read_text()
    assert participants(tmp_path) == [["participant_id"], ["sub-01"]]
    assert "participant_id" in json.loads((tmp_path / "participants.json").read_text())
    # Provenance lives in sourcedata/, which BIDS leaves to the lab: nothing non-BIDS beside the data.
    beh_dir = tmp_path / "sub-01" / "ses-1" / "beh"
    assert sorted(p.name.split("_run-1_")[1] for p in beh_dir.iterdir()) == [
        "beh.json", "beh.tsv", "events.json", "events.tsv"]
    assert (tmp_path / "sourcedata" / "sub-01" / "ses-1" / "beh"
            / "sub-01_ses-1_task-localisation_run-1_manifest.json").exists()


def test_a_lab_edits_root_files_and_pinarray_keeps_them(tmp_path, monkeypatch):
    start_run(tmp_path, "01", "localisation", localisation_plan((4, 10))).close()
    path = tmp_path / "dataset_description.json"
    edited = json.loads(path.read_text()) | {"Name": "Fingertip localisation", "Authors": ["A. B."],
                                              "License": "CC0"}
    path.write_text(json.dumps(edited))
    # saved from a spreadsheet: a byte-order mark first
    (tmp_path / "participants.tsv").write_text("\ufeffparticipant_id\tage\nsub-01\t34\n")
    (tmp_path / "README.md").write_text("Our study.\n")
    monkeypatch.setattr(dataset, "__version__", "9.9.9")  # a newer pinarray writes next
    start_run(tmp_path, "02", "localisation", localisation_plan((4, 10))).close()
    start_run(tmp_path, "02", "localisation", localisation_plan((4, 10))).close()
    description = json.loads(path.read_text())
    assert {k: description[k] for k in ("Name", "Authors", "License")} == {
        "Name": "Fingertip localisation", "Authors": ["A. B."], "License": "CC0"}
    assert [g["Version"] for g in description["GeneratedBy"]] == [__version__, "9.9.9"]
    assert participants(tmp_path) == [["participant_id", "age"], ["sub-01", "34"], ["sub-02", "n/a"]]
    assert (tmp_path / "README.md").read_text() == "Our study.\n"


def test_a_damaged_root_file_is_refused_in_one_line_and_left_as_it_was(tmp_path):
    (tmp_path / "dataset_description.json").write_text('{"Name": "x", "GeneratedBy": {"Name": 1}}')
    with pytest.raises(ResultsError) as refused:
        start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    assert "GeneratedBy must be a list" in str(refused.value) and "\n" not in str(refused.value)
    assert (tmp_path / "dataset_description.json").read_text() == (
        '{"Name": "x", "GeneratedBy": {"Name": 1}}')
    (tmp_path / "participants.tsv").write_text("subject\nsub-01\n")
    (tmp_path / "dataset_description.json").unlink()
    with pytest.raises(ResultsError, match=r"participants.tsv:1:1: expected the first column "
                                           r"participant_id, found \['subject'\]"):
        start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    # a cell longer than Python's csv module reads: said at its line, not in csv's words
    long_cell = "participant_id\tnote\nsub-01\t" + "x" * 200_000 + "\n"
    (tmp_path / "participants.tsv").write_text(long_cell)
    with pytest.raises(ResultsError, match=r"participants.tsv:2:8: expected cells of at most "
                                           r"131,072 characters, found one of 200,000$"):
        start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    assert (tmp_path / "participants.tsv").read_text() == long_cell


def test_a_subject_is_listed_once_however_many_runs_and_resumes(tmp_path):
    for subject in ("01", "02", "01"):
        writer = start_run(tmp_path, subject, "localisation", localisation_plan((4, 10)))
        writer.close()
        RunWriter.resume(writer.paths, VIRTUAL).close()
    assert participants(tmp_path) == [["participant_id"], ["sub-01"], ["sub-02"]]


ADD_SUBJECTS = """
import sys
from pinarray.journal.dataset import ensure_dataset
for n in range(int(sys.argv[3])):
    ensure_dataset(sys.argv[1], f"{sys.argv[2]}x{n}")
"""


def test_participants_written_by_processes_at_the_same_time_are_all_kept(tmp_path):
    processes = [subprocess.Popen([sys.executable, "-c", ADD_SUBJECTS, str(tmp_path), f"p{i}", "8"],
                                  cwd=REPO) for i in range(6)]
    assert [p.wait(timeout=120) for p in processes] == [0] * 6
    rows = participants(tmp_path)
    assert rows[0] == ["participant_id"]
    assert sorted(r[0] for r in rows[1:]) == sorted(f"sub-p{i}x{n}" for i in range(6) for n in range(8))


def test_the_sidecars_describe_every_column_with_levels_or_units(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10), (7, 3)))
    writer.close()
    beh = json.loads(writer.paths.beh_json.read_text())
    for column in columns_of(rows_of("localisation")).values():
        assert beh[column.name]["Description"]
        if column.cell in (Cell.SECONDS, Cell.BOOLEAN) or column.name == "frequency_hz":
            assert "Units" in beh[column.name] or "Levels" in beh[column.name], column.name
    assert beh["stimulus_onset"]["Units"] == beh["response_time"]["Units"] == "s"
    assert beh["task"]["Levels"] == {"localisation": "localisation"}
    assert set(beh["pin"]["Levels"]) == {str(p) for p in range(1, 17)}
    assert beh["pin"]["Levels"]["4"] == "row 1, column 4 (row 1 at the bottom)"
    assert set(beh["response"]["Levels"]) == {str(p) for p in range(1, 17)} | {"none"}
    assert set(beh["error_class"]["Levels"]) == {"correct", "A", "B", "C", "D", "none"}
    assert "Practice trials come first" in beh["trial"]["Description"]
    assert beh["TaskName"] == "localisation" and "name the pin" in beh["Instructions"]
    assert beh["Device"]["PitchMm"] == 2.0 and beh["Device"]["ServoModels"] == ["STS3215"]
    events = json.loads(writer.paths.events_json.read_text())
    assert [k for k in events if k in LEGACY_EVENT_LAYOUT] == list(LEGACY_EVENT_LAYOUT)
    assert events["onset"]["Units"] == events["duration"]["Units"] == "s"
    assert events["trial_type"]["Levels"] == {"localisation_3hz": "one pin moves at 3 Hz",
                                              "localisation_10hz": "one pin moves at 10 Hz"}


def test_dataset_files_are_readable_as_the_umask_allows_not_owner_only(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    writer.close()
    data_mode = stat.S_IMODE(writer.paths.beh_tsv.stat().st_mode)  # an ordinary new file
    for path in (writer.paths.manifest, writer.paths.beh_json, tmp_path / "participants.tsv",
                 tmp_path / "dataset_description.json", tmp_path / "README.md"):
        assert stat.S_IMODE(path.stat().st_mode) == data_mode, path


OLD_HEADER = ("trial\tblock\ttask\tpin\trow\tdirection\tfrequency_hz\tresponse\terror_class\t"
              "perceived_motion\tdirection_correct\tonset\tduration\tresponse_time\tstatus\t"
              "practice\tresumed\n")
OLD_ROW = "1\t1\tlocalisation\t4\tn/a\tn/a\t10\t4\tcorrect\tn/a\tn/a\t12.5\t10\t1.5\tok\tfalse\tfalse\n"


def test_results_written_before_the_onset_columns_were_renamed_are_still_read(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    writer.close()
    writer.paths.beh_tsv.write_text(OLD_HEADER + OLD_ROW)
    (row,) = read_trials(writer.paths.beh_tsv)
    assert (row.onset_ns, row.duration_ns, row.response_time_ns) == (12_500_000_000, 10**10,
                                                                     1_500_000_000)


def test_resuming_a_run_with_the_old_column_names_renames_them_adds_todays_as_na_and_keeps_every_row(
        tmp_path):
    header = OLD_HEADER.rstrip("\n") + "\tgoals_scheduled\tgoals_confirmed\tgoals_healed\t" \
        "goals_missing\tdelivery_lateness\tstatus_reason\n"
    row = OLD_ROW.rstrip("\n") + "\t4\t4\t0\t0\t0.001\tn/a\n"
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10), (7, 3)))
    writer.close()
    writer.paths.beh_tsv.write_text(header + row)
    before = read_trials(writer.paths.beh_tsv)
    resumed = RunWriter.resume(writer.paths, VIRTUAL)
    resumed.close()
    text = writer.paths.beh_tsv.read_text()
    assert text.splitlines()[0].split("\t")[11:13] == ["stimulus_onset", "stimulus_duration"]
    lines = text.splitlines()
    added = lines[1].split("\t")[len(row.split("\t")):]
    assert lines[1].startswith(row.rstrip("\n") + "\t") and set(added) == {"n/a"}
    assert len(lines[1].split("\t")) == len(lines[0].split("\t")) == len(LEGACY_LAYOUT)
    assert read_trials(writer.paths.beh_tsv) == before
    assert [e.trial for e in resumed.remaining()] == [2]

