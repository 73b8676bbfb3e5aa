"""Results read back for a script's own analysis: the runs a sitting wrote, as the analysis
reads them (``pinarray analyse``), one frozen record per row (each paradigm's type of its own:
`pinarray.api.paradigms`)."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

from pinarray.analysis.load import LoadedRun, ManifestState, load_runs
from pinarray.api import arguments
from pinarray.journal.paths import RunPaths
from pinarray.journal.records import TrialRecord, TrialStatus

__all__ = ["LoadedRun", "ManifestState", "RunPaths", "TrialRecord", "TrialStatus",
           "read_results"]


def read_results(*paths: str | PathLike[str]) -> tuple[LoadedRun, ...]:
    """Every run found in the results files and folders named.

    Parameters
    ----------
    *paths : str or path-like
        ``*_beh.tsv`` files, or folders searched below for them (a whole ``results/``).

    Returns
    -------
    tuple of LoadedRun
        One per run, sorted by path, each once (copies and links of its files passed over,
        as ``pinarray analyse`` passes them over): its rows (a torn last row left out, a trial finished
        twice kept once), its manifest's status and the planned trials with no row.

    Raises
    ------
    ResultsError
        A path that does not exist, no results found, or a file that is not a results table
        (`DamagedResults`, naming the file, line and reason).
    """
    checked = arguments.paths("read_results", paths)
    return tuple(load_runs(Path(path) for path in checked))
