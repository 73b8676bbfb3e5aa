"""The results folder as a BIDS dataset: root files from the first run, sidecars for every run.

At the dataset root: ``dataset_description.json`` (BIDS's required file, naming pinarray and
its version in ``GeneratedBy``), ``README.md``, ``participants.tsv`` and ``participants.json``.
They are created when missing and otherwise kept as the lab edited them: a subject's row is
added to ``participants.tsv`` (never removed; columns the lab added are kept, the new row
n/a there) and this pinarray's version is added to ``GeneratedBy``. Each change replaces the
file atomically under a lock, so two sessions starting at once cannot lose each other's rows.

Each run's ``_beh.json`` and ``_events.json`` sidecars describe every column (Levels for every
categorical one, Units for every measured one), the task (TaskName, TaskDescription,
Instructions), the device, and the run's time base: what its zero is and each sitting's clock,
so a sped-up rehearsal says so in the data's own sidecar, not only in its manifest.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import platform
from pathlib import Path
from typing import Any

from pinarray.errors import ResultsError
from pinarray.journal.columns import entry
from pinarray.journal.files import (
    read_results_json,
    read_results_text,
    read_tsv,
    results_file,
    write_atomically,
)
from pinarray.journal.lock import held
from pinarray.journal.manifest import RunManifest
from pinarray.journal.paths import SOURCEDATA, RunPaths
from pinarray.journal.records import EVENT_ONLY
from pinarray.journal.seam import columns_of, rows_of
from pinarray.journal.timebase import (
    FIRST_TRIAL_ONSET,
    Answers,
    ClockKind,
    Sitting,
    seconds_text,
)
from pinarray.version import __version__

BIDS_VERSION = "1.10.0"
NAME = "pinarray results"
PARTICIPANT_ID = "participant_id"
DATASET_README = """\
# pinarray results

Behavioural data from a 4x4 servo pin-array tactile stimulator, written by pinarray
(localisation: "which pin moved?"; apparent motion: "did a dot move, and which way?").
This folder is a BIDS dataset (https://bids.neuroimaging.io): check it with the official
validator (`bids-validator-deno results/`).

## Layout

    dataset_description.json, participants.tsv, participants.json, README.md
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-<task>_run-<k>_beh.tsv      one row per trial
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-<task>_run-<k>_beh.json     what each column means
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-<task>_run-<k>_events.tsv   onsets for imaging analyses
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-<task>_run-<k>_events.json
    sourcedata/sub-<id>/ses-<n>/beh/<same stem>_manifest.json              plan, seed, protocol hash,
                                                                           sittings, status
    sourcedata/sub-<id>/ses-<n>/beh/<same stem>.lock                       while a process writes the run

Each trial's row is on disk (fsync'd) the moment the trial ends. A trial presented again
(redone, aborted, or its stimulus not delivered) keeps its earlier rows; only a row with
status `ok` counts, and each trial has at most one.

## Time

`onset` (events.tsv) and `stimulus_onset` (beh.tsv) are in seconds from the run's time zero
(the stimulus onset of its first trial unless the sidecar says otherwise), on one time base
for the whole run: a run interrupted and resumed later continues where it stood (in real time
the pause counts; in simulated time it continues from the end of the last trial on file).
Each sitting's wall-clock start (with its UTC offset), its clock (real, or simulated and how
fast) and where it joins the run's time are in the run's manifest and its sidecars'
`TimeBase`. A simulated rehearsal says `"Simulated": true`.

## Resuming

A run has one writer at a time (the `.lock` file in `sourcedata/` names it while it writes).
A run that was stopped or killed resumes with exactly its remaining trials:
Resume on the UI's start screen for a subject's run; for a scripted one, the line `pinarray
batch` printed as it stopped (`pinarray batch FILE --subject ID --responses CSV --resume`).

## Provenance

