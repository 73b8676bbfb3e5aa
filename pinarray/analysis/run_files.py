"""Which files are runs: each ``beh.tsv`` found once, copies of a run's files passed over.

A results folder is a BIDS dataset: a run's rows are at ``sub-<id>/ses-<n>/beh/`` under the
name that says its subject, session, task and run. A lab copies folders (a file manager's
``sub-01 copy``, a ``beh.bak``, a ``ses-1_old``) and links them; none of those is another run.
A ``beh.tsv`` found in a folder search is passed over, and said, when it lies in a BIDS
folder tree but not at its own place (one of the folders on its way is named ``sub-``,
``ses-`` or ``beh...``, and they are not its run's). One file reached twice (a link to it, a
folder linked into the dataset, the dataset named twice through a link) is read once. What
two copies of one run at their own places share (the same time zero, the same rows) is for
`pinarray.analysis.load.scan` to find; a file named directly is always read.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.journal.paths import RunPaths
from pinarray.text_files import kind_of

BEH_PATTERN = "*_beh.tsv"
BIDS_FOLDERS = ("sub-", "ses-", "beh")  # how a BIDS tree's folders start


@dataclass(frozen=True)
class FoundFiles:
    """The ``beh.tsv`` files to read, sorted, and one line for each file passed over (why)."""

    files: tuple[Path, ...]
    passed_over: tuple[str, ...]


def found_files(paths: Iterable[Path | str]) -> FoundFiles:
    """``beh.tsv`` files named directly or found below the named folders, each once."""
    paths = list(paths)
    found: list[Path] = []
    passed_over: list[str] = []
    for given in paths:
        path = Path(given)
        if path.is_dir():
            # Every name a run's rows go by, whatever it is: a folder or a FIFO under that
            # name is a run whose rows cannot be read (`load_run` says so), not nothing.
            for beh in sorted(path.rglob(BEH_PATTERN)):
                misplaced = _misplaced(beh, path)
                if misplaced:
                    passed_over.append(misplaced)
                else:
                    found.append(beh)
        elif path.is_file():
            found.append(path)
        elif path.exists():
            raise ResultsError(f"{path}: expected a results file or folder, found "
                               f"{kind_of(path.stat().st_mode)}")
        else:
            raise ResultsError(f"{path}: no such results file or folder")
    if not found and not passed_over:
        names = ", ".join(str(p) for p in paths)
        raise ResultsError(f"no {BEH_PATTERN} files found in {names}")
    reached: dict[str, list[Path]] = {}
    for beh in found:
        reached.setdefault(os.path.realpath(beh), []).append(beh)
    files = []
    for real, ways in sorted(reached.items()):
        # The file's own path first, where it was reached by it; else the first way in.
        first, *others = sorted(ways, key=lambda p: (os.path.abspath(p) != real, str(p)))
        files.append(first)
        for other in {os.path.abspath(p): p for p in others}.values():
            if os.path.abspath(other) != os.path.abspath(first):
                passed_over.append(f"{other}: the same file as {first} (reached through a "
                                   "link); read once")
    return FoundFiles(tuple(files), tuple(passed_over))


def at_its_place(paths: RunPaths, path: Path) -> bool:
    """Whether ``path`` lies in the run's own folder, ``sub-<id>/ses-<n>/beh/`` below any
    root: a copy of one of its files in another folder (``sub-01 copy``, ``beh.bak``) does
    not, and the run's manifest is not that copy's."""
    return path.parent.parts[-3:] == paths.relative_dir.parts


def _misplaced(beh: Path, searched: Path) -> str | None:
    """Why ``beh``, found below ``searched``, is a copy of a run's file and no run; None when
    it lies at its run's place or outside any BIDS tree (a flat folder of files)."""
    try:
        paths = RunPaths.from_file(beh)
    except ResultsError:
        return None  # no run's name: `load_run` says so
    if at_its_place(paths, beh):
        return None
    between = beh.relative_to(searched).parts[:-1]
    if not any(part.startswith(BIDS_FOLDERS) for part in between):
        return None
    return (f"{beh}: passed over: a file of {paths.label} belongs in {paths.relative_dir}/, "
            f"not in {Path(*between[-3:])}/ (a copy?); rename or remove the copy")


def raw_data_holding(folder: Path, roots: Iterable[Path]) -> str | None:
    """Why ``folder`` (a report's) is inside the raw data of one of the datasets ``roots``:
    the dataset's own folder, a subject's folder or ``sourcedata/`` below it (where a report
    would lie beside the runs' files, and later analyses would pass it over); None when it
    is not. A BIDS dataset keeps what is made from it in ``derivatives/``."""
    where = Path(os.path.realpath(folder))
    for root in {Path(os.path.realpath(r)) for r in roots}:
        if where == root:
            return f"the dataset {root} itself"
        if where.is_relative_to(root):
            top = where.relative_to(root).parts[0]
            if top.startswith("sub-") or top == "sourcedata":
                return f"{top}/ of the dataset {root}"
    return None
