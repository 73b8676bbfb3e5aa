"""Find and read runs: the analysis reads result files (rows and manifests) and nothing else.

A run is one ``beh.tsv`` with its manifest (in ``sourcedata/``, or beside it for runs written
before the manifests moved there). Which runs count is decided here, once:
a run whose manifest does not say ``completed``, or that holds no counted trial (a main
trial with status ok), is *incomplete*; incomplete runs are listed and left out unless the
caller asks for them. A run with no manifest (a dataset shared without ``sourcedata/``)
cannot be judged complete and is counted, with a note, its rows checked against the levels
its ``_beh.json`` sidecar gives (the task, the answers offered, each pattern's pins:
`pinarray.journal.sidecar_levels`); one with neither (a ``beh.tsv`` handed over on its own)
cannot be checked at all and is not counted, even on request. A run whose rows finish a
trial twice (two ``ok`` rows for one trial number: a second writer before runs were locked,
or a hand edit) is damaged: which answer counts is for a person to say, as a resume refuses
it too.

Files are not trusted to be what their names say. A ``beh.tsv`` that is not a results table
(binary, another encoding, a wrong header, a row that does not parse) is *damaged*: it is
named with the line and the reason, and the analysis stops unless asked to go on without
it. One that was cut short is not damaged but incomplete: a torn last row is left out and
said, and a run whose manifest says ``completed`` while planned trials have no finished row
is left out like any unfinished run, with the trials that are missing (those with no row,
and apart from them those whose rows are there but none ``ok``: an edit, not a cut).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from pinarray.analysis.copies import Claim, judged
from pinarray.analysis.run_files import at_its_place, found_files
from pinarray.errors import ResultsError
from pinarray.journal.files import results_file
from pinarray.journal.manifest import RunManifest, read_manifest, remaining_plan
from pinarray.journal.paths import RunPaths
from pinarray.journal.records import LEGACY_LAYOUT, TrialRecord
from pinarray.journal.rows import (
    beh_header,
    check_finished_once,
    check_run,
    read_trials,
    results_bytes,
    split_torn_tail,
)
from pinarray.journal.sidecar_levels import (
    Sidecar,
    check_against_sidecar,
    missing_levels,
    read_sidecar,
)


class DamagedResults(ResultsError):
    """Results files that are not results tables: one ``FILE[:LINE]: why`` line each."""

    def __init__(self, damaged: Sequence[DamagedRun]):
        self.damaged = tuple(damaged)
        super().__init__("\n".join(d.reason for d in self.damaged))


@dataclass(frozen=True)
class DamagedRun:
    """A ``beh.tsv`` that could not be read, and why (``FILE[:LINE[:COL]]: reason``)."""

    source: Path
    reason: str


class ManifestState(StrEnum):
    """What a run's manifest says about how it ended, as far as the analysis cares."""

    COMPLETED = "completed"
    UNFINISHED = "unfinished"  # running (killed), crashed or aborted
    MISSING = "no manifest"  # the rows checked against the sidecar's levels
    UNCHECKED = "no manifest or sidecar"  # neither there, or the sidecar unreadable
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

    ``paths`` are the run's files (`RunPaths`: ``beh_tsv``, ``events_tsv``, ``manifest``),
    ``source`` the rows' file as found; ``state`` is the manifest's verdict for the analysis
    (`ManifestState`). ``status`` is the manifest's own word (``completed``, ``aborted``...) or the
    `ManifestState` text when there is none to read; ``duplicates`` is empty (a run whose
    rows finish a trial twice is refused as damaged since 0.5.2; scripts that build a
    `LoadedRun` may still name such trials); ``torn`` is
    the text of a last row cut short by an interrupted write (left out); ``unfinished`` the
    planned trials with no finished row; ``mm_per_step`` each pin's travel per step as the
    manifest records it (empty where it does not).
    """

    paths: RunPaths
    source: Path
    state: ManifestState
    status: str
    records: tuple[TrialRecord, ...]
    duplicates: tuple[int, ...] = ()
    torn: str = ""
    unfinished: tuple[int, ...] = ()
    mm_per_step: tuple[float, ...] = ()

    @property
    def label(self) -> str:
        """The run in words: ``sub-01 ses-1 task-localisation run-2``."""
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
            return (f"manifest unreadable ({self.status}): its rows cannot be checked against "
                    "the run's plan and the answers it offered, so it is not counted, even "
                    "with --include-incomplete")
        if self.state is ManifestState.UNCHECKED:
            return (f"{self.status}: its rows cannot be checked against the design the run "
                    "offered, so it is not counted, even with --include-incomplete (keep its "
                    "manifest in sourcedata/, or its _beh.json beside it)")
        if self.state is ManifestState.COMPLETED and self.unfinished:
            return f"manifest says completed, but {self._unfinished_words()}"
        if not self.counted:
            return "no counted trials"
        return None

    def _unfinished_words(self) -> str:
        """The planned trials without an ``ok`` row, as found: those with no row at all (a
        file cut short), and those whose rows are all something else (a row set to
        ``invalid`` by hand is there, not cut)."""
        statuses: dict[int, set[str]] = {}
        for record in self.records:
            if record.trial in self.unfinished:
                statuses.setdefault(record.trial, set()).add(record.status.value)
        missing = [t for t in self.unfinished if t not in statuses]
        parts = []
        if missing:
            parts.append(f"trial(s) {_shown(missing)} have no finished row (the file was cut "
                         "short?)")
        if statuses:
            found = ", ".join(sorted(set().union(*statuses.values())))
            parts.append(f"trial(s) {_shown(sorted(statuses))} have rows but none with status "
                         f"ok (found {found}; edited by hand?)")
        return "; ".join(parts)

    def trials(self) -> list[LoadedTrial]:
        """Each row with the run it came from (subject, session, run, file)."""
        return [LoadedTrial(self.paths.subject, self.paths.session, self.paths.run, self.source,
                            record) for record in self.records]


def _shown(trials: Sequence[int]) -> str:
    """Trial numbers in a line: the first ten, then " ..."."""
    return ", ".join(map(str, trials[:10])) + (" ..." if len(trials) > 10 else "")


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
    """The ``beh.tsv`` files to read below ``paths`` (`pinarray.analysis.run_files`)."""
    return list(found_files(paths).files)


def load_run(beh: Path) -> LoadedRun:
    """One run: its whole rows (torn last row left out) and its manifest's verdict.

    With its manifest, every row is read as the run's paradigm writes it and checked against
    the run (`pinarray.journal.rows.check_run`: its task, its plan, the answers offered).
    Raises `DamagedResults` for a file that is not a results table, or whose rows are not the
    run's.
    """
    return _identified_run(beh)[0]


def _identified_run(beh: Path) -> tuple[LoadedRun, Claim]:
    """`load_run`'s run, and what tells it from its copies (`pinarray.analysis.copies`)."""
    manifest: RunManifest | None = None
    unfinished: tuple[int, ...] = ()
    mm_per_step: tuple[float, ...] = ()
    try:
        paths = RunPaths.from_file(beh)
        # Looked at, never opened, through a link: a FIFO would wait for a writer for ever.
        if not results_file(beh):
            raise ResultsError(f"{beh}: no such results file")
    except (ResultsError, ValueError) as problem:
        raise DamagedResults([DamagedRun(beh, _reason(beh, problem))]) from None
    # A copy of the run's file in another folder, or under another spelling of its name
    # (``run-01``), is not the run its manifest describes.
    manifest_path = (paths.manifest_on_disk()
                     if at_its_place(paths, beh) and beh.name == paths.beh_tsv.name else None)
    sidecar = beh.with_name(beh.name.removesuffix(".tsv") + ".json")  # beside it, as found
    said: Sidecar | None = None
    zero_at = ""
    if manifest_path is None:
        state, status = ManifestState.MISSING, ManifestState.MISSING.value
        try:
            said = read_sidecar(sidecar)
            if said is None:
                state, status = ManifestState.UNCHECKED, f"no manifest and no sidecar {sidecar}"
        except (ResultsError, UnicodeDecodeError) as problem:
            state, status = ManifestState.UNCHECKED, (
                f"no manifest, and its sidecar unreadable ({' '.join(str(problem).split())})")
    else:
        try:
            manifest = read_manifest(manifest_path)
            status = manifest.status
            state = (ManifestState.COMPLETED if status == "completed"
                     else ManifestState.UNFINISHED)
            mm_per_step = manifest.task_info.mm_per_step
        except (ResultsError, UnicodeDecodeError) as problem:
            state, status = ManifestState.UNREADABLE, " ".join(str(problem).split())
    if manifest is not None:
        _check_names_the_run(beh, paths, manifest_path, manifest)
        zero_at = "" if manifest.time_zero is None else manifest.time_zero.at
    elif said is not None:
        zero_at = said.zero_at
    try:
        torn, rows = _check_table(beh)
        all_records = read_trials(beh, None if manifest is None
                                  else manifest.task_info.paradigm)
        if manifest is not None:
            check_run(beh, all_records, manifest)
        elif said is not None:
            check_against_sidecar(beh, all_records, said.levels, sidecar)
            lacking = missing_levels(all_records, said.levels)
            if lacking:
                state, status = ManifestState.UNCHECKED, (
                    f"no manifest, and its sidecar {sidecar.name} gives no Levels of "
                    f"{', '.join(lacking)} (the design's values its rows must hold)")
        check_finished_once(beh, all_records)
    except (ResultsError, ValueError) as problem:  # ValueError: a decode error
        raise DamagedResults([DamagedRun(beh, _reason(beh, problem))]) from None
    if manifest is not None:
        unfinished = tuple(e.trial for e in remaining_plan(manifest.needed, all_records))
    run = LoadedRun(paths, beh, state, status, tuple(all_records), (), torn, unfinished,
                    mm_per_step)
    return run, Claim(beh, run.label, manifest_path is not None, zero_at, rows)


