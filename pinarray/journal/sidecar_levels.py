"""A run's rows checked against its sidecar when its manifest is not there.

A BIDS dataset is often shared without ``sourcedata/``, where the manifests live; the run's
``_beh.json`` sidecar still says every level a column of that run may hold (`Levels`: the
task, the answers the design offered, each pattern with its pins, the pins of the grid...).
Read back without the manifest, every row is checked against them as `check_run` checks it
against the manifest: a cell the sidecar gives levels for holds one of them, the paradigm's
own rows say what else its levels fix (identification: a pattern's pins), and a row marked
practice is in block 0 (the practice block), a main trial in a later one. A run with neither
its manifest nor a sidecar that can be read cannot be checked at all, nor can one whose
sidecar lacks the Levels its paradigm's design needs (`missing_levels`: identification's
patterns, temporal order's SOAs, two intervals' compared parameter, standards and
comparisons): the analysis does not count it (`pinarray.analysis.load`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.journal.columns import NA
from pinarray.journal.files import read_results_json, results_file
from pinarray.journal.records import TrialRecord
from pinarray.journal.rows import trial_row
from pinarray.journal.seam import rows_of

Levels = Mapping[str, Mapping[str, str]]
SHOWN_LEVELS = 12  # a message lists at most this many levels


@dataclass(frozen=True)
class Sidecar:
    """What a run's ``_beh.json`` says that its rows are checked against: every column's
    ``Levels`` (by column) and when the run's time zero was on the wall clock (its
    ``TimeBase.ZeroAt``; empty when it does not say)."""

    levels: dict[str, dict[str, str]]
    zero_at: str = ""


def read_sidecar(path: Path) -> Sidecar | None:
    """The sidecar at ``path`` (None: no sidecar there); a `ResultsError` saying where when it
    is there but is no sidecar."""
    if not results_file(path, "sidecar"):
        return None
    data = read_results_json(path, "sidecar")
    if not isinstance(data, dict):
        raise ResultsError(f"{path}: expected a JSON object (a BIDS sidecar), found "
                           f"{type(data).__name__}")
    time_base = data.get("TimeBase")
    zero_at = time_base.get("ZeroAt") if isinstance(time_base, dict) else None
    levels: dict[str, dict[str, str]] = {}
    for name, described in data.items():
        if not isinstance(described, dict) or "Levels" not in described:
            continue
        found = described["Levels"]
        if not isinstance(found, dict) or not all(isinstance(v, str) for v in found.values()):
            raise ResultsError(f"{path}: expected the Levels of {name!r} as level: meaning "
                               f"pairs, found {found!r:.80}")
        levels[name] = {str(level): meaning for level, meaning in found.items()}
    if "task" not in levels or "response" not in levels:
        raise ResultsError(f"{path}: expected the Levels of 'task' and 'response' (a run's "
                           "sidecar names its task and the answers it offered), found none")
    return Sidecar(levels, zero_at if isinstance(zero_at, str) else "")


def missing_levels(records: Sequence[TrialRecord], levels: Levels) -> tuple[str, ...]:
    """The columns whose Levels the rows' paradigms need to be checked (their design's
    values: identification's patterns, temporal order's SOAs, two intervals' standards...)
    and ``levels`` does not give: a run whose sidecar lacks them cannot be checked."""
    needed = {name: None for record in records
              for name in getattr(rows_of(record.paradigm), "sidecar_needs", ())}
    return tuple(name for name in needed if name not in levels)


def check_against_sidecar(path: Path | str, records: Sequence[TrialRecord], levels: Levels,
                          sidecar: Path) -> None:
    """Every row holds, in each column ``levels`` names, one of its levels, and what its
    paradigm ties to them (`RowsDefaults.check_levels`); a `ResultsError` naming the first
    row that does not (row ``i`` is line ``i + 2``)."""
    for number, record in enumerate(records, start=2):
        where = f"{path}:{number}: trial {record.trial}"
        if record.practice != (record.block == 0):
            raise ResultsError(f"{where}: practice is {str(record.practice).lower()} in block "
                               f"{record.block} (block 0 is the practice, blocks from 1 the "
                               "main trials)")
        rows = rows_of(record.paradigm)
        for name, cell in zip(rows.layout, trial_row(record, rows), strict=True):
            allowed = levels.get(name)
            if cell == NA or allowed is None or cell in allowed:
                continue
            shown = ", ".join(list(allowed)[:SHOWN_LEVELS])
            more = " ..." if len(allowed) > SHOWN_LEVELS else ""
            raise ResultsError(f"{where}: expected a {name} the run's sidecar {sidecar.name} "
                               f"lists ({shown}{more}), found {cell!r}")
        tied = getattr(rows, "check_levels", None)  # optional: RowsDefaults has it
        problem = tied(record, levels) if tied is not None else None
        if problem:
            raise ResultsError(f"{where}: {problem} (the run's sidecar {sidecar.name})")
