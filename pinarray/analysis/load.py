"""Find and read ``beh.tsv`` files: the analysis reads result files and nothing else."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.manifest import RunPaths
from pinarray.results import TrialRecord, read_trials

BEH_PATTERN = "*_beh.tsv"


@dataclass(frozen=True)
class LoadedTrial:
    """One trial row with the run it came from."""

    subject: str
    session: str
    run: int
    source: Path
    record: TrialRecord


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


def load_results(paths: Iterable[Path | str]) -> list[LoadedTrial]:
    """Every row of every ``beh.tsv`` under ``paths``; subject and session come from the names."""
    loaded = []
    for beh in find_beh_files(paths):
        run = RunPaths.from_file(beh)
        loaded.extend(LoadedTrial(run.subject, run.session, run.run, beh, record)
                      for record in read_trials(beh))
    return loaded
