"""A run's manifest: its plan, provenance, sittings, time zero and status, as one JSON file.

Written before trial 1 and replaced atomically whenever it changes (a sitting starts, the
run's time zero is fixed, the status changes), so a reader always finds a whole version. The
values crossing modules are frozen: `PlanEntry` (one trial of the plan), `Provenance` (what
the run was made from), `TaskInfo` (what the sidecars say about the task); JSON only at the
file boundary. Manifests written before the time base and the sum-typed plan (a ``pid`` and
``resumed_at`` list instead of sittings) are still read.

Past 400 lines on purpose: the manifest's values and their JSON, written and read back by the
same code; apart, they drift. A plan entry's condition is its paradigm's to check
(`pinarray.journal.seam.ParadigmRows.check_entry`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from pathlib import Path
from typing import Any

from pinarray.errors import ResultsError
from pinarray.journal.files import now_iso, read_results_json, results_file, write_atomically
from pinarray.journal.paths import SOURCEDATA, RunPaths, check_label
from pinarray.journal.records import TrialRecord, TrialStatus
from pinarray.journal.timebase import (
    Answers,
    ClockKind,
    Sitting,
    TimeScale,
    TimeZero,
    ns_from_seconds,
    seconds_text,
)
from pinarray.journal.volumes import ScannerRecord
from pinarray.version import __version__


class RunStatus(StrEnum):
    RUNNING = "running"  # being written, or killed outright (nothing was left to say so)
    COMPLETED = "completed"
    ABORTED = "aborted"  # stopped by the experimenter, a signal, or failed deliveries
    CRASHED = "crashed"  # an error inside the writer's block

    @property
    def unfinished(self) -> bool:
        """Whether the run can be resumed: everything but completed."""
        return self is not RunStatus.COMPLETED




# The keys of a plan entry every paradigm's has; the rest are its paradigm's (`fields`).
ENTRY_KEYS = ("trial", "block", "practice", "stimulus")
# Keys every entry has had since the first release (null where the paradigm has none).
FIRST_FIELDS = ("pin", "frequency_hz", "direction", "row")


@dataclass(frozen=True, kw_only=True)
class PlanEntry:
    """One trial of a run's plan, as its manifest keeps it: its number (1..N in plan order, the
    number every output uses), block (0: practice), stimulus, whether it is a catch trial of
    an adaptive design, and what its paradigm says of its condition (``fields``: plain JSON
    values, `pinarray.protocol.seam.ParadigmDesign.plan_fields`, after the pin,
    frequency_hz, direction and row every entry has had since the first release)."""

    trial: int
    block: int = 1
    practice: bool = False
    stimulus: str = ""
    catch: bool = False
    fields: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # The first release's keys are in every entry's JSON, null where they do not apply:
        # an entry is the same whether they were written or not.
        object.__setattr__(self, "fields", {k: v for k, v in self.fields.items()
                                            if not (k in FIRST_FIELDS and v is None)})

    def __getitem__(self, name: str) -> Any:
        """A field of the condition (None where the entry has none)."""
        return self.fields.get(name)


def entry_key(entry: PlanEntry) -> tuple[int, bool]:
    """(trial, practice), as `TrialRecord.key` names the same trial."""
    return entry.trial, entry.practice


def entry_from_record(record: Mapping[str, Any]) -> PlanEntry:
    """A plan entry from the JSON a planned trial is described by (`PlannedTrial.record`)."""
    return PlanEntry(trial=record["trial"], block=record["block"], practice=record["practice"],
                     stimulus=record["stimulus"], catch=record.get("catch") is True,
                     fields={k: v for k, v in record.items()
                             if k not in ENTRY_KEYS and k != "catch"})


def entry_to_json(entry: PlanEntry) -> dict[str, Any]:
    """The JSON a plan entry is stored as (the shape `pinarray compile` writes too)."""
    data: dict[str, Any] = {"trial": entry.trial, "block": entry.block,
                            "practice": entry.practice, "stimulus": entry.stimulus,
                            **dict.fromkeys(FIRST_FIELDS)}
    data |= entry.fields
    if entry.catch:
        data["catch"] = True
    return data


def entry_from_json(data: object, where: str, paradigm: str) -> PlanEntry:
    """A plan entry read back, its fields checked by its paradigm's room (``paradigm``)."""
    from pinarray.journal.seam import rows_of

    if not isinstance(data, Mapping):
        raise ResultsError(f"{where}: expected a trial plan entry, found {data!r}")
    trial = data.get("trial")
    if isinstance(trial, bool) or not isinstance(trial, int):
        raise ResultsError(f"{where}: a trial plan entry needs an integer 'trial', found {data!r}")
    try:
        entry = PlanEntry(trial=trial, block=int(data.get("block", 1)),
                          practice=bool(data.get("practice", False)),
                          stimulus=str(data.get("stimulus") or ""),
                          catch=data.get("catch") is True,
                          fields={k: v for k, v in data.items()
                                  if k not in ENTRY_KEYS and k != "catch"})
        rows_of(paradigm).check_entry(entry)
        return entry
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as problem:
        article = "an" if paradigm[:1] in "aeiou" else "a"
        raise ResultsError(f"{where}: trial {trial} of the plan is not {article} {paradigm} "
                           f"trial ({problem}): {dict(data)!r}") from None


