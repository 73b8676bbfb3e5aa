"""The paradigm seam, as the results see it: a paradigm's rows, their columns, their checks.

Each paradigm's room (`pinarray.paradigms`) gives its trials' record type, the columns that
hold what its trials presented, and how a row is made, read back and checked (`ParadigmRows`,
the room's ``rows``); the journal knows a paradigm only through it, found by name
(`rows_of`). What every paradigm promises of its rows is kept by the journal, once for all
(`pinarray.journal.rows`): every cell written is a record's field checked when the record is
made, every cell read back is parsed by its column's type, the row's record rebuilt and its
cells written again must be the cells read (a derived cell edited by hand is named), the
task is the run's, the trial is one of its plan's and presents what the plan says
(`check_row`), and the answer is one the design offered (`offered`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cache
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from pinarray import registry
from pinarray.errors import ResultsError
from pinarray.journal.columns import Column
from pinarray.journal.records import (
    COMMON,
    EVENT_LAYOUT,
    LEGACY_LAYOUT,
    TrialFields,
    TrialRecord,
)

if TYPE_CHECKING:
    from pinarray.grid import Grid
    from pinarray.journal.manifest import PlanEntry, RunManifest, TaskInfo
    from pinarray.protocol.model import Condition


@runtime_checkable
class ParadigmRows(Protocol):
    """What a paradigm is to its results: its rows' type, columns, and checks.

    Attributes
    ----------
    name : str
        The paradigm's name (its room's).
    record_type : type
        Its rows' record type, a `TrialRecord` subclass.
    columns : tuple of Column
        The columns that hold what its trials presented (beside `COMMON_COLUMNS`, which it
        may fill too: the response, correct, pins).
    layout, event_layout : tuple of str
        The columns of its ``beh.tsv`` and ``events.tsv``, in order.
    marker : str
        A column only its rows fill: what tells its rows apart in a file read without its
        manifest (results handed over alone).
    instructions : str
        What the subject is told, for the sidecars of a run whose manifest does not say
        (manifests older than the words: a design's own are in its run's manifest).
    """

    name: str
    record_type: type[TrialRecord]
    columns: tuple[Column, ...]
    layout: tuple[str, ...]
    event_layout: tuple[str, ...]
    marker: str
    instructions: str

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        """The row's cells of its paradigm (its columns', the response's, and correct's or
        pins' where it fills them), as Python values (None: n/a)."""
        ...

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        """The record of a row read back: ``fields`` every row has, ``values`` every cell by
        column name (None: n/a); a `ResultsError` naming ``where`` when they make none."""
        ...

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        """The record of a trial presenting ``condition`` (as its row tells it: an adaptive
        value in place), answered ``response`` (as the design takes answers); ``pins`` are
        the pins its drives move, on ``grid``."""
        ...

    def trial_type(self, record: TrialRecord) -> str:
        """The row's ``trial_type`` in ``events.tsv`` (``<task>_<condition>``)."""
        ...

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        """Every ``trial_type`` the plan's trials have, with what each means."""
        ...

    def levels(self, manifest: RunManifest) -> dict[str, dict[str, str]]:
        """The run's levels of its columns and of ``response`` (its sidecar's), by column."""
        ...

    def offered(self, manifest: RunManifest) -> tuple[str, ...] | None:
        """Every answer a row of the run may hold (None: the manifest does not say them, and
        the record's own check is all there is)."""
        ...

    def check_entry(self, entry: PlanEntry) -> None:
        """A plan entry's fields read back: a `ValueError` (or `KeyError`, `TypeError`) when
        they are not its paradigm's."""
        ...

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        """Why the row does not present what its plan entry says, or its cells do not follow
        from the run (an error class of its grid...); None: it does."""
        ...

    def live_lines(self, counted: Sequence[TrialRecord]) -> list[str]:
        """The run screen's running counts of the rows counted so far (main trials, ok)."""
        ...

    def last_line(self, record: TrialRecord) -> str:
        """The trial just answered, as the run screen shows it after its number (``, pin 6 →
        pin 7 (A)``; `` → first ✓``)."""
        ...


@cache  # a protocol's check is slow (typing's), and a results file asks once per row
def rows_of(name: str) -> ParadigmRows:
    """The rows of the paradigm called ``name`` (the registry's), checked to be `ParadigmRows`."""
    room = registry.room(name)
    rows = getattr(room, "rows", None)
    if not isinstance(rows, ParadigmRows):
        raise ResultsError(f"paradigm {name!r} does not implement the paradigm seam: its room "
                           "gives no rows (ParadigmRows)")
    return rows


