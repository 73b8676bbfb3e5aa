"""A run's rows as tables: each record's cells written, and ``beh.tsv`` read back and checked.

A record's cells are the common ones every row has, its paradigm's
(`pinarray.journal.seam.ParadigmRows.cells`) and an adaptive design's, in the columns of its
paradigm's layout. Reading a file parses every cell by its column's type, makes each row's
record through its paradigm's room, and writes the record's cells again: a row whose cells
are not what its record would write (a derived cell such as ``correct`` edited by hand) is
refused, named by its line and column. Read with the run's manifest (`check_run`), each row
is also the run's task, one of its plan's trials presenting what the plan says, and answered
with an answer the design offered. This module only formats and parses, so the analysis reads
results without any writer code.

A process killed while writing leaves at most one torn last line (`split_torn_tail`); the
reader leaves it out.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pinarray.errors import PinArrayError, ResultsError
from pinarray.journal.columns import Column, cell_text, cell_value
from pinarray.journal.files import read_results_file, read_tsv, results_file
from pinarray.journal.records import (
    EVENT_ONLY,
    FIRST_NAMES,
    LEGACY_LAYOUT,
    RENAMED,
    TrialRecord,
    TrialStatus,
    adaptive_cells,
    common_cells,
    common_fields,
)
from pinarray.journal.seam import ParadigmRows, columns_of, legacy_rooms, rows_of
from pinarray.text_files import position_of

if TYPE_CHECKING:
    from pinarray.journal.manifest import RunManifest


def record_values(record: TrialRecord, rows: ParadigmRows) -> dict[str, Any]:
    """The record's cells as Python values (None for n/a), by column name."""
    return common_cells(record) | rows.cells(record) | adaptive_cells(record)


def _cells(values: Mapping[str, Any], names: Sequence[str], columns: Mapping[str, Column]
           ) -> list[str]:
    return [cell_text(columns.get(name) or EVENT_ONLY[name], values.get(name)) for name in names]


def trial_row(record: TrialRecord, rows: ParadigmRows | None = None) -> list[str]:
    """The ``beh.tsv`` cells of ``record``, in its paradigm's layout."""
    rows = rows or rows_of(record.paradigm)
    return _cells(record_values(record, rows), rows.layout, columns_of(rows))


def event_row(record: TrialRecord, rows: ParadigmRows | None = None) -> list[str]:
    """The ``events.tsv`` cells of ``record``, in its paradigm's event layout."""
    rows = rows or rows_of(record.paradigm)
    values = record_values(record, rows)
    values |= {"onset": values["stimulus_onset"], "duration": values["stimulus_duration"],
               "trial_type": rows.trial_type(record)}
    return _cells(values, rows.event_layout, columns_of(rows))


# -- reading -------------------------------------------------------------------------------------


def split_torn_tail(data: bytes, columns: int) -> tuple[int, bytes]:
    """Where the whole rows of a TSV end, and the torn bytes after them.

    A row is whole when it ends in a newline and has ``columns`` cells. Only the last row can
    be torn (rows are written one at a time, each fsync'd); zero bytes that a file system may
    leave after a power cut are torn too.
    """
    end = len(data.rstrip(b"\0"))
    end = data.rfind(b"\n", 0, end) + 1  # 0 when there is no whole line at all
    if end:
        start = data.rfind(b"\n", 0, end - 1) + 1
        last = data[start:end].decode("utf-8", errors="replace")
        try:
            cells = len(next(csv.reader([last], delimiter="\t")))
        except csv.Error:  # not a row at all: not torn but damaged, which reading it says
            cells = columns
        if start and cells != columns:
            end = start
    return end, data[end:]


def _regular(path: Path) -> bool:
    """Whether ``path`` is a regular file (`pinarray.journal.files.results_file`)."""
    return results_file(path)


