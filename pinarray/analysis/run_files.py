"""Which files are runs: each ``beh.tsv`` found once, copies of a run's files passed over.

A results folder is a BIDS dataset (it holds ``dataset_description.json``): its raw runs are
under the ``sub-<label>/`` folders at its root, each run's rows at ``sub-<id>/ses-<n>/beh/``
under the name that says its subject, session, task and run. ``sourcedata/``,
``derivatives/`` and any other folder at the root (a ``backup/``) are not raw data and are
never searched; a run whose manifest is in ``sourcedata/`` while its rows are gone is said.
Folders linked in (a subject's data on another disk) are followed, once. A lab copies
folders (a file manager's ``sub-01 copy``, a ``beh.bak``, a ``ses-1_old``) and links them;
none of those is another run. A ``beh.tsv`` found in a folder search is passed over, and said,
when it is hidden (a name on its way starts with ``.``: macOS's ``._`` files) or lies in a BIDS
folder tree but not at its own place (one of the folders on its way is named ``sub-``,
``ses-`` or ``beh...``, and they are not its run's). One file reached twice (a link to it, a
folder linked into the dataset, the dataset named twice through a link) is read once, by
its own place's path. What two copies of one run at their own places share (the time zero,
the labels) is for `pinarray.analysis.copies` to judge; a file named directly is always read.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from fnmatch import fnmatchcase
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.journal.paths import SOURCEDATA, RunPaths
from pinarray.text_files import kind_of

BEH_PATTERN = "*_beh.tsv"
BIDS_FOLDERS = ("sub-", "ses-", "beh")  # how a BIDS tree's folders start
DATASET_DESCRIPTION = "dataset_description.json"  # what makes a folder a BIDS dataset


@dataclass(frozen=True)
class FoundFiles:
    """The ``beh.tsv`` files to read, sorted, and one line for each file passed over (why)."""

    files: tuple[Path, ...]
    passed_over: tuple[str, ...]


def found_files(paths: Iterable[Path | str]) -> FoundFiles:
    """``beh.tsv`` files named directly or found below the named folders, each once."""
    paths = list(paths)
    candidates: list[tuple[Path, str | None]] = []  # each with why it is no run, or None
    passed_over: list[str] = []
    for given in paths:
        path = Path(given)
        if path.is_dir():
            # Every name a run's rows go by, whatever it is: a folder or a FIFO under that
            # name is a run whose rows cannot be read (`load_run` says so), not nothing.
            candidates.extend((beh, _not_a_run(beh, path))
                              for beh in _searched(path, passed_over))
        elif path.is_file():
            candidates.append((path, None))
        elif path.exists():
            raise ResultsError(f"{path}: expected a results file or folder, found "
                               f"{kind_of(path.stat().st_mode)}")
        else:
            raise ResultsError(f"{path}: no such results file or folder")
    if not candidates and not passed_over:
        names = ", ".join(str(p) for p in paths)
        raise ResultsError(f"no {BEH_PATTERN} files found in {names}")
    reached: dict[str, list[tuple[Path, str | None]]] = {}
    for beh, why_not in candidates:
        reached.setdefault(os.path.realpath(beh), []).append((beh, why_not))
    files = []
    for real, ways in sorted(reached.items()):
        # A way that is a run's before one that is not; then the file's own path, where it was
        # reached by it; else the first way in.
        (first, why_not), *others = sorted(ways, key=lambda w: (
            w[1] is not None, os.path.abspath(w[0]) != real, str(w[0])))
        if why_not is None:
            files.append(first)
        else:
            passed_over.append(why_not)
        for other in {os.path.abspath(p): p for p, _ in others}.values():
            if os.path.abspath(other) != os.path.abspath(first):
                passed_over.append(f"{other}: the same file as {first} (reached through a "
                                   "link); read once")
    return FoundFiles(tuple(sorted(files)), tuple(passed_over))


def _not_a_run(beh: Path, searched: Path) -> str | None:
    """Why ``beh``, found below ``searched``, is no run's file (hidden, or a copy's), or None."""
    hidden = next((part for part in beh.relative_to(searched).parts if part.startswith(".")),
                  None)
    if hidden is not None:
        return (f"{beh}: passed over: a hidden file ({hidden!r} starts with '.', as the "
                "leftovers of a copy do, such as macOS's ._ files), not a run")
    return _misplaced(beh, searched)


def is_dataset(folder: Path) -> bool:
    """Whether ``folder`` is a BIDS dataset's root (it holds ``dataset_description.json``)."""
    return (folder / DATASET_DESCRIPTION).is_file()


def _searched(folder: Path, said: list[str]) -> list[Path]:
    """Every ``beh.tsv`` name below ``folder``, sorted, folders linked in followed once each.
    In a dataset's root only the ``sub-`` folders hold raw data (BIDS): ``sourcedata/``,
    ``derivatives/`` and any other folder there (a backup) are not searched; a run whose
    manifest is there while its ``beh.tsv`` is not is said in ``said``."""
    found: list[Path] = []
    for top, folders, files in os.walk(folder, followlinks=True):
        here = Path(top)
        real = os.path.realpath(here)
        if any(os.path.realpath(up) == real for up in _between(folder, here)):
            folders.clear()  # a link back up the tree: its folders are searched once
            continue
        if is_dataset(here):
            folders[:] = [f for f in folders if f.startswith("sub-")]
            said.extend(_rows_missing(here))
        found.extend(here / name for name in (*files, *folders)
                     if fnmatchcase(name, BEH_PATTERN))
    return sorted(found)


def _between(folder: Path, below: Path) -> list[Path]:
    """The folders from ``folder`` down to ``below``'s parent."""
    parts = below.relative_to(folder).parts
    return [folder.joinpath(*parts[:n]) for n in range(len(parts))]


def _rows_missing(root: Path) -> list[str]:
    """One line for each run of the dataset ``root`` whose manifest is in ``sourcedata/`` while
    its ``beh.tsv`` is not at its place (a subject's folder moved, deleted or linked to a
    disk that is not there)."""
    lines = []
    for manifest in sorted((root / SOURCEDATA).glob("sub-*/ses-*/beh/*_manifest.json")):
        try:
            paths = RunPaths.from_file(manifest)
        except ResultsError:
            continue
        if paths.manifest == manifest and not os.path.lexists(paths.beh_tsv):
            lines.append(f"{manifest}: the manifest of {paths.label}, but no {paths.beh_tsv} "
                         "(moved or deleted?): the run is not counted")
        elif paths.manifest == manifest and not os.path.exists(paths.beh_tsv):
            lines.append(f"{paths.beh_tsv}: the rows of {paths.label} cannot be reached (a "
                         "link to a file or disk that is not there?): the run is not counted")
    return lines


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
    """Why ``folder`` (a report's) is inside raw data: the dataset's own folder for one of the
    datasets ``roots`` analysed, or a subject's folder or ``sourcedata/`` of any dataset (those
    analysed, or another found by looking up for ``dataset_description.json``), where a report
    would lie beside runs' files and later analyses would pass it over; None when it is not. A
    BIDS dataset keeps what is made from it in ``derivatives/``."""
    where = Path(os.path.realpath(folder))
    analysed = {Path(os.path.realpath(r)) for r in roots}
    if where in analysed:
        return f"the dataset {where} itself"
    for root in [*analysed, *(up for up in where.parents if is_dataset(up))]:
        if where.is_relative_to(root) and where != root:
            top = where.relative_to(root).parts[0]
            if top.startswith("sub-") or top == SOURCEDATA:
                return f"{top}/ of the dataset {root}"
    return None
