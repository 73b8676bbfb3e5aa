"""Where a run's files live: BIDS labels and the layout under a results root.

A results root is a BIDS dataset. Each run's data files are BIDS behaviour files::

    sub-<subject>/ses-<session>/beh/sub-<subject>_ses-<session>_task-<task>_run-<k>_beh.tsv
                                   ..._beh.json       column descriptions (sidecar)
                                   ..._events.tsv     stimulus timing for imaging analyses
                                   ..._events.json

and its provenance, which BIDS has no file for, lives under ``sourcedata/`` (which BIDS
leaves to the lab and the validator does not read), mirroring that layout::

    sourcedata/sub-<subject>/ses-<session>/beh/<same stem>_manifest.json  plan, seed, sittings, status
                                              <same stem>.lock            the writer's lock, while open

Runs written before the manifests moved have ``_manifest.json`` beside the data; they are
still read (and moved on resume).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from pathlib import Path

from pinarray.errors import ResultsError

DEFAULT_RESULTS_ROOT = Path("results")
SOURCEDATA = "sourcedata"
_LABEL = re.compile(r"[A-Za-z0-9]+")
_RUN_FILE = re.compile(
    r"sub-(?P<sub>[A-Za-z0-9]+)_ses-(?P<ses>[A-Za-z0-9]+)_task-(?P<task>[A-Za-z0-9]+)"
    r"_run-(?P<run>[0-9]+)(?:_(?P<suffix>[a-z]+)\.(?P<ext>tsv|json)|\.lock)$"
)


# What the system takes: a file name of at most 255 bytes, a path of at most 4095 (Linux's
# NAME_MAX and PATH_MAX). The longest name a run writes is its motion recording's sidecar while
# it is written (`journal.files.write_atomically`: ".<name>.<8 characters>.tmp"): this many
# bytes beyond the run's stem.
NAME_MAX_BYTES = 255
PATH_MAX_BYTES = 4095
BEYOND_STEM_BYTES = len("._recording-motion_physio.json.12345678.tmp")


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
    """The files of one run under a results ``root``: the ``subject``, ``session`` and ``task``
    labels (checked on construction) and the ``run`` number."""

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
        self._check_fits()

    def _check_fits(self) -> None:
        """Every file of the run can be written by the name it would have: refused here, before
        anything is, rather than by the system once the dataset's first files are."""
        name = len(self.stem.encode()) + BEYOND_STEM_BYTES
        path = len(os.fsencode(self.source_dir)) + 1 + name
        if name <= NAME_MAX_BYTES and path <= PATH_MAX_BYTES:
            return
        labels = (f"the subject label of {len(self.subject)} characters, the session's of "
                  f"{len(self.session)} and the task's of {len(self.task)}")
        if name > NAME_MAX_BYTES:
            raise LabelError(
                f"expected labels that fit a file name of at most {NAME_MAX_BYTES} bytes, found "
                f"{labels}: the run's longest file name would be {name} bytes; shorten the "
                "subject label or the protocol's name")
        raise LabelError(
            f"expected a results folder whose run files fit a path of at most {PATH_MAX_BYTES} "
            f"bytes, found one of {len(os.fsencode(self.root))} bytes with {labels}: the run's "
            f"longest path would be {path} bytes")

    @property
    def label(self) -> str:
        """The run in words, e.g. ``sub-01 ses-1 task-localisation run-2``."""
        return f"sub-{self.subject} ses-{self.session} task-{self.task} run-{self.run}"

    @property
    def relative_dir(self) -> Path:
        """``sub-<id>/ses-<n>/beh``: the run's folder below the results root."""
        return Path(f"sub-{self.subject}", f"ses-{self.session}", "beh")

    @property
    def beh_dir(self) -> Path:
        """The folder of the run's data files."""
        return self.root / self.relative_dir

    @property
    def source_dir(self) -> Path:
        """Where the run's provenance lives: ``sourcedata/`` mirrors the data's folders."""
        return self.root / SOURCEDATA / self.relative_dir

    @property
    def stem(self) -> str:
        """``sub-<id>_ses-<n>_task-<task>_run-<k>``: what every file name of the run starts with."""
        return f"sub-{self.subject}_ses-{self.session}_task-{self.task}_run-{self.run}"

    def file(self, suffix: str, ext: str) -> Path:
        """The run's data file ``<stem>_<suffix>.<ext>``."""
        return self.beh_dir / f"{self.stem}_{suffix}.{ext}"

    @property
    def beh_tsv(self) -> Path:
        """The trial rows (``_beh.tsv``)."""
        return self.file("beh", "tsv")

    @property
    def events_tsv(self) -> Path:
        """The stimulus events for imaging analyses (``_events.tsv``)."""
        return self.file("events", "tsv")

    @property
    def beh_json(self) -> Path:
        """The rows' sidecar: every column described."""
        return self.file("beh", "json")

    @property
    def events_json(self) -> Path:
        """The events' sidecar."""
        return self.file("events", "json")

    @property
    def manifest(self) -> Path:
        """The run's manifest in ``sourcedata/``: plan, seed, provenance, sittings, status."""
        return self.source_dir / f"{self.stem}_manifest.json"

    @property
    def legacy_manifest(self) -> Path:
        """Where pinarray wrote the manifest before it moved to ``sourcedata/``."""
        return self.file("manifest", "json")

    @property
    def lock(self) -> Path:
        """The lock file held while a process writes the run."""
        return self.source_dir / f"{self.stem}.lock"

    def manifest_on_disk(self) -> Path | None:
        """The run's manifest file, where it is (``sourcedata/`` or beside the data), or None."""
        for path in (self.manifest, self.legacy_manifest):
            if path.exists():
                return path
        return None

    @classmethod
    def from_file(cls, path: Path | str) -> RunPaths:
        """The run a file belongs to (data, sidecar, manifest or lock), with its results root."""
        path = Path(path)
        match = _RUN_FILE.fullmatch(path.name)
        if not match:
            raise ResultsError(
                f"{path}: not a pinarray run file; expected "
                "sub-<id>_ses-<n>_task-<task>_run-<k>_<beh|events|manifest>.<tsv|json>"
            )
        root = path.parent.parent.parent.parent  # <root>/sub-X/ses-Y/beh/<file>
        if root.name == SOURCEDATA:
            root = root.parent
        return cls(root, match["sub"], match["ses"], match["task"], int(match["run"]))


def runs_of(root: Path | str, subject: str, session: str | int, task: str) -> list[RunPaths]:
    """Existing runs of one subject, session and task (any file of theirs), by run number."""
    probe = RunPaths(Path(root), subject, str(session), task, 1)
    prefix = f"sub-{probe.subject}_ses-{probe.session}_task-{probe.task}_run-"
    found = {
        RunPaths.from_file(p).run
        for folder in (probe.beh_dir, probe.source_dir)
        for p in folder.glob(prefix + "*")
        if _RUN_FILE.fullmatch(p.name)
    }
    return [replace(probe, run=k) for k in sorted(found)]


def has_files(paths: RunPaths) -> bool:
    """Whether the run has data or a manifest (a lock alone is only a claim on its number)."""
    return any(p.exists() for p in (paths.beh_tsv, paths.manifest, paths.legacy_manifest))
