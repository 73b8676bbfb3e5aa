"""Trial rows on disk: one row per finished trial, appended and fsync'd before the next trial.

``beh.tsv`` is the record of what happened; ``events.tsv`` is derived from it one row per
trial (so it can always be rebuilt from ``beh.tsv`` after a crash). A process killed while
writing can leave at most one torn last line, which `repair_tail` drops; every earlier row
was on disk before the trial after it began.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from pinarray.errors import ResultsError
from pinarray.journal.manifest import (
    UNFINISHED_STATUSES,
    RunPaths,
    SessionManifest,
    check_label,
    fsync_folder,
    new_manifest,
    next_run,
    now_iso,
    read_manifest,
    set_status,
    write_atomically,
    write_manifest,
)
from pinarray.stop import deferred_signals

NA = "n/a"  # BIDS spelling of "not applicable"
TRIAL_STATUSES = ("ok", "redone", "aborted", "invalid")
# Only an "ok" row finishes its trial. A "redone", "aborted" or "invalid" one (the stimulus
# failed, e.g. a bus fault) is presented again: after a redo or retry, or on resume.
FINISHING_STATUSES = ("ok",)
ERROR_CLASSES = ("correct", "A", "B", "C", "D", "none")
MOTION_RESPONSES = ("none", "left", "right", "unsure")
DIRECTIONS = ("left", "right", "none")


@dataclass(frozen=True)
class TrialRecord:
    """One finished (or abandoned) trial as its ``beh.tsv`` row holds it. Times in seconds.

    A localisation trial sets ``pin``, ``frequency_hz`` and ``error_class``; a motion trial
    sets ``row``, ``direction`` ("left", "right", or "none" for the no-wave control),
    ``perceived_motion`` and ``direction_correct``. Fields that do not apply are ``None``
    (written ``n/a``). ``response`` is the pin number as text or "none" (nothing felt) for
    localisation, and one of none / left / right / unsure for motion.
    """

    trial: int
    block: int
    task: str
    onset_s: float
    duration_s: float
    status: str = "ok"
    response: str | None = None
    response_time_s: float | None = None
    pin: int | None = None
    frequency_hz: float | None = None
    error_class: str | None = None
    row: int | None = None
    direction: str | None = None
    perceived_motion: bool | None = None
    direction_correct: bool | None = None
    practice: bool = False
    resumed: bool = False
    goals_scheduled: int | None = None
    goals_confirmed: int | None = None
    goals_healed: int | None = None
    goals_missing: int | None = None
    delivery_lateness_s: float | None = None
    status_reason: str | None = None

    def __post_init__(self) -> None:
        check_label("task", self.task)
        where = f"trial {self.trial}"
        if isinstance(self.trial, bool) or not isinstance(self.trial, int) or self.trial < 0:
            raise ResultsError(f"trial number must be a whole number >= 0, found {self.trial!r}")
        for name, allowed in (("status", TRIAL_STATUSES), ("error_class", ERROR_CLASSES),
                              ("direction", DIRECTIONS)):
            value = getattr(self, name)
            if value is not None and value not in allowed:
                raise ResultsError(f"{where}: {name} must be one of {allowed}, found {value!r}")
        if self.direction is not None and self.response not in (None, *MOTION_RESPONSES):
            raise ResultsError(
                f"{where}: a motion response must be one of {MOTION_RESPONSES}, "
                f"found {self.response!r}"
            )
        for name in ("response", "status_reason"):
            text = getattr(self, name)
            if isinstance(text, str) and ("\n" in text or "\r" in text):
                # One row per line is what lets a torn last line be told from a whole one.
                raise ResultsError(f"{where}: a {name} cannot contain a line break")

    @property
    def is_localisation(self) -> bool:
        return self.pin is not None

    @property
    def is_motion(self) -> bool:
        return self.direction is not None

    @property
    def counts(self) -> bool:
        """Whether analysis counts this row: a main (not practice) trial with status ok."""
        return self.status == "ok" and not self.practice


# TSV column -> (TrialRecord field, sidecar description, units or levels)
BEH_COLUMNS: dict[str, tuple[str, str, str | dict[str, str] | None]] = {
    "trial": ("trial", "Trial number in the session plan (1-based; 0 or more for practice).",
              None),
    "block": ("block", "Block number within the session.", None),
    "task": ("task", "Task label: which experiment this row belongs to.", None),
    "pin": ("pin", "Stimulated pin, numbered as the subject sees it (1 = bottom-left, "
            "16 = top-right on the 4x4 grid).", None),
    "row": ("row", "Grid row the apparent-motion wave runs along (1 = bottom row).", None),
    "direction": ("direction", "Direction of the stimulated wave.",
                  {"left": "wave travels leftwards", "right": "wave travels rightwards",
                   "none": "no wave: the central pin alternates with the lateral ones"}),
    "frequency_hz": ("frequency_hz", "Stimulation frequency of the moving pin.", "Hz"),
    "response": ("response", "The subject's answer: a pin number or 'none' (nothing felt) "
                 "for localisation; none / left / right / unsure for motion.", None),
    "error_class": ("error_class", "Localisation response relative to the stimulated pin.",
                    {"correct": "the stimulated pin", "A": "adjacent, same row or column",
                     "B": "diagonal neighbour", "C": "same row or column, not adjacent",
                     "D": "neither on the same row or column nor close",
                     "none": "nothing felt"}),
    "perceived_motion": ("perceived_motion", "Whether the subject felt a moving dot.",
                         {"true": "felt motion", "false": "felt no motion"}),
    "direction_correct": ("direction_correct", "Whether the named direction matches the "
                          "wave; n/a when no motion was felt or there was no wave.",
                          {"true": "named the wave's direction", "false": "did not"}),
    "onset": ("onset_s", "Stimulus onset from the start of the run.", "s"),
    "duration": ("duration_s", "Stimulus duration.", "s"),
    "response_time": ("response_time_s", "Time from stimulus onset to the response.", "s"),
    "status": ("status", "What became of the trial.",
               {"ok": "completed and counted", "redone": "repeated at the experimenter's "
                "request; a later row holds the repeat", "aborted": "cut short; presented "
                "again on resume",
                "invalid": "the stimulus failed (e.g. a bus fault); presented again"}),
    "practice": ("practice", "Whether this was a practice trial (not analysed).",
                 {"true": "practice", "false": "main trial"}),
    "resumed": ("resumed", "Whether the trial ran after the session was resumed.",
                {"true": "after a resume", "false": "in the first sitting"}),
    "goals_scheduled": ("goals_scheduled", "Servo goal-position changes the trial's schedule "
                        "holds; n/a when the stimulus never played.", None),
    "goals_confirmed": ("goals_confirmed", "Goal changes read back from their servo as sent "
                        "(sync writes get no reply, so each is verified by a read).", None),
    "goals_healed": ("goals_healed", "Goal changes the servo did not hold when read back "
                     "(lost on the wire), written again with an acknowledged write.", None),
    "goals_missing": ("goals_missing", "Goal changes never confirmed on their servo; any "
                      "makes the trial invalid.", None),
    "delivery_lateness": ("delivery_lateness_s", "How late the latest confirmed or healed goal "
                          "change reached its servo after its scheduled time (host write time "
                          "plus wire time); above the protocol's delivery tolerance the trial "
                          "is invalid.", "s"),
    "status_reason": ("status_reason", "Why a trial is not ok: the bus fault, what was not "
                      "delivered as scheduled, or who stopped it; n/a for ok rows.", None),
}
EVENT_COLUMNS = ("onset", "duration", "trial_type", "trial", "pin", "row", "direction",
                 "frequency_hz", "response", "status", "practice")
_FIELD_TYPES = {f.name: f.type for f in fields(TrialRecord)}
# The columns of the first release; later ones are appended after them.
_FIRST_COLUMNS = tuple(BEH_COLUMNS)[: tuple(BEH_COLUMNS).index("resumed") + 1]


def _is_int(text: object) -> bool:
    return isinstance(text, str) and text.isdigit()


def _format(value: Any) -> str:
    if value is None:
        return NA
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        # Whole numbers print as integers ("10", not "10.0"); others round-trip exactly.
        return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)
    return str(value)


def _parse(name: str, text: str, where: str) -> Any:
    if text == NA:
        return None
    kind = _FIELD_TYPES[name]
    try:
        if kind.startswith("bool"):
            if text not in ("true", "false"):
                raise ValueError(text)
            return text == "true"
        if kind.startswith("int"):
            return int(text)
        if kind.startswith("float"):
            return float(text)
    except ValueError:
        raise ResultsError(f"{where}: column {name!r} cannot hold {text!r}") from None
    return text


def trial_row(record: TrialRecord) -> list[str]:
    """The ``beh.tsv`` cells of ``record``, in column order."""
    return [_format(getattr(record, attr)) for attr, _, _ in BEH_COLUMNS.values()]


def trial_type(record: TrialRecord) -> str:
    """The events.tsv condition label, e.g. ``localisation_10hz`` or ``motion_left``."""
    if record.direction is not None:
        return f"{record.task}_{record.direction}"
    if record.frequency_hz is not None:
        return f"{record.task}_{_format(record.frequency_hz)}hz"
    return record.task


def event_row(record: TrialRecord) -> list[str]:
    """The ``events.tsv`` cells of ``record``, in `EVENT_COLUMNS` order."""
    values = {"onset": record.onset_s, "duration": record.duration_s,
              "trial_type": trial_type(record)}
    return [_format(values[c] if c in values else getattr(record, c)) for c in EVENT_COLUMNS]


def beh_sidecar() -> dict[str, dict[str, Any]]:
    """The BIDS JSON sidecar describing every ``beh.tsv`` column."""
    sidecar: dict[str, dict[str, Any]] = {}
    for column, (_, description, extra) in BEH_COLUMNS.items():
        entry: dict[str, Any] = {"Description": description}
        if isinstance(extra, dict):
            entry["Levels"] = extra
        elif extra:
            entry["Units"] = extra
        sidecar[column] = entry
    return sidecar


def events_sidecar() -> dict[str, dict[str, Any]]:
    """The BIDS JSON sidecar describing every ``events.tsv`` column."""
    beh = beh_sidecar()
    sidecar = {c: beh[c] for c in EVENT_COLUMNS if c in beh}
    sidecar["trial_type"] = {"Description": "Condition: task and frequency (localisation) "
                             "or task and wave direction (motion), e.g. localisation_10hz."}
    return {c: sidecar[c] for c in EVENT_COLUMNS}


def _line(cells: Sequence[str]) -> str:
    out = io.StringIO()
    csv.writer(out, delimiter="\t", lineterminator="\n").writerow(cells)
    return out.getvalue()


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
        if start and len(next(csv.reader([last], delimiter="\t"))) != columns:
            end = start
    return end, data[end:]


def repair_tail(path: Path, columns: int) -> str:
    """Drop a torn last row of the TSV at ``path`` in place; return the dropped text."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return ""
    end, torn = split_torn_tail(data, columns)
    if torn:
        with open(path, "r+b") as handle:
            handle.truncate(end)
            handle.flush()
            os.fsync(handle.fileno())
    return torn.decode("utf-8", errors="replace")