def _check_names_the_run(beh: Path, paths: RunPaths, manifest_path: Path | None,
                         manifest: RunManifest) -> None:
    """`DamagedResults` unless the manifest is the run's that the file's name says (a copy
    renamed to another subject, session or run keeps the manifest of the run it copies)."""
    try:
        itself = RunPaths(paths.root, manifest.subject, manifest.session, manifest.task,
                          manifest.run)
    except ResultsError as problem:
        raise DamagedResults([DamagedRun(beh, f"{manifest_path}: {problem}")]) from None
    if itself != paths:
        raise DamagedResults([DamagedRun(beh, (
            f"{beh}: its manifest {manifest_path} says it is {itself.label}, the file's name "
            f"says {paths.label} (a copy of another run, renamed?); keep each run under its "
            "own name, or remove the copy"))])


def _reason(beh: Path, problem: Exception) -> str:
    reason = " ".join(str(problem).split())
    return reason if reason.startswith(str(beh)) else f"{beh}: {reason}"


def _check_table(beh: Path) -> tuple[str, tuple[str, ...]]:
    """A `ResultsError` unless ``beh`` is UTF-8 text of a readable size; the torn last row's
    text, and the whole rows' lines, line ends aside (what a copy of the run holds)."""
    data = results_bytes(beh)
    end, torn = split_torn_tail(data, len(beh_header(beh)) or len(LEGACY_LAYOUT))
    rows = data[:end].decode("utf-8", errors="replace").splitlines()
    return torn.decode("utf-8", errors="replace"), tuple(rows)