def results_bytes(path: Path) -> bytes:
    """The bytes of a ``beh.tsv``: a regular file of UTF-8 text within
    `pinarray.journal.files.MAX_RESULTS_BYTES`
    (zeros after a power cut belong to its torn tail); else a `ResultsError` saying where."""
    data = read_results_file(path)
    body = data.rstrip(b"\0")
    if b"\0" in body:
        line, col = position_of(body, body.index(b"\0"))
        raise ResultsError(f"{path}:{line}:{col}: expected a tab-separated results table, "
                           "found a NUL byte (a binary file?)")
    try:
        body.decode("utf-8")
    except UnicodeDecodeError as problem:
        line, col = position_of(body, problem.start)
        raise ResultsError(f"{path}:{line}:{col}: expected UTF-8 text, found byte "
                           f"0x{body[problem.start]:02x}") from None
    return data


def beh_header(path: Path) -> list[str]:
    """The column names of an existing ``beh.tsv`` (empty if it has no header yet)."""
    if not _regular(path):
        return []
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            first = handle.readline(1 << 16)
    except FileNotFoundError:
        return []
    except UnicodeDecodeError:
        raise ResultsError(f"{path}:1: expected UTF-8 text in the header line") from None
    if not first.endswith("\n"):
        return []  # no header yet, or one torn by a crash (a resume drops it)
    return next(csv.reader([first], delimiter="\t"), []) if first.strip() else []


def todays_names(header: Sequence[str]) -> tuple[str, ...]:
    """A ``beh.tsv`` header with the columns an earlier pinarray named otherwise renamed."""
    return tuple(RENAMED.get(name, name) for name in header)


def is_legacy_prefix(names: Sequence[str]) -> bool:
    """Whether ``names`` are the first columns of the legacy layout (an earlier pinarray's
    file, which a resume gives the columns appended since)."""
    return tuple(names) == LEGACY_LAYOUT[: len(names)] and len(names) >= len(FIRST_NAMES)


def layout_rows(names: Sequence[str], paradigm: str | None,
                where: str) -> tuple[ParadigmRows | None, dict[str, Column]]:
    """Whose rows a file with columns ``names`` holds (None: the legacy layout's, told apart
    row by row) and its columns; a `ResultsError` at ``where`` when no paradigm writes them."""
    if paradigm is not None:
        rows = rows_of(paradigm)
        fits = (is_legacy_prefix(names) if rows.layout == LEGACY_LAYOUT
                else tuple(names) == rows.layout)
        if not fits:
            raise ResultsError(f"{where}:1: expected the columns {list(rows.layout)}, found "
                               f"{list(names)}")
        # An older layout's header is a prefix of today's, but it holds the paradigm's own
        # columns (its marker): a header cut before them is no file of its rows.
        if rows.marker not in names:
            raise ResultsError(f"{where}:1: expected the column {rows.marker!r} of a "
                               f"{rows.name} file, found the header ending at {names[-1]!r}")
        return rows, columns_of(rows)
    if is_legacy_prefix(names):
        found: dict[str, Column] = {}
        for rows in legacy_rooms():
            found |= columns_of(rows)
        return None, found
    from pinarray import registry

    # pinarray's own first: a lab's package that cannot be loaded hides none of their files,
    # and is named only when no other paradigm writes these columns (the file may be its).
    for name in registry.BUILT_IN:
        if tuple(names) == rows_of(name).layout:
            return rows_of(name), columns_of(rows_of(name))
    broken = []
    for name in registry.plug_ins():
        try:
            rows = rows_of(name)
        except PinArrayError as problem:
            broken.append(f"; {problem}")
            continue
        if tuple(names) == rows.layout:
            return rows, columns_of(rows)
    raise ResultsError(f"{where}:1: expected the columns {list(LEGACY_LAYOUT)} (or a "
                       f"paradigm's own), found {list(names)}{''.join(broken)}")