def legacy_rooms() -> tuple[ParadigmRows, ...]:
    """pinarray's own paradigms whose files keep the layout of the releases before the seam."""
    return tuple(rows for rows in (rows_of(name) for name in registry.BUILT_IN)
                 if rows.layout == LEGACY_LAYOUT)


def columns_of(rows: ParadigmRows) -> dict[str, Column]:
    """Every column a file of ``rows``'s paradigm may hold, by name: the common ones, its own,
    and in the legacy layout those of the other paradigms that share it."""
    found = dict(COMMON)
    if rows.layout == LEGACY_LAYOUT:
        for other in legacy_rooms():
            found |= {c.name: c for c in other.columns}
    return found | {c.name: c for c in rows.columns}


def paradigm_of_entry(data: Any, where: str) -> str:
    """The paradigm of a manifest older than the paradigms' names, from its first plan entry:
    the first of pinarray's own whose entries it can be."""
    from pinarray.journal.manifest import entry_from_json

    for rows in legacy_rooms():
        try:
            entry_from_json(data, where, rows.name)
        except ResultsError:
            continue
        return rows.name
    raise ResultsError(f"{where}: the plan's first trial is no paradigm's: {data!r}")


class RowsDefaults:
    """What a paradigm's rows need not say: the layout of a paradigm added since the seam
    (the common columns, then its own), ``trial_type`` from the stimulus, answers as the
    design offered them (the manifest's task info), a plan entry whose fields are checked by
    the plan it was compared with on resume."""

    name: str
    columns: tuple[Column, ...] = ()
    instructions = ""
    # The columns whose Levels (the design's values) a run's sidecar must give for its rows to
    # be checked without the manifest (`pinarray.journal.sidecar_levels`); a sidecar without
    # them leaves the run unchecked, as no sidecar does.
    sidecar_needs: tuple[str, ...] = ()

    @property
    def layout(self) -> tuple[str, ...]:
        own = tuple(c.name for c in self.columns if c.name not in COMMON)
        return (*(name for name in LEGACY_LAYOUT if name in COMMON), *own)

    @property
    def event_layout(self) -> tuple[str, ...]:
        return EVENT_LAYOUT

    def trial_type(self, record: TrialRecord) -> str:
        return f"{record.task}_{_label(getattr(record, 'stimulus', '') or 'trial')}"

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        return dict(sorted({f"{task}_{_label(e.stimulus)}": f"stimulus {e.stimulus}"
                            for e in plan}.items()))

    def levels(self, manifest: RunManifest) -> dict[str, dict[str, str]]:
        return {"response": dict(manifest.task_info.answers)}

    def offered(self, manifest: RunManifest) -> tuple[str, ...] | None:
        return tuple(answer for answer, _ in manifest.task_info.answers) or None

    def check_entry(self, entry: PlanEntry) -> None:
        return None

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        return None

    def check_together(self, records: Sequence[TrialRecord]) -> tuple[int, str] | None:
        """What a run's rows must agree on that no plan entry says (optional: `check_run`
        asks where a room has it): the index of the first row that does not, and why."""
        return None

    def check_levels(self, record: TrialRecord,
                     levels: Mapping[str, Mapping[str, str]]) -> str | None:
        """What else the run's levels (its sidecar's, by column: read when the manifest is not
        there) fix of a row whose every cell is one of its column's levels (optional:
        `pinarray.journal.sidecar_levels` asks where a room has it): why the row breaks it,
        or None."""
        return None

    def live_lines(self, counted: Sequence[TrialRecord]) -> list[str]:
        """Right answers of the rows that have one (``correct``)."""
        judged = [c for c in (getattr(r, "correct", None) for r in counted) if c is not None]
        return [f"correct {sum(judged)}/{len(judged)}"]

    def last_line(self, record: TrialRecord) -> str:
        correct = getattr(record, "correct", None)
        mark = "" if correct is None else "✓" if correct else "✗"
        return f" → {record.response} {mark}".rstrip()


def _label(text: str) -> str:
    return "".join(ch for ch in text if ch.isalnum()) or "trial"


def pin_levels(info: TaskInfo) -> dict[str, str]:
    """A pin column's levels: each pin of the run's grid by its row and column."""
    return {str(p): f"row {(p - 1) // info.grid_columns + 1}, column "
                    f"{(p - 1) % info.grid_columns + 1} (row 1 at the bottom)" for p in info.pins}


def row_levels(info: TaskInfo) -> dict[str, str]:
    """A grid-row column's levels: each row of the run's grid."""
    return {str(r): f"row {r} (1 = bottom)" for r in range(1, info.grid_rows + 1)}