@dataclass(frozen=True)
class Scan:
    """What a search for results found: the runs read, the files that cannot be, and one
    line for each file or run passed over (a copy, a link to a file already read)."""

    runs: tuple[LoadedRun, ...]
    damaged: tuple[DamagedRun, ...]
    passed_over: tuple[str, ...]


def scan(paths: Iterable[Path | str]) -> Scan:
    """Every run under ``paths`` that can be read (each once), and every results file that
    cannot. Files that claim one run (its time zero, or its subject, session, task and run
    where nothing gives the time zero) are that run and its copies: the run is read, and
    each copy passed over and named (`pinarray.analysis.copies`); where nothing tells which
    is the run, both are refused as damaged, in one line."""
    found = found_files(paths)
    read: list[LoadedRun] = []
    claims: list[Claim] = []
    damaged: list[DamagedRun] = []
    for beh in found.files:
        try:
            run, claim = _identified_run(beh)
        except DamagedResults as problem:
            damaged.extend(problem.damaged)
            continue
        read.append(run)
        claims.append(claim)
    verdict = judged(claims)
    for line, left_out in verdict.refused:
        damaged.append(DamagedRun(read[left_out[0]].source, line))
    return Scan(tuple(read[i] for i in verdict.runs), tuple(damaged),
                (*found.passed_over, *verdict.passed_over))


def scan_runs(paths: Iterable[Path | str]) -> tuple[list[LoadedRun], list[DamagedRun]]:
    """Every run under ``paths`` that can be read (each once), and every results file that
    cannot (`scan`)."""
    found = scan(paths)
    return list(found.runs), list(found.damaged)


def load_runs(paths: Iterable[Path | str]) -> list[LoadedRun]:
    """Every run under ``paths``, sorted by file; `DamagedResults` names every damaged file."""
    runs, damaged = scan_runs(paths)
    if damaged:
        raise DamagedResults(damaged)
    return runs


def countable_on_request(run: LoadedRun) -> bool:
    """Whether ``--include-incomplete`` counts ``run``: one with counted trials, but not one
    whose manifest cannot be read (rows edited by hand, an answer never offered or a pattern
    that is not the plan's, pass every check a row makes on its own: only the manifest says
    what they must be), nor one with neither manifest nor sidecar (nothing says it)."""
    return bool(run.counted) and run.state not in (ManifestState.UNREADABLE,
                                                   ManifestState.UNCHECKED)


def select_runs(runs: Iterable[LoadedRun], include_incomplete: bool = False) -> RunSelection:
    """Split runs into those that count and those left out.

    Incomplete runs (see `LoadedRun.incomplete_reason`) are left out unless
    ``include_incomplete``; a run with no counted trial is left out either way, since it
    would add a subject who answered nothing, and so is one whose manifest cannot be read,
    since its rows cannot be checked against the run.
    """
    included, excluded = [], []
    for run in runs:
        reason = run.incomplete_reason
        if reason is None or (include_incomplete and countable_on_request(run)):
            included.append(run)
        else:
            excluded.append(run)
    return RunSelection(tuple(included), tuple(excluded), include_incomplete)


def load_results(paths: Iterable[Path | str]) -> list[LoadedTrial]:
    """Every row of every run under ``paths`` (each finished trial once), whatever its state."""
    return [trial for run in load_runs(paths) for trial in run.trials()]