def read_trials(path: Path | str) -> list[TrialRecord]:
    """The whole rows of a ``beh.tsv`` (a torn last row is left out, not an error)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ResultsError(f"{path}: no such results file") from None
    columns = len(beh_header(path)) or len(BEH_COLUMNS)
    end, _ = split_torn_tail(data, columns)
    rows = list(csv.reader(io.StringIO(data[:end].decode("utf-8")), delimiter="\t"))
    if not rows:
        return []
    header = rows[0]
    if header != list(BEH_COLUMNS)[: len(header)] or len(header) < len(_FIRST_COLUMNS):
        raise ResultsError(f"{path}:1: expected the columns {list(BEH_COLUMNS)}, found {header}")
    # Files written before the delivery columns existed end at `resumed`: read what they hold.
    attrs = [BEH_COLUMNS[column][0] for column in header]
    records = []
    for number, cells in enumerate(rows[1:], start=2):
        where = f"{path}:{number}"
        if len(cells) != len(header):
            raise ResultsError(f"{where}: expected {len(header)} cells, found {len(cells)}")
        values = {attr: _parse(attr, cell, where) for attr, cell in zip(attrs, cells, strict=True)}
        records.append(TrialRecord(**values))
    return records


def beh_header(path: Path) -> list[str]:
    """The column names of an existing ``beh.tsv`` (empty if it has no header yet)."""
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            first = handle.readline()
    except FileNotFoundError:
        return []
    return next(csv.reader([first], delimiter="\t"), []) if first.strip() else []


def _plan_key(entry: Mapping[str, Any]) -> tuple[int, bool]:
    return int(entry["trial"]), bool(entry.get("practice", False))


def finished_trials(records: Iterable[TrialRecord]) -> frozenset[tuple[int, bool]]:
    """(trial, practice) of every trial whose row finishes it (status ok)."""
    return frozenset((r.trial, r.practice) for r in records if r.status in FINISHING_STATUSES)


def remaining_plan(
    plan: Sequence[Mapping[str, Any]], records: Iterable[TrialRecord]
) -> list[Mapping[str, Any]]:
    """The plan entries not yet finished, in plan order."""
    done = finished_trials(records)
    return [entry for entry in plan if _plan_key(entry) not in done]


class _AppendOnlyTsv:
    """A TSV opened for appending whose every row is on disk when `append` returns."""

    def __init__(self, path: Path, header: Sequence[str]):
        created = not path.exists()
        self._file = open(path, "a", encoding="utf-8", newline="")  # noqa: SIM115
        if self._file.tell() == 0:
            self.append(header)
        if created:
            fsync_folder(path.parent)

    def append(self, cells: Sequence[str]) -> None:
        self._file.write(_line(cells))
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        self._file.close()


class RunWriter:
    """Writes one run: the manifest before trial 1, then each trial row the moment it ends.

    Make one with `RunWriter.start` (a new run) or `RunWriter.resume` (an unfinished one);
    use it as a context manager so a crash inside the block marks the manifest ``crashed``.
    """

    def __init__(self, paths: RunPaths, manifest: SessionManifest,
                 records: list[TrialRecord], resumed: bool, repaired: str = ""):
        self.paths = paths
        self.manifest = manifest
        self.records = records
        self.resumed = resumed
        self.repaired = repaired  # text of a torn row dropped on resume, for the log
        self._beh = _AppendOnlyTsv(paths.beh_tsv, list(BEH_COLUMNS))
        self._events = _AppendOnlyTsv(paths.events_tsv, EVENT_COLUMNS)

    @classmethod
    def start(
        cls,
        root: Path | str,
        subject: str,
        session: str | int,
        task: str,
        plan: Sequence[Mapping[str, Any]],
        **provenance: Any,
    ) -> RunWriter:
        """Start the next free run: write the manifest (status running) and the sidecars.

        ``provenance`` is the keywords of `pinarray.journal.manifest.new_manifest`: ``seed``,
        ``protocol_sha256``, ``port``, and optionally ``servo_models`` and ``experimenter``.
        """
        try:
            paths = next_run(root, subject, session, task)
            manifest = new_manifest(paths, plan, **provenance)
            write_manifest(paths.manifest, manifest)
            for suffix, sidecar in (("beh", beh_sidecar()), ("events", events_sidecar())):
                write_atomically(paths.file(suffix, "json"), json.dumps(sidecar, indent=2) + "\n")
            return cls(paths, manifest, [], resumed=False)
        except OSError as problem:
            where = problem.filename or root
            raise ResultsError(f"{where}: cannot write results there: {problem.strerror}") from None

    @classmethod
    def resume(cls, paths: RunPaths) -> RunWriter:
        """Reopen an unfinished run: drop a torn row, rebuild missing events, mark running."""
        manifest = read_manifest(paths.manifest)
        if manifest.status not in UNFINISHED_STATUSES:
            raise ResultsError(f"{paths.manifest}: the run is {manifest.status}; "
                               f"only a {'/'.join(UNFINISHED_STATUSES)} run can be resumed")
        header = beh_header(paths.beh_tsv)
        if header and header != list(BEH_COLUMNS):
            raise ResultsError(
                f"{paths.beh_tsv}:1: this run was written by an earlier pinarray with the columns "
                f"{', '.join(header)}; finish it with that version, or start a new run"
            )
        repaired = repair_tail(paths.beh_tsv, len(BEH_COLUMNS))
        records = read_trials(paths.beh_tsv) if paths.beh_tsv.exists() else []
        repair_tail(paths.events_tsv, len(EVENT_COLUMNS))
        manifest = replace(manifest, status="running", abort_reason="", pid=os.getpid(),
                           updated_at=now_iso(), resumed_at=(*manifest.resumed_at, now_iso()))
        write_manifest(paths.manifest, manifest)
        writer = cls(paths, manifest, records, resumed=True, repaired=repaired)
        writer._rebuild_missing_events()
        return writer

    def _rebuild_missing_events(self) -> None:
        # beh.tsv is fsync'd before events.tsv, so a crash between the two leaves events one
        # row short; its rows are a function of the trial rows, so the gap is rebuilt.
        with open(self.paths.events_tsv, encoding="utf-8") as handle:
            have = max(0, sum(1 for _ in handle) - 1)
        for record in self.records[have:]:
            self._events.append(event_row(record))

    @property
    def plan(self) -> tuple[Mapping[str, Any], ...]:
        return self.manifest.plan

    def remaining(self) -> list[Mapping[str, Any]]:
        """Plan entries still to run, in plan order."""
        return remaining_plan(self.manifest.plan, self.records)

    def write_trial(self, record: TrialRecord) -> TrialRecord:
        """Append ``record`` to beh.tsv and events.tsv, each fsync'd, and return it as written.

        On a resumed run the row is marked ``resumed``.
        """
        if self.resumed and not record.resumed:
            record = replace(record, resumed=True)
        with deferred_signals():  # a Ctrl-C must not fall between the two files
            self._beh.append(trial_row(record))
            self._events.append(event_row(record))
            self.records.append(record)
        return record

    def finish(self, status: str = "completed", reason: str = "") -> None:
        """Set the manifest's final status (completed / aborted / crashed) and close."""
        self.manifest = set_status(self.paths.manifest, status, reason)
        self.close()

    def close(self) -> None:
        self._beh.close()
        self._events.close()

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(self, kind, error, traceback) -> None:
        if kind is None or self.manifest.status != "running":
            # Nothing went wrong, or the caller already recorded how the run ended.
            self.close()
        elif issubclass(kind, KeyboardInterrupt):
            self.finish("aborted", "interrupted (Ctrl-C)")
        else:
            self.finish("crashed", f"{kind.__name__}: {error}")
