"""Who, what and where a run is: labels, the BIDS file layout, and the session manifest.

A run lives under a results root (``results/`` by default) as BIDS lays out behaviour::

    sub-<subject>/ses-<session>/beh/sub-<subject>_ses-<session>_task-<task>_run-<k>_beh.tsv
                                   ..._beh.json       column descriptions (sidecar)
                                   ..._events.tsv     stimulus timing for imaging analyses
                                   ..._events.json
                                   ..._manifest.json  plan, seed, provenance, status

The manifest is written before trial 1 and replaced atomically (temporary file in the same
folder, fsync, ``os.replace``) whenever its status changes, so a reader always finds either
the old or the new version, never half of one.
"""

from __future__ import annotations

import json
import os
import platform
import re
import socket
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Any

from pinarray import __version__
from pinarray.errors import ResultsError

DEFAULT_RESULTS_ROOT = Path("results")
STATUSES = ("running", "completed", "aborted", "crashed")
# An aborted run (the experimenter stopped, or quit the UI) resumes like a crashed one.
UNFINISHED_STATUSES = ("running", "crashed", "aborted")
_LABEL = re.compile(r"[A-Za-z0-9]+")
_RUN_FILE = re.compile(
    r"sub-(?P<sub>[A-Za-z0-9]+)_ses-(?P<ses>[A-Za-z0-9]+)_task-(?P<task>[A-Za-z0-9]+)"
    r"_run-(?P<run>[0-9]+)_(?P<suffix>[a-z]+)\.(?P<ext>tsv|json)$"
)


class LabelError(ResultsError):
    """A subject, session or task label that BIDS (and a safe file path) cannot hold."""


def check_label(kind: str, label: object) -> str:
    """Return ``label`` as text if it is alphanumeric (BIDS), else raise `LabelError`.

    Parameters
    ----------
    kind : str
        What the label names ("subject", "session", "task"), for the message.
    label : object
        The label; integers are accepted for sessions (``1`` -> ``"1"``).
    """
    text = str(label) if isinstance(label, int) and not isinstance(label, bool) else label
    if not isinstance(text, str) or not _LABEL.fullmatch(text):
        raise LabelError(
            f"{kind} label {label!r} is not allowed: expected letters and digits only "
            f"(BIDS labels; no spaces, dots, slashes, dashes or underscores)"
        )
    return text


@dataclass(frozen=True)
class RunPaths:
    """The files of one run under a results root; labels are checked on construction."""

    root: Path
    subject: str
    session: str
    task: str
    run: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "root", Path(self.root))
        object.__setattr__(self, "subject", check_label("subject", self.subject))
        object.__setattr__(self, "session", check_label("session", self.session))
        object.__setattr__(self, "task", check_label("task", self.task))
        if isinstance(self.run, bool) or not isinstance(self.run, int) or self.run < 1:
            raise ResultsError(f"run number must be a whole number >= 1, found {self.run!r}")

    @property
    def beh_dir(self) -> Path:
        return self.root / f"sub-{self.subject}" / f"ses-{self.session}" / "beh"

    @property
    def stem(self) -> str:
        return f"sub-{self.subject}_ses-{self.session}_task-{self.task}_run-{self.run}"

    def file(self, suffix: str, ext: str) -> Path:
        return self.beh_dir / f"{self.stem}_{suffix}.{ext}"

    @property
    def beh_tsv(self) -> Path:
        return self.file("beh", "tsv")

    @property
    def events_tsv(self) -> Path:
        return self.file("events", "tsv")

    @property
    def manifest(self) -> Path:
        return self.file("manifest", "json")

    @classmethod
    def from_file(cls, path: Path | str) -> RunPaths:
        """The run a BIDS file name belongs to, with the results root three folders up."""
        path = Path(path)
        match = _RUN_FILE.fullmatch(path.name)
        if not match:
            raise ResultsError(
                f"{path}: not a pinarray run file; expected "
                "sub-<id>_ses-<n>_task-<task>_run-<k>_<beh|events|manifest>.<tsv|json>"
            )
        return cls(path.parent.parent.parent.parent, match["sub"], match["ses"],
                   match["task"], int(match["run"]))


def runs_of(root: Path | str, subject: str, session: str | int, task: str) -> list[RunPaths]:
    """Existing runs of one subject, session and task, by run number."""
    probe = RunPaths(Path(root), subject, str(session), task, 1)
    prefix = f"sub-{probe.subject}_ses-{probe.session}_task-{probe.task}_run-"
    found = {
        RunPaths.from_file(p).run
        for p in probe.beh_dir.glob(prefix + "*")
        if _RUN_FILE.fullmatch(p.name)
    }
    return [replace(probe, run=k) for k in sorted(found)]


def next_run(root: Path | str, subject: str, session: str | int, task: str) -> RunPaths:
    """The first run number after every existing one (never reuses a number)."""
    existing = runs_of(root, subject, session, task)
    probe = RunPaths(Path(root), subject, str(session), task, 1)
    return replace(probe, run=existing[-1].run + 1) if existing else probe