The manifests in `sourcedata/` hold the full trial plan, the plan's seed, the protocol file's
SHA-256, the software version, the machine, the serial port and servo models, and the run's
status (running, completed, aborted, crashed) with the reason it ended.
"""
_PARTICIPANTS_JSON = {
    PARTICIPANT_ID: {"Description": "Subject label, as given when the session was started "
                                    "(letters and digits)."},
}
# -- dataset-level files -------------------------------------------------------------------------


def generated_by() -> dict[str, str]:
    return {"Name": "pinarray", "Version": __version__,
            "Description": "Drives a 4x4 servo pin-array tactile stimulator and writes each "
                           "trial as it ends."}


def _dump(data: Any) -> str:
    return json.dumps(data, indent=2, ensure_ascii=False) + "\n"


def _description(path: Path) -> None:
    if not results_file(path, "dataset description"):
        write_atomically(path, _dump({"Name": NAME, "BIDSVersion": BIDS_VERSION,
                                      "DatasetType": "raw", "GeneratedBy": [generated_by()]}))
        return
    data = read_results_json(path, "dataset description")
    if not isinstance(data, dict):
        raise ResultsError(f"{path}:1:1: expected a JSON object, found {type(data).__name__}")
    mine = generated_by()
    already = data.get("GeneratedBy") or []
    if not isinstance(already, list):
        raise ResultsError(f"{path}: GeneratedBy must be a list of objects (BIDS), found "
                           f"{type(already).__name__}")
    if not any(isinstance(g, dict) and (g.get("Name"), g.get("Version")) == (mine["Name"],
               mine["Version"]) for g in already):
        write_atomically(path, _dump({**data, "GeneratedBy": [*already, mine]}))


def _participants(tsv: Path, subject: str) -> None:
    participant = f"sub-{subject}"
    rows: list[list[str]] = []
    if results_file(tsv, "participants"):
        text = read_results_text(tsv, "participants")
        rows = read_tsv(tsv, text)
    if not rows:
        rows = [[PARTICIPANT_ID]]
    if rows[0][:1] != [PARTICIPANT_ID]:
        raise ResultsError(f"{tsv}:1:1: expected the first column {PARTICIPANT_ID}, "
                           f"found {rows[0][:1]}")
    if any(row[:1] == [participant] for row in rows[1:]):
        return
    rows.append([participant] + ["n/a"] * (len(rows[0]) - 1))
    out = io.StringIO()
    csv.writer(out, delimiter="\t", lineterminator="\n").writerows(rows)
    write_atomically(tsv, out.getvalue())


DESCRIPTION, PARTICIPANTS, PARTICIPANTS_JSON = (
    "dataset_description.json", "participants.tsv", "participants.json")
DATASET_FILES = (DESCRIPTION, PARTICIPANTS, PARTICIPANTS_JSON)  # the root's, but its README


def ensure_dataset(root: Path | str, subject: str) -> None:
    """Create or complete the dataset's root files, with ``subject`` listed as a participant."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(root))
    root.mkdir(parents=True, exist_ok=True)
    with held(root / SOURCEDATA / "dataset.lock"):
        _description(root / DESCRIPTION)
        if not any(root.glob("README*")):
            write_atomically(root / "README.md", DATASET_README)
        _participants(root / PARTICIPANTS, subject)
        if not results_file(root / PARTICIPANTS_JSON, "participants description"):
            write_atomically(root / PARTICIPANTS_JSON, _dump(_PARTICIPANTS_JSON))


# -- per-run sidecars ----------------------------------------------------------------------------


def _run_levels(manifest: RunManifest) -> dict[str, dict[str, str]]:
    """The run's levels, by column: those its device gives (the pins of its grid), those its
    paradigm gives (the answers offered...), and the task's."""
    info = manifest.task_info
    rows = rows_of(info.paradigm)
    levels = {c.name: dict(c.levels_for(info)) for c in columns_of(rows).values()
              if c.levels_for is not None}
    return levels | rows.levels(manifest) | {
        "task": {manifest.task: info.name + (f": {info.description}" if info.description
                                             else "")}}


def _sitting(sitting: Sitting) -> dict[str, Any]:
    if sitting.start_ns is None:  # no trial ran yet, or an earlier pinarray wrote the run
        start, joins = None, "at a time not recorded"
    else:
        text = seconds_text(sitting.start_ns)
        start, joins = float(text), f"at {text} s"
    return {"Sitting": sitting.number, "StartedAt": sitting.started_at,
            "Clock": sitting.clock.kind.value, "TimeScale": sitting.clock.factor,
            "RunTimeAtStart": start, "AnsweredBy": sitting.answers.value,
            "Description": f"{sitting.clock.describe()}; joins the run's time base {joins}"
                           + (f"; answers: {sitting.answers.describe()}"
                              if sitting.answers is not Answers.UNKNOWN else "")}