def remaining_plan(plan: Iterable[PlanEntry], records: Iterable[TrialRecord]) -> list[PlanEntry]:
    """The plan entries not yet finished (no ``ok`` row), in plan order."""
    done = frozenset(r.key for r in records if r.status is TrialStatus.OK)
    return [entry for entry in plan if entry_key(entry) not in done]


@dataclass(frozen=True)
class Provenance:
    """What a run was made from: the plan's seed, the protocol, the bus, who ran it."""

    seed: int | None
    protocol_sha256: str
    port: str
    protocol_file: str = ""
    servo_models: tuple[str, ...] = ()
    experimenter: str = ""


@dataclass(frozen=True)
class TaskInfo:
    """What the sidecars say about the task and the device (BIDS TaskName, Instructions...)."""

    name: str
    paradigm: str  # what the protocol's design names: its room's name
    description: str = ""
    instructions: str = ""
    grid_rows: int = 4
    grid_columns: int = 4
    pitch_mm: float = 2.0
    # Each pin's travel for one position unit (servo step; us on a PWM board), mm, pin 1
    # first: what turns a stroke in the rows into millimetres. Empty in older manifests.
    mm_per_step: tuple[float, ...] = ()
    # Every answer the design offers, each with what it means (the sidecar's response
    # levels), where its paradigm keeps them here; empty where the plan says them, and in
    # older manifests.
    answers: tuple[tuple[str, str], ...] = ()

    @property
    def pins(self) -> range:
        return range(1, self.grid_rows * self.grid_columns + 1)


@dataclass(frozen=True)
class RunManifest:
    """Everything needed to re-run or audit a run. Wall-clock times are ISO 8601 with offset."""

    subject: str
    session: str
    task: str
    run: int
    plan: tuple[PlanEntry, ...]
    provenance: Provenance
    task_info: TaskInfo
    started_at: str = ""
    updated_at: str = ""
    status: RunStatus = RunStatus.RUNNING
    abort_reason: str = ""
    sittings: tuple[Sitting, ...] = ()
    time_zero: TimeZero | None = None
    software_version: str = __version__
    scanner: ScannerRecord | None = None  # a run timed from scanner volumes
    machine: Mapping[str, str] = field(default_factory=dict)
    # An adaptive run whose procedures all finished at this trial: the plan's later trials
    # were not needed (0: every planned trial is).
    needed_until: int = 0

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "status", RunStatus(self.status))
        except ValueError:
            raise ResultsError(f"manifest status must be one of {', '.join(RunStatus)}, "
                               f"found {self.status!r}") from None
        keys = [entry_key(e) for e in self.plan]
        if len(set(keys)) != len(keys):
            raise ResultsError("trial plan numbers a trial twice: each 'trial' must be unique")

    @property
    def needed(self) -> tuple[PlanEntry, ...]:
        """The planned trials the run needs: all of them, or, once its adaptive procedures
        have finished, those up to the trial they finished at."""
        if not self.needed_until:
            return self.plan
        return tuple(e for e in self.plan if e.practice or e.trial <= self.needed_until)

    @property
    def seed(self) -> int | None:
        return self.provenance.seed

    @property
    def protocol_sha256(self) -> str:
        return self.provenance.protocol_sha256

    def to_json(self) -> dict[str, Any]:
        p, t = self.provenance, self.task_info
        return {
            "subject": self.subject, "session": self.session, "task": self.task, "run": self.run,
            "status": self.status.value, "abort_reason": self.abort_reason,
            "started_at": self.started_at, "updated_at": self.updated_at,
            "seed": p.seed, "protocol_sha256": p.protocol_sha256, "protocol_file": p.protocol_file,
            "port": p.port, "servo_models": list(p.servo_models), "experimenter": p.experimenter,
            "software_version": self.software_version, "machine": dict(self.machine),
            "task_info": {"name": t.name, "paradigm": t.paradigm,
                          "description": t.description, "instructions": t.instructions,
                          "grid_rows": t.grid_rows, "grid_columns": t.grid_columns,
                          "pitch_mm": t.pitch_mm, "mm_per_step": list(t.mm_per_step),
                          **({"answers": dict(t.answers)} if t.answers else {})},
            "time_zero": None if self.time_zero is None else {
                "event": self.time_zero.event, "at": self.time_zero.at},
            "sittings": [_sitting_to_json(s) for s in self.sittings],
            **({} if self.scanner is None else {"scanner": self.scanner.to_json()}),
            **({"needed_until": self.needed_until} if self.needed_until else {}),
            "plan": [entry_to_json(e) for e in self.plan],
        }

    @classmethod
    def from_json(cls, data: object, where: str = "<manifest>") -> RunManifest:
        if not isinstance(data, Mapping):
            raise ResultsError(f"{where}: expected a pinarray run manifest (a JSON object), "
                               f"found {_json_kind(data)}")
        try:
            paradigm = _paradigm(data.get("task_info"), data["plan"], where)
            plan = tuple(entry_from_json(e, f"{where}: plan entry {i + 1}", paradigm)
                         for i, e in enumerate(data["plan"]))
            seed = data["seed"]
            if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
                raise ResultsError(f"{where}: the plan's seed must be a whole number from 0 "
                                   f"to 2**63 - 1, found {seed!r}")
            provenance = Provenance(
                seed=seed, protocol_sha256=str(data["protocol_sha256"]),
                port=str(data["port"]), protocol_file=str(data.get("protocol_file", "")),
                servo_models=tuple(map(str, data.get("servo_models", ()))),
                experimenter=str(data.get("experimenter", "")))
            zero = data.get("time_zero")
            return cls(
                subject=str(data["subject"]), session=str(data["session"]),
                task=str(data["task"]), run=int(data["run"]), plan=plan, provenance=provenance,
                task_info=_task_info(data.get("task_info"), str(data["task"]), paradigm),
                started_at=str(data.get("started_at", "")),
                updated_at=str(data.get("updated_at", "")), status=data["status"],
                abort_reason=str(data.get("abort_reason", "")),
                sittings=_sittings(data),
                time_zero=None if zero is None else TimeZero(str(zero["event"]), str(zero["at"])),
                software_version=str(data.get("software_version", "")),
                machine={str(k): str(v) for k, v in dict(data.get("machine", {})).items()},
                scanner=(ScannerRecord.from_json(data["scanner"]) if data.get("scanner")
                         else None),
                needed_until=int(data.get("needed_until", 0)),
            )
        except KeyError as error:
            raise ResultsError(f"{where}: expected a pinarray run manifest, found one without "
                               f"the key {error.args[0]!r}") from None
        except (TypeError, ValueError, AttributeError) as error:
            raise ResultsError(f"{where}: expected a pinarray run manifest, found a damaged "
                               f"one ({error})") from None