@dataclass(frozen=True)
class SessionManifest:
    """Everything needed to re-run or audit a run; plain JSON-safe values only.

    ``plan`` is the full trial plan in presentation order, one mapping per trial, each with
    an integer ``"trial"`` key. ``started_at`` and ``updated_at`` are ISO 8601 with offset.
    """

    subject: str
    session: str
    task: str
    run: int
    plan: tuple[Mapping[str, Any], ...]
    seed: int | None
    protocol_sha256: str
    port: str
    servo_models: tuple[str, ...] = ()
    experimenter: str = ""
    software_version: str = __version__
    machine: Mapping[str, str] = field(default_factory=dict)
    started_at: str = ""
    updated_at: str = ""
    status: str = "running"
    abort_reason: str = ""
    pid: int = 0
    resumed_at: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ResultsError(f"manifest status must be one of {STATUSES}, found {self.status!r}")
        numbers = []
        for index, entry in enumerate(self.plan):
            trial = entry.get("trial") if isinstance(entry, Mapping) else None
            if isinstance(trial, bool) or not isinstance(trial, int):
                raise ResultsError(
                    f"trial plan entry {index} needs an integer 'trial' key, found {entry!r}"
                )
            numbers.append(trial)
        if len(set(numbers)) != len(numbers):
            raise ResultsError("trial plan numbers a trial twice: each 'trial' must be unique")

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data["plan"] = [dict(e) for e in self.plan]
        data["servo_models"] = list(self.servo_models)
        data["resumed_at"] = list(self.resumed_at)
        data["machine"] = dict(self.machine)
        return data

    @classmethod
    def from_json(cls, data: Mapping[str, Any], where: str = "<manifest>") -> SessionManifest:
        try:
            return cls(**{
                **data,
                "plan": tuple(data["plan"]),
                "servo_models": tuple(data.get("servo_models", ())),
                "resumed_at": tuple(data.get("resumed_at", ())),
            })
        except (TypeError, KeyError) as error:
            raise ResultsError(f"{where}: not a pinarray session manifest ({error})") from None


def now_iso() -> str:
    """Local wall-clock time with its UTC offset, to the second, e.g. 2024-05-01T14:03:07+02:00."""
    return datetime.now().astimezone().isoformat(timespec="seconds")


def this_machine() -> dict[str, str]:
    """Platform and host name, recorded so results can be traced to the computer that ran them."""
    return {
        "hostname": socket.gethostname(),
        "platform": platform.platform(),
        "python": platform.python_version(),
    }


def new_manifest(
    paths: RunPaths,
    plan: Sequence[Mapping[str, Any]],
    *,
    seed: int | None,
    protocol_sha256: str,
    port: str,
    servo_models: Sequence[str] = (),
    experimenter: str = "",
) -> SessionManifest:
    """A ``running`` manifest for a run starting now on this machine, in this process."""
    started = now_iso()
    return SessionManifest(
        subject=paths.subject, session=paths.session, task=paths.task, run=paths.run,
        plan=tuple(dict(e) for e in plan), seed=seed, protocol_sha256=protocol_sha256,
        port=port, servo_models=tuple(str(m) for m in servo_models), experimenter=experimenter,
        machine=this_machine(), started_at=started, updated_at=started, pid=os.getpid(),
    )


def write_atomically(path: Path, text: str) -> None:
    """Replace ``path`` with ``text`` so that a crash leaves either the old or the new file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # The temporary file must be in the same folder: os.replace is atomic only within one
    # file system.
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            out.write(text)
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    fsync_folder(path.parent)


def fsync_folder(folder: Path) -> None:
    """Make a new or renamed file's name durable by syncing its folder entry (POSIX)."""
    # Windows cannot open folders; there the rename is already as durable as it gets.
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_manifest(path: Path, manifest: SessionManifest) -> None:
    """Write ``manifest`` to ``path`` atomically, as indented JSON."""
    write_atomically(path, json.dumps(manifest.to_json(), indent=2, ensure_ascii=False) + "\n")


def read_manifest(path: Path | str) -> SessionManifest:
    """Read a manifest written by `write_manifest`; a clear `ResultsError` if it is not one."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ResultsError(f"{path}: no session manifest here") from None
    except json.JSONDecodeError as error:
        raise ResultsError(f"{path}:{error.lineno}:{error.colno}: {error.msg}") from None
    return SessionManifest.from_json(data, str(path))


def set_status(path: Path | str, status: str, reason: str = "") -> SessionManifest:
    """Atomically set a manifest's status (and abort reason), stamping ``updated_at``."""
    path = Path(path)
    manifest = replace(read_manifest(path), status=status, abort_reason=reason,
                       updated_at=now_iso())
    write_manifest(path, manifest)
    return manifest


def find_unfinished(
    root: Path | str, subject: str, session: str | int | None = None, task: str | None = None
) -> list[tuple[RunPaths, SessionManifest]]:
    """Runs of ``subject`` whose manifest says running, crashed or aborted, oldest run first.

    A run killed outright (SIGKILL, power cut) still says ``running``: nothing was left alive
    to change it, which is why ``running`` counts as unfinished too.
    """
    subject = check_label("subject", subject)
    ses = "*" if session is None else check_label("session", session)
    tsk = "*" if task is None else check_label("task", task)
    pattern = f"sub-{subject}/ses-{ses}/beh/sub-{subject}_ses-{ses}_task-{tsk}_run-*_manifest.json"
    found = []
    for path in sorted(Path(root).glob(pattern)):
        manifest = read_manifest(path)
        if manifest.status in UNFINISHED_STATUSES:
            found.append((RunPaths.from_file(path), manifest))
    return sorted(found, key=lambda item: (item[0].session, item[0].task, item[0].run))