def _time_base(manifest: RunManifest) -> dict[str, Any]:
    zero = manifest.time_zero
    return {
        "Zero": zero.event if zero else FIRST_TRIAL_ONSET,
        "ZeroAt": zero.at if zero else None,
        # Simulated servos, or time that is not the wall clock's: not data from a real sitting.
        "Simulated": manifest.provenance.port.startswith("sim://") or any(
            s.clock.kind.simulated or s.clock.kind is ClockKind.SCALED for s in manifest.sittings),
        "Sittings": [_sitting(s) for s in manifest.sittings],
        **({} if manifest.scanner is None else {"Scanner": _scanner(manifest)}),
        "Description": "onset (events.tsv) and stimulus_onset (beh.tsv) are in seconds from the "
                       "run's time zero (Zero; ZeroAt is when it was on the wall clock, with its "
                       "UTC offset) on one time base for all sittings. Each sitting (a resume "
                       "starts a new one) records its wall-clock start (StartedAt), its clock "
                       "and how many of its seconds passed per wall-clock second (TimeScale: 1 "
                       "in real time, null in virtual time), and where it joins the run's time "
                       "base (RunTimeAtStart, s): in real time where the wall clock says (the "
                       "pause counts), in simulated time at the end of the last trial on file. "
                       "Simulated is true when the servos were simulated or any sitting ran in "
                       "simulated or sped-up time: not data from a subject.",
    }


def _scanner(manifest: RunManifest) -> dict[str, Any]:
    """A run timed from scanner volumes: its trigger, and where every volume is logged."""
    record = manifest.scanner
    assert record is not None

    def seconds(ns: int | None) -> float | None:
        return None if ns is None else float(seconds_text(ns))

    return {
        "Trigger": record.trigger, "DummyVolumes": record.dummy_volumes,
        "RepetitionTime": seconds(record.repetition_time_ns),
        "LockToVolumes": record.lock_to_volumes, "Tolerance": seconds(record.tolerance_ns),
        "VolumeLog": record.volume_log,
        "Description": "Time zero is the first counted scanner volume; every volume the trigger "
                       "delivered (and every one it missed) is in volume_log, with its arrival "
                       "on the same time base as onset."}


def _common(manifest: RunManifest) -> dict[str, Any]:
    info, provenance = manifest.task_info, manifest.provenance
    return {
        "TaskName": info.name,
        "TaskDescription": info.description or info.name,
        "Instructions": info.instructions or rows_of(info.paradigm).instructions,
        "StimulusPresentation": {"OperatingSystem": platform.platform(),
                                 "SoftwareName": "pinarray",
                                 "SoftwareVersion": manifest.software_version or __version__},
        "Device": {
            "Description": f"{info.grid_rows}x{info.grid_columns} pin array, one 1 mm pin per "
                           "servo, moved up and down under the fingertip",
            "PitchMm": info.pitch_mm,
            "ServoModels": sorted(set(provenance.servo_models)),
            "Port": provenance.port,
            "SimulatedServos": provenance.port.startswith("sim://"),
        },
        "TimeBase": _time_base(manifest),
    }


def beh_sidecar(manifest: RunManifest) -> dict[str, Any]:
    """The BIDS JSON sidecar of a run's ``beh.tsv``: every column of its paradigm's layout."""
    rows = rows_of(manifest.task_info.paradigm)
    levels = _run_levels(manifest)
    known = columns_of(rows)
    columns = {}
    for name in rows.layout:
        described = entry(known[name])
        if name in levels:
            described["Levels"] = levels[name]
        columns[name] = described
    onset = columns["stimulus_onset"]
    onset["Description"] += f" Zero: {_time_base(manifest)['Zero']}."
    return _common(manifest) | columns


def events_sidecar(manifest: RunManifest) -> dict[str, Any]:
    """The BIDS JSON sidecar of a run's ``events.tsv``."""
    rows = rows_of(manifest.task_info.paradigm)
    beh = beh_sidecar(manifest)
    columns = {name: beh.get(name) or entry(EVENT_ONLY[name]) for name in rows.event_layout}
    columns["onset"]["Description"] += f" Zero: {_time_base(manifest)['Zero']}."
    columns["trial_type"] |= {"Levels": rows.trial_types(manifest.task, manifest.plan)}
    return _common(manifest) | columns


def write_sidecars(paths: RunPaths, manifest: RunManifest) -> None:
    """(Re)write a run's two sidecars atomically."""
    write_atomically(paths.beh_json, _dump(beh_sidecar(manifest)))
    write_atomically(paths.events_json, _dump(events_sidecar(manifest)))
