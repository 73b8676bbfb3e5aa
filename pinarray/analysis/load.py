"""Find and read runs: the analysis reads result files (rows and manifests) and nothing else.

A run is one ``beh.tsv`` with its manifest (in ``sourcedata/``, or beside it for runs written
before the manifests moved there). Which runs count is decided here, once:
a run whose manifest does not say ``completed``, or that holds no counted trial (a main
trial with status ok), is *incomplete*; incomplete runs are listed and left out unless the
caller asks for them. A run with no manifest at all (a file handed over on its own) cannot
be judged and is counted, with a note. Within a run a trial finished twice (two ``ok`` rows
for one trial number, as two processes writing one run leave) counts once: the first row.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.journal.manifest import read_manifest
from pinarray.journal.paths import RunPaths
from pinarray.journal.records import TrialRecord, TrialStatus, read_trials

BEH_PATTERN = "*_beh.tsv"


class ManifestState(StrEnum):
    """What a run's manifest says about how it ended, as far as the analysis cares."""

    COMPLETED = "completed"
    UNFINISHED = "unfinished"  # running (killed), crashed or aborted
    MISSING = "no manifest"
    UNREADABLE = "unreadable manifest"


@dataclass(frozen=True)
class LoadedTrial:
    """One trial row with the run it came from."""

    subject: str
    session: str
    run: int
    source: Path
    record: TrialRecord


@dataclass(frozen=True)
class LoadedRun:
    """One run's rows and what its manifest says.

    ``status`` is the manifest's own word (``completed``, ``aborted``...) or the
    `ManifestState` text when there is none to read; ``duplicates`` are the trial numbers
    that had more than one ``ok`` row (only the first is kept in ``records``).
    """

    paths: RunPaths
    source: Path
    state: ManifestState
    status: str
    records: tuple[TrialRecord, ...]
    duplicates: tuple[int, ...] = ()

    @property
    def label(self) -> str:
        p = self.paths
        return f"sub-{p.subject} ses-{p.session} task-{p.task} run-{p.run}"

    @property
    def counted(self) -> int:
        """How many of its rows the analysis would count (main trials with status ok)."""
        return sum(r.counts for r in self.records)

    @property
    def incomplete_reason(self) -> str | None:
        """Why the run is left out by default, or None when it counts."""
        if self.state is ManifestState.UNFINISHED:
            return f"manifest says {self.status}"
        if self.state is ManifestState.UNREADABLE:
            return f"manifest unreadable ({self.status})"
        if not self.counted:
            return "no counted trials"
        return None

    def trials(self) -> list[LoadedTrial]:
        return [LoadedTrial(self.paths.subject, self.paths.session, self.paths.run, self.source,
                            record) for record in self.records]


@dataclass(frozen=True)
class RunSelection:
    """The runs that count, the runs left out (with why), and whether incomplete ones count."""

    included: tuple[LoadedRun, ...]
    excluded: tuple[LoadedRun, ...]
    include_incomplete: bool

    @property
    def trials(self) -> list[LoadedTrial]:
        return [trial for run in self.included for trial in run.trials()]

    @property
    def incomplete_included(self) -> tuple[LoadedRun, ...]:
        return tuple(r for r in self.included if r.incomplete_reason is not None)

    @property
    def without_manifest(self) -> tuple[LoadedRun, ...]:
        return tuple(r for r in self.included if r.state is ManifestState.MISSING)


def find_beh_files(paths: Iterable[Path | str]) -> list[Path]:
    """``beh.tsv`` files named directly or found below the named folders, each once, sorted."""
    paths = list(paths)
    found: set[Path] = set()
    for given in paths:
        path = Path(given)
        if path.is_dir():
            found.update(p for p in path.rglob(BEH_PATTERN) if p.is_file())
        elif path.is_file():
            found.add(path)
        else:
            raise ResultsError(f"{path}: no such results file or folder")
    if not found:
        names = ", ".join(str(p) for p in paths)
        raise ResultsError(f"no {BEH_PATTERN} files found in {names}")
    return sorted(found, key=lambda p: str(p.resolve()))


def first_ok_rows(records: Sequence[TrialRecord]) -> tuple[list[TrialRecord], list[int]]:
    """The rows with every trial finished at most once, and the trial numbers finished twice.

    The first ``ok`` row of a (trial, practice) pair is the one the subject answered in the
    run's own order; a later one can only come from a second writer or a hand edit.
    """
    seen: set[tuple[int, bool]] = set()
    kept, twice = [], []
    for record in records:
        key = (record.trial, record.practice)
        if record.status is TrialStatus.OK:
            if key in seen:
                twice.append(record.trial)
                continue
            seen.add(key)
        kept.append(record)
    return kept, sorted(set(twice))


def load_run(beh: Path) -> LoadedRun:
    """One run: its whole rows (torn last row left out) and its manifest's verdict."""
    paths = RunPaths.from_file(beh)
    records, duplicates = first_ok_rows(read_trials(beh))
    manifest = paths.manifest_on_disk()
    if manifest is None:
        state, status = ManifestState.MISSING, ManifestState.MISSING.value
    else:
        try:
            status = read_manifest(manifest).status
            state = (ManifestState.COMPLETED if status == "completed"
                     else ManifestState.UNFINISHED)
        except ResultsError as problem:
            state, status = ManifestState.UNREADABLE, str(problem)
    return LoadedRun(paths, beh, state, status, tuple(records), tuple(duplicates))


def load_runs(paths: Iterable[Path | str]) -> list[LoadedRun]:
    """Every run under ``paths``, sorted by file."""
    return [load_run(beh) for beh in find_beh_files(paths)]


def select_runs(runs: Iterable[LoadedRun], include_incomplete: bool = False) -> RunSelection:
    """Split runs into those that count and those left out.

    Incomplete runs (see `LoadedRun.incomplete_reason`) are left out unless
    ``include_incomplete``; a run with no counted trial is left out either way, since it
    would add a subject who answered nothing.
    """
    included, excluded = [], []
    for run in runs:
        reason = run.incomplete_reason
        if reason is None or (include_incomplete and run.counted):
            included.append(run)
        else:
            excluded.append(run)
    return RunSelection(tuple(included), tuple(excluded), include_incomplete)


def load_results(paths: Iterable[Path | str]) -> list[LoadedTrial]:
    """Every row of every run under ``paths`` (each finished trial once), whatever its state."""
    return [trial for run in load_runs(paths) for trial in run.trials()]