def _json_kind(data: object) -> str:
    kinds = {list: "a list", str: "a string", bool: "true or false", int: "a number",
             float: "a number", type(None): "null"}
    return kinds.get(type(data), type(data).__name__)


def _sitting_to_json(sitting: Sitting) -> dict[str, Any]:
    return {"number": sitting.number, "started_at": sitting.started_at,
            "clock": sitting.clock.kind.value, "time_scale": sitting.clock.factor,
            "start_s": None if sitting.start_ns is None else float(seconds_text(sitting.start_ns)),
            "pid": sitting.pid, "host": sitting.host,
            "software_version": sitting.software_version,
            **({"timing_check": sitting.timing_check} if sitting.timing_check else {}),
            **({"answers": sitting.answers.value}
               if sitting.answers is not Answers.UNKNOWN else {})}


def _answers(sitting: Mapping[str, Any]) -> Answers:
    """A sitting's answers (not recorded: an earlier pinarray's); a value a hand typed
    otherwise named in words (ValueError), not as Python names it."""
    value = sitting.get("answers", Answers.UNKNOWN.value)
    if isinstance(value, str) and value in tuple(Answers):
        return Answers(value)
    found = repr(value) if isinstance(value, str) else _json_kind(value)
    raise ValueError(f"sitting {sitting.get('number', '?')}'s answers: expected one of "
                     f"{', '.join(Answers)}, found {found}")


def _sittings(data: Mapping[str, Any]) -> tuple[Sitting, ...]:
    if "sittings" in data:
        return tuple(
            Sitting(number=int(s["number"]), started_at=str(s["started_at"]),
                    clock=TimeScale(ClockKind(s["clock"]), s.get("time_scale")),
                    start_ns=None if s.get("start_s") is None else ns_from_seconds(str(s["start_s"])),
                    pid=int(s.get("pid", 0)), host=str(s.get("host", "")),
                    software_version=str(s.get("software_version", "")),
                    timing_check=str(s.get("timing_check", "")),
                    answers=_answers(s))
            for s in data["sittings"])
    # Written before sittings were recorded: a start time and a pid, then one time per resume.
    unknown = TimeScale(ClockKind.UNKNOWN, None)
    host = str(dict(data.get("machine", {})).get("hostname", ""))
    starts = [str(data.get("started_at", "")), *map(str, data.get("resumed_at", ()))]
    return tuple(Sitting(number, at, unknown, None, int(data.get("pid", 0)) if number == 1 else 0,
                         host) for number, at in enumerate(starts, start=1))


