"""A run's scanner volumes: every trigger received, with its arrival time and what was odd about it.

A run timed from a scanner (``--trigger``) keeps a volume log beside its manifest, in
``sourcedata/``: one row per volume the trigger delivered (dummy volumes included) and one
per volume that should have come and did not, with the arrival in seconds from the run's time
zero (the first counted volume), so ``onset`` here and in ``events.tsv`` share one clock.

Why a companion file and not ``trial_type`` rows in ``events.tsv``: analysis tools build one
regressor per ``trial_type`` of an events file (nilearn's first-level models, FitLins), so a
"volume" condition there would be modelled as a stimulus. BIDS has no file for trigger
arrival times (``_physio.tsv.gz`` is a sampled signal); ``sourcedata/`` is the lab's own and
the validator leaves it alone. The JSON beside the log describes its columns.

Formatting and parsing only; the writer appends rows (`pinarray.journal.writer`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

from pinarray.journal.paths import RunPaths
from pinarray.journal.timebase import ns_from_seconds, seconds_text

NA = "n/a"


class VolumeStatus(StrEnum):
    """What a volume's trigger did."""

    RECEIVED = "received"  # on time: within the tolerance of one TR after the previous one
    IRREGULAR = "irregular"  # arrived, but off the expected time by more than the tolerance
    MISSED = "missed"  # expected from the TR, never arrived (a gap in the trigger stream)
    EXTRA = "extra"  # within half a TR of the previous volume's trigger: not a new volume


VOLUME_STATUS_MEANING = {
    VolumeStatus.RECEIVED: "the trigger arrived where the TR put it (within the tolerance)",
    VolumeStatus.IRREGULAR: "the trigger arrived, off its expected time by more than the "
                            "tolerance (TR jitter, or a late or extra character)",
    VolumeStatus.MISSED: "no trigger came for a volume the TR says was acquired: onset is "
                         "when it was expected",
    VolumeStatus.EXTRA: "a second trigger within half a TR of the volume's own (a repeated "
                        "character): not a new volume; volume is the one it repeats",
}


@dataclass(frozen=True)
class VolumeRow:
    """One volume of the log. Times in ns; ``onset_ns`` from the run's time zero.

    ``volume`` numbers volumes as the scanner acquired them, 1 = the first trigger received;
    a missed volume gets the number it would have had. ``interval_ns`` is the time since the
    previous trigger received and ``deviation_ns`` how far the arrival was from where the TR
    put it; both None where they do not apply (the first volume, a missed one, no TR yet).
    """

    volume: int
    onset_ns: int
    dummy: bool
    status: VolumeStatus
    interval_ns: int | None = None
    deviation_ns: int | None = None

    @property
    def counted(self) -> bool:
        return not self.dummy


@dataclass(frozen=True)
class ScannerRecord:
    """What a run's manifest says about its scanner: trigger, dummies, TR, locking, the log."""

    trigger: str
    dummy_volumes: int
    repetition_time_ns: int | None  # None: taken from the volumes
    lock_to_volumes: int
    tolerance_ns: int | None  # irregular beyond this; None until the TR is known
    volume_log: str = ""  # the log's path from the results root (`RunWriter.start` sets it)

    def to_json(self) -> dict[str, Any]:
        return {"trigger": self.trigger, "dummy_volumes": self.dummy_volumes,
                "repetition_time_s": _seconds_or_none(self.repetition_time_ns),
                "lock_to_volumes": self.lock_to_volumes,
                "tolerance_s": _seconds_or_none(self.tolerance_ns),
                "volume_log": self.volume_log}

    @classmethod
    def from_json(cls, data: Any) -> ScannerRecord:
        def ns(key: str) -> int | None:
            value = data.get(key)
            return None if value is None else ns_from_seconds(str(value))

        return cls(str(data["trigger"]), int(data["dummy_volumes"]), ns("repetition_time_s"),
                   int(data.get("lock_to_volumes", 0)), ns("tolerance_s"), str(data["volume_log"]))


def _seconds_or_none(ns: int | None) -> float | None:
    return None if ns is None else float(seconds_text(ns))


VOLUME_NAMES = ("onset", "volume", "dummy", "status", "interval", "deviation")
VOLUME_COLUMNS = {
    "onset": {"Description": "When the volume's trigger arrived, in seconds from the run's time "
                             "zero (the first counted volume): negative for dummy volumes; for "
                             "a missed volume, when it was expected. Same clock as onset in "
                             "the run's beh.tsv and events.tsv.", "Units": "s"},
    "volume": {"Description": "Volume number in acquisition order, 1 = the first trigger "
                              "received; a missed volume has the number it would have had."},
    "dummy": {"Description": "Whether the volume was a dummy (logged, not counted).",
              "Levels": {"true": "dummy volume, before time zero", "false": "counted volume"}},
    "status": {"Description": "What the volume's trigger did.",
               "Levels": {str(k): v for k, v in VOLUME_STATUS_MEANING.items()}},
    "interval": {"Description": "Time since the previous trigger received; n/a for the first "
                                "and for missed volumes.", "Units": "s"},
    "deviation": {"Description": "Arrival minus where the TR put it (the previous trigger plus "
                                 "one TR per volume since); n/a until the TR is known.",
                  "Units": "s"},
}


def volume_log_path(paths: RunPaths) -> Path:
    """Where a run's volume log lives: beside its manifest in ``sourcedata/``."""
    return paths.source_dir / f"{paths.stem}_volumes.tsv"


def volume_sidecar(record: ScannerRecord) -> dict[str, Any]:
    """The JSON that describes a run's volume log."""
    return {"Description": "Scanner volumes as the trigger delivered them, written by pinarray.",
            "Trigger": record.trigger, "DummyVolumes": record.dummy_volumes,
            "RepetitionTime": _seconds_or_none(record.repetition_time_ns),
            "ToleranceSeconds": _seconds_or_none(record.tolerance_ns),
            **VOLUME_COLUMNS}


def volume_cells(row: VolumeRow) -> list[str]:
    def seconds(ns: int | None) -> str:
        return NA if ns is None else seconds_text(ns)

    return [seconds_text(row.onset_ns), str(row.volume), "true" if row.dummy else "false",
            row.status.value, seconds(row.interval_ns), seconds(row.deviation_ns)]