def _rows_of_row(values: Mapping[str, Any], where: str) -> ParadigmRows:
    """A legacy row's paradigm: the first whose marker column it fills."""
    rooms = legacy_rooms()
    for rows in rooms:
        if values.get(rows.marker) is not None:
            return rows
    markers = ", ".join(f"{r.marker} ({r.name})" for r in rooms)
    raise ResultsError(f"{where}: a row needs one of {markers}")


def _same(read: Any, written: Any) -> bool:
    if isinstance(read, float) and isinstance(written, float):
        return read == written or (math.isnan(read) and math.isnan(written))
    return bool(read == written)


# Cells read back that cannot be below 0: times (ns) and counts.
NOT_NEGATIVE = {"stimulus_onset": "s", "stimulus_duration": "s", "response_time": "s",
                "goals_scheduled": "", "goals_confirmed": "", "goals_healed": "",
                "goals_missing": "", "stroke_commanded": "steps", "stroke_achieved": "steps",
                "stroke_median": "steps", "motion_lag": "s", "cycles_short": ""}


def check_common(values: Mapping[str, Any], where: str) -> None:
    """The common cells of a row read back, against each other: times and counts not below
    0, no more goal changes accounted for than were scheduled, and none missing from a trial
    that counts (a trial with a change never confirmed was not delivered as scheduled)."""
    for name, unit in NOT_NEGATIVE.items():
        value = values.get(name)
        if value is not None and value < 0:
            shown = f"{value / 1e9:g} s" if unit == "s" else f"{value:g} {unit}".rstrip()
            raise ResultsError(f"{where}: expected {name} of at least 0, found {shown}")
    scheduled, missing = values.get("goals_scheduled"), values.get("goals_missing")
    fates = [values.get(n) for n in ("goals_confirmed", "goals_healed", "goals_missing")]
    accounted = sum(f for f in fates if f is not None)
    if missing and values.get("status") == TrialStatus.OK:
        raise ResultsError(f"{where}: expected status {TrialStatus.INVALID} for a trial with "
                           f"goal changes missing (not delivered as scheduled), found "
                           f"{TrialStatus.OK} with {missing} missing")
    if scheduled is not None and accounted > scheduled:
        raise ResultsError(f"{where}: expected at most the {scheduled} goal change(s) scheduled "
                           f"to be confirmed, healed or missing, found {accounted}")


def row_record(values: Mapping[str, Any], names: Sequence[str], columns: Mapping[str, Column],
               rows: ParadigmRows | None, where: str,
               cells: Sequence[str] | None = None) -> TrialRecord:
    """The record of a row read back (``values``: its cells parsed, by column; ``cells``:
    their text, when at hand), checked to write exactly the cells it was read from."""
    rows = rows or _rows_of_row(values, where)
    check_common(values, where)
    try:
        record = rows.record(common_fields(dict(values), where), values, where)
    except ResultsError as problem:
        message = str(problem)
        raise ResultsError(message if message.startswith(where) else f"{where}: {message}") \
            from None
    written = record_values(record, rows)
    for n, name in enumerate(names):
        column = columns[name]
        read, again = values.get(name), written.get(name)
        if read is None and again is None:
            continue
        if cells is not None and again is not None and cells[n] == cell_text(column, again):
            continue  # written as read, to the character: the common case, and the quick one
        if read is None or again is None or not _same(
                cell_value(column, cell_text(column, read), where),
                cell_value(column, cell_text(column, again), where)):
            raise ResultsError(
                f"{where}: column {name!r} holds {cell_text(column, read)!r}, but the row "
                f"makes it {cell_text(column, again)!r} (edited by hand?); put the row back "
                "as it was")
    return record