def _paradigm(data: Any, plan: Any, where: str) -> str:
    """The run's paradigm, as its manifest names it (a manifest older than the names: the
    seed's two paradigms, told apart by the plan's first entry)."""
    from pinarray import registry
    from pinarray.journal.seam import paradigm_of_entry

    if data is None:
        return paradigm_of_entry(plan[0] if plan else {}, where)
    name = str(data["paradigm"])
    if not registry.is_known(name):
        raise ResultsError(f"{where}: the run's paradigm is not installed: "
                           f"{registry.why_not(name)}")
    return name


def _task_info(data: Any, task: str, paradigm: str) -> TaskInfo:
    if data is None:  # an older manifest (the seed's paradigms only): what the plan says
        return TaskInfo(task, paradigm)
    return TaskInfo(name=str(data["name"]), paradigm=paradigm,
                    description=str(data.get("description", "")),
                    instructions=str(data.get("instructions", "")),
                    grid_rows=int(data.get("grid_rows", 4)),
                    grid_columns=int(data.get("grid_columns", 4)),
                    pitch_mm=float(data.get("pitch_mm", 2.0)),
                    mm_per_step=tuple(float(mm) for mm in data.get("mm_per_step", ())),
                    answers=tuple((str(a), str(m))
                                  for a, m in dict(data.get("answers", {})).items()))


# A lone surrogate: what Python makes of a byte of a file name not in the locale's encoding
# (a protocol in a folder named in Latin-1 on a UTF-8 system: b"M\xfcller" is "M\udcfcller").
_LONE_SURROGATE = re.compile("[\ud800-\udfff]")


def write_manifest(path: Path, manifest: RunManifest) -> None:
    """Write ``manifest`` to ``path`` atomically, as indented UTF-8 JSON.

    Text as it reads, but a lone surrogate (the protocol file's name, say) as its JSON escape:
    UTF-8 has no code for it, and reading the file back gives the same name again."""
    text = json.dumps(manifest.to_json(), indent=2, ensure_ascii=False)
    write_atomically(path, _LONE_SURROGATE.sub(lambda lone: f"\\u{ord(lone[0]):04x}", text)
                     + "\n")


def read_manifest(path: Path | str) -> RunManifest:
    """Read a manifest written by `write_manifest`; a clear `ResultsError` if it is not one."""
    path = Path(path)
    if not results_file(path, "run manifest"):
        raise ResultsError(f"{path}: no run manifest here")
    return RunManifest.from_json(read_results_json(path, "run manifest"), str(path))


def updated(manifest: RunManifest, **changes: Any) -> RunManifest:
    """``manifest`` with ``changes``, stamped now."""
    return replace(manifest, **changes, updated_at=now_iso())


def set_status(path: Path | str, status: RunStatus, reason: str = "") -> RunManifest:
    """Atomically set a manifest's status (and abort reason), stamping ``updated_at``."""
    path = Path(path)
    manifest = updated(read_manifest(path), status=RunStatus(status), abort_reason=reason)
    write_manifest(path, manifest)
    return manifest


def find_unfinished(
    root: Path | str, subject: str, session: str | int | None = None, task: str | None = None
) -> list[tuple[RunPaths, RunManifest]]:
    """Runs of ``subject`` whose manifest says running, crashed or aborted, oldest run first.

    A run killed outright (SIGKILL, power cut) still says ``running``: nothing was left alive
    to change it, which is why ``running`` counts as unfinished too. Whether another process is
    writing it right now is the run's lock's to say (`pinarray.journal.lock.lock_holder`).
    """
    subject = check_label("subject", subject)
    ses = "*" if session is None else check_label("session", session)
    tsk = "*" if task is None else check_label("task", task)
    name = f"sub-{subject}_ses-{ses}_task-{tsk}_run-*_manifest.json"
    found: dict[RunPaths, RunManifest] = {}
    seen: set[RunPaths] = set()
    for base in (Path(root) / SOURCEDATA, Path(root)):  # where manifests live, then older runs'
        for path in sorted(base.glob(f"sub-{subject}/ses-{ses}/beh/{name}")):
            paths = RunPaths.from_file(path)
            if paths in seen:
                continue
            seen.add(paths)
            manifest = read_manifest(path)
            if manifest.status.unfinished:
                found[paths] = manifest
    return sorted(found.items(), key=lambda item: (item[0].session, item[0].task, item[0].run))