def read_trials(path: Path | str, paradigm: str | None = None) -> list[TrialRecord]:
    """The whole rows of a ``beh.tsv`` (a torn last row is left out, not an error).

    ``paradigm``: the run's (its manifest's); None reads a file handed over alone, whose rows
    are told apart by their columns. Row ``i`` of the list is line ``i + 2`` of the file (line
    1 is the header).
    """
    path = Path(path)
    data = results_bytes(path)
    header_names = beh_header(path)
    end, _ = split_torn_tail(data, len(header_names) or len(LEGACY_LAYOUT))
    table = read_tsv(path, data[:end].decode("utf-8"))
    if not table:
        return []
    names = todays_names(table[0])
    rows, columns = layout_rows(names, paradigm, str(path))
    # Files written before the delivery columns existed end at `resumed`: read what they hold.
    records = []
    for number, cells in enumerate(table[1:], start=2):
        where = f"{path}:{number}"
        if len(cells) != len(names):
            raise ResultsError(f"{where}: expected {len(names)} cells, found {len(cells)}")
        values = {name: cell_value(columns[name], cell, where)
                  for name, cell in zip(names, cells, strict=True)}
        records.append(row_record(values, names, columns, rows, where, cells))
    return records


def check_run(path: Path | str, records: Sequence[TrialRecord], manifest: RunManifest) -> None:
    """Every row is the run's: its task, a trial of its plan presenting what the plan says
    (a finished row, status ok, a trial the plan has), an answer the design offered; a
    `ResultsError` naming the first row that is not."""
    rows = rows_of(manifest.task_info.paradigm)
    plan = {(e.trial, e.practice): e for e in manifest.plan}
    answers = rows.offered(manifest)
    offered = None if answers is None else set(answers)
    for number, record in enumerate(records, start=2):
        where = f"{path}:{number}: trial {record.trial}"
        if record.task != manifest.task:
            raise ResultsError(f"{where}: expected the run's task {manifest.task!r}, found "
                               f"{record.task!r}")
        entry = plan.get(record.key)
        if entry is None:
            if record.status is not TrialStatus.OK:
                continue  # a trial presented again, never finished: nothing counts it
            kind = "practice trial" if record.practice else "trial"
            raise ResultsError(f"{where}: the run's plan has no {kind} {record.trial}")
        if record.block != entry.block:
            raise ResultsError(f"{where}: expected the plan's block {entry.block}, found "
                               f"{record.block}")
        problem = rows.check_row(record, entry, manifest)
        if problem:
            raise ResultsError(f"{where}: {problem}")
        if offered is not None and record.response is not None and record.response not in offered:
            raise ResultsError(f"{where}: expected an answer the design offered ("
                               f"{', '.join(sorted(offered)) or 'none'}), found "
                               f"{record.response!r}")
    together = getattr(rows, "check_together", None)  # optional: RowsDefaults has it
    found = together(records) if together is not None else None
    if found is not None:
        index, problem = found
        raise ResultsError(f"{path}:{index + 2}: trial {records[index].trial}: {problem}")


def finished_trials(records: Iterable[TrialRecord]) -> frozenset[tuple[int, bool]]:
    """(trial, practice) of every trial whose row finishes it (status ok)."""
    return frozenset(r.key for r in records if r.status is TrialStatus.OK)


def check_finished_once(path: Path | str, records: Sequence[TrialRecord], then: str = "") -> None:
    """A `ResultsError` at the second ``ok`` row of the first trial logged ok twice (only a
    second writer or a hand edit leaves one: which answer counts is for a person to say, by
    deleting the other row; ``then`` says what comes after that)."""
    for (trial, practice), lines in finished_twice(records).items():
        kind = "practice trial" if practice else "trial"
        raise ResultsError(
            f"{path}:{lines[1]}: {kind} {trial} is logged ok twice (lines "
            f"{', '.join(map(str, lines))}); a trial counts once: delete the row that should "
            f"not count{then}")


def finished_twice(records: Sequence[TrialRecord]) -> dict[tuple[int, bool], list[int]]:
    """Trials with more than one ``ok`` row, and the file lines of those rows (header = line 1)."""
    lines: dict[tuple[int, bool], list[int]] = {}
    for index, record in enumerate(records):
        if record.status is TrialStatus.OK:
            lines.setdefault(record.key, []).append(index + 2)
    return {key: found for key, found in lines.items() if len(found) > 1}

