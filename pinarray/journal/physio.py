"""A run's measured pin motion as a BIDS continuous recording: ``..._recording-motion_physio``.

Beside the run's ``beh.tsv``: a gzip-compressed TSV without a header (BIDS) holding every
sample of every moving pin, trial after trial, and its JSON naming the columns. The samples
are irregular (taken in the slack between frames, see
`pinarray.hardware.feetech.readback`): each row carries its own ``timestamp``, on the run's
time base as ``stimulus_onset`` in ``beh.tsv``. BIDS requires a number for
``SamplingFrequency`` in a physio sidecar (only NIRS may write ``n/a``), so the sidecar gives
the median rate of the first trial recorded and says that the timestamps are what count.

One gzip stream for the whole run (BIDS validators refuse a file of several gzip members):
`MotionRecording` compresses each trial's samples and flushes the stream to a whole block
boundary, then fsyncs, so every trial on disk can be read back even before the run closes
and writes the stream's end. A process killed meanwhile leaves a stream without its end (and
at most one torn block): a resumed writer keeps what reads back whole and starts the stream
again from it. The writer (`pinarray.journal.writer`) decides when.
"""

from __future__ import annotations

import os
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from pinarray.errors import ResultsError
from pinarray.journal.files import read_results_file, results_file
from pinarray.journal.paths import RunPaths
from pinarray.journal.timebase import ns_from_seconds
from pinarray.units import NS_PER_S

if TYPE_CHECKING:
    import numpy as np

    from pinarray.journal.records import TrialRecord

NA = "n/a"
# A run's recording, compressed: hours of every pin's samples, far more than any design.
MAX_RECORDING_BYTES = 1 << 30


class MotionSample(NamedTuple):
    """One pin's position at one instant of a trial; ``time_ns`` on the run's time base."""

    time_ns: int
    trial: int
    pin: int
    position_steps: int
    goal_steps: int | None  # the goal in force (None: before the trial's first change)


MOTION_NAMES = ("timestamp", "trial", "pin", "position", "goal")
MOTION_COLUMNS: dict[str, dict[str, Any]] = {
    "timestamp": {"Description": "When the servo sampled its position: seconds from the run's "
                                 "time zero, as stimulus_onset in the run's beh.tsv. Samples are "
                                 "irregular: this column, not SamplingFrequency, times them.",
                  "Units": "s"},
    "trial": {"Description": "The trial number (beh.tsv's trial column) the sample belongs to."},
    "pin": {"Description": "The pin sampled, numbered as in beh.tsv."},
    "position": {"Description": "The servo's Present Position (register 56): where its horn "
                                "was, in encoder steps.", "Units": "steps"},
    "goal": {"Description": "The goal position in force at that instant, in encoder steps; "
                            "n/a before the trial's first goal change.", "Units": "steps"},
}


def motion_recording_path(paths: RunPaths) -> Path:
    """Where a run's motion recording lives: beside its beh.tsv."""
    return paths.beh_dir / f"{paths.stem}_recording-motion_physio.tsv.gz"


def motion_sidecar(first: Sequence[MotionSample], task_name: str) -> dict[str, Any]:
    """The JSON that describes a run's motion recording, given its first trial's samples and
    the task's name (as the run's other sidecars give it)."""
    return {"TaskName": task_name, "PhysioType": "generic",
            "Description": "Where each moving pin was during each trial, sampled from its "
                           "servo in the slack between the stimulus's frames by pinarray.",
            "SamplingFrequency": median_rate_hz(first), "StartTime": 0,
            "Columns": list(MOTION_NAMES), **MOTION_COLUMNS}


def median_rate_hz(samples: Sequence[MotionSample]) -> float:
    """The median rate at which one pin was sampled, Hz (0 with fewer than two samples)."""
    by_pin: dict[int, list[int]] = {}
    for sample in samples:
        by_pin.setdefault(sample.pin, []).append(sample.time_ns)
    gaps = sorted(b - a for times in by_pin.values()
                  for a, b in zip(times, times[1:], strict=False) if b > a)
    return round(NS_PER_S / gaps[len(gaps) // 2], 1) if gaps else 0


@dataclass(frozen=True, eq=False)
class MotionColumns:
    """Samples column by column, in the recording's order: a run records tens of thousands,
    and a Python object per sample (a `MotionSample`) costs more than the trial's compute.

    Each a numpy array of one length: ``time_ns`` (int64, on the run's time base), ``trial``,
    ``pin``, ``position_steps`` and ``goal_steps`` (int64 steps), ``has_goal`` (bool: False
    before the trial's first goal change, where ``goal_steps`` means nothing).
    """

    time_ns: np.ndarray
    trial: np.ndarray
    pin: np.ndarray
    position_steps: np.ndarray
    goal_steps: np.ndarray
    has_goal: np.ndarray

    @classmethod
    def of(cls, samples: Sequence[MotionSample] | MotionColumns) -> MotionColumns:
        """``samples`` as columns, in their order (columns as they are)."""
        import numpy as np  # the journal reads and checks results without numpy

        if isinstance(samples, MotionColumns):
            return samples
        rows = np.array([(*s[:4], 0 if s.goal_steps is None else s.goal_steps, s.goal_steps
                          is not None) for s in samples], dtype=np.int64).reshape(-1, 6)
        time_ns, trial, pin, position, goal, has_goal = rows.T.copy()
        return cls(time_ns, trial, pin, position, goal, has_goal.astype(bool))

    def __len__(self) -> int:
        return len(self.time_ns)

    def samples(self) -> list[MotionSample]:
        """One `MotionSample` a row."""
        goals = [g if known else None
                 for g, known in zip(self.goal_steps.tolist(), self.has_goal.tolist(),
                                     strict=True)]
        return list(map(MotionSample, self.time_ns.tolist(), self.trial.tolist(),
                        self.pin.tolist(), self.position_steps.tolist(), goals))


def motion_lines(samples: Sequence[MotionSample] | MotionColumns) -> bytes:
    """The rows of ``samples``, tab-separated, as bytes; each time as
    `pinarray.journal.timebase.seconds_text` writes it.

    Built for all rows at once (tens of thousands a run): each line's characters laid out in
    a row of a byte matrix, beside a mask of those shown (a number's leading zeros, a time's
    trailing ones, the n/a or the goal), and the shown ones read out in row order.
    """
    import numpy as np  # the journal reads and checks results without numpy

    columns = MotionColumns.of(samples)
    count = len(columns)
    if not count:
        return b""
    whole, fraction = np.divmod(np.abs(columns.time_ns), NS_PER_S)
    fraction_digits = _digits(fraction, 9)
    # Trailing zeros dropped: the digits up to the last that is not 0 are shown (none of a
    # fraction 0, nor the point before it).
    last = 8 - np.argmax(fraction_digits[:, ::-1] != ord("0"), axis=1)
    fraction_shown = (np.arange(9) <= last[:, None]) & (fraction != 0)[:, None]
    tab = _text(b"\t")
    cells = [
        _decimal(whole, negative=columns.time_ns < 0),
        _text(b".", fraction != 0), (fraction_digits, fraction_shown), tab,
        _decimal(columns.trial), tab, _decimal(columns.pin), tab,
        _decimal(columns.position_steps), tab,
        _decimal(columns.goal_steps, shown=columns.has_goal),
        _text(NA.encode("ascii"), ~columns.has_goal), _text(b"\n"),
    ]
    width = sum(c.shape[-1] for c, _ in cells)
    chars, shown = np.empty((count, width), np.uint8), np.empty((count, width), bool)
    at = 0
    for cell_chars, cell_shown in cells:  # each broadcast to its rows as it is copied in
        end = at + cell_chars.shape[-1]
        chars[:, at:end], shown[:, at:end] = cell_chars, cell_shown
        at = end
    lines: bytes = chars[shown].tobytes()
    return lines


def _digits(values: np.ndarray, width: int) -> np.ndarray:
    """The decimal digits (ASCII) of non-negative ``values``, ``width`` of them a row, the
    leading ones 0."""
    import numpy as np

    digits = np.empty((len(values), width), np.uint8)
    # Unsigned, and 32 bits where the values fit: numpy divides those several times faster.
    rest: np.ndarray = values.astype(np.uint32 if width <= 9 else np.uint64)
    for place in range(width - 1, -1, -1):
        tens: np.ndarray = rest // 10
        digits[:, place] = rest - tens * 10
        rest = tens
    digits += ord("0")
    return digits


def _decimal(values: np.ndarray, negative: np.ndarray | None = None,
             shown: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The characters of integers ``values`` in decimal, a row each, and which of them are
    shown: a sign where ``negative`` (by default where the value is), then the digits but the
    leading zeros (0 itself shows one); none where not ``shown`` (by default all are)."""
    import numpy as np

    magnitude = np.abs(values)
    width = len(str(int(magnitude.max())))
    digits = _digits(magnitude, width)
    # Each digit is shown from the value's first: where the value reaches its place's power
    # of ten (the last place always).
    places = 10 ** np.arange(width - 1, -1, -1, dtype=np.int64)
    places[-1] = 0
    digit_shown = magnitude[:, None] >= places
    minus = values < 0 if negative is None else negative
    if minus.any():
        digits = np.concatenate([np.full((len(values), 1), ord("-"), np.uint8), digits], axis=1)
        digit_shown = np.concatenate([minus[:, None], digit_shown], axis=1)
    return digits, digit_shown if shown is None else digit_shown & shown[:, None]


def _text(text: bytes, shown: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | bool]:
    """``text`` on every row; shown on all of them, or on those where ``shown``."""
    import numpy as np

    return np.frombuffer(text, np.uint8), True if shown is None else shown[:, None]


class MotionRecording:
    """A run's motion recording open for appending: one gzip stream, flushed per trial.

    ``keep``: how many samples of what is on disk to keep (those the run's rows claim: a
    presentation whose row was never written, cut by a crash or a full disk, is played again
    and its samples dropped); None: every whole line.
    """

    def __init__(self, path: Path, keep: int | None = None):
        self.path = path
        kept = read_text(path) if results_file(path, "motion recording") else b""
        if keep is not None:
            kept = b"".join(kept.splitlines(keepends=True)[:keep])
        self._stream = zlib.compressobj(wbits=31)  # 31: a gzip header and trailer
        start = self._stream.compress(kept) + self._stream.flush(zlib.Z_FULL_FLUSH)
        temporary = path.with_name(path.name + ".tmp")
        # A new file: whatever is at that name (one left by a crash, a link to another file)
        # is removed, not written through.
        temporary.unlink(missing_ok=True)
        fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666)
        with os.fdopen(fd, "wb") as handle:
            handle.write(start)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
        self._file = open(path, "ab")  # noqa: SIM115

    @property
    def in_place(self) -> bool:
        """Whether the file this writes is still the one at its path (not deleted, moved or
        replaced meanwhile: samples appended to it would be lost with it)."""
        try:
            there = os.stat(self.path)
        except FileNotFoundError:
            return False
        mine = os.fstat(self._file.fileno())
        return (there.st_dev, there.st_ino) == (mine.st_dev, mine.st_ino)

    def append(self, samples: MotionColumns) -> None:
        """The samples compressed onto the stream, flushed to a whole block and fsync'd."""
        stream = self._stream
        self._file.write(stream.compress(motion_lines(samples)) + stream.flush(zlib.Z_FULL_FLUSH))
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        """End the stream (a whole gzip file from now on) and close it."""
        try:
            self._file.write(self._stream.flush(zlib.Z_FINISH))
            self._file.flush()
            os.fsync(self._file.fileno())
        finally:
            self._file.close()


def read_text(path: Path | str) -> bytes:
    """What a motion recording holds, uncompressed: all of it, or as far as it reads whole
    (a stream a killed process left without its end, or with a torn last block)."""
    data = read_results_file(Path(path), "motion recording", MAX_RECORDING_BYTES)
    stream = zlib.decompressobj(wbits=31)
    try:
        text = stream.decompress(data)
    except zlib.error:
        # A torn block: keep the blocks before it, each ending at a full flush's marker.
        text, end = b"", data.rfind(b"\x00\x00\xff\xff")
        while end > 0:
            try:
                text = zlib.decompressobj(wbits=31).decompress(data[:end + 4])
                break
            except zlib.error:
                end = data.rfind(b"\x00\x00\xff\xff", 0, end)
    return text[:text.rfind(b"\n") + 1]


def read_motion(path: Path | str) -> list[MotionSample]:
    """Every sample of a motion recording (one a killed process left: every whole trial's)."""
    text = read_text(path).decode("ascii")
    samples = []
    for line in text.splitlines():
        time, trial, pin, position, goal = line.split("\t")
        samples.append(MotionSample(ns_from_seconds(time), int(trial), int(pin), int(position),
                                    None if goal == NA else int(goal)))
    return samples


def claimed_samples(path: Path, records: Sequence[TrialRecord]) -> int | None:
    """How many samples of the recording at ``path`` the rows ``records`` claim (each row's
    ``motion_samples``, in row order), checked against what it holds; None when some row does
    not say (written before the count was kept: nothing to check). `ResultsError` naming
    both files when the recording holds fewer, or other trials' samples, than the rows say (it
    was deleted, cut or replaced), or samples of more than one presentation after them (rows
    were deleted: a crash leaves at most one presentation without its row), where resuming
    would lose samples, or present trials again, in silence."""
    counts = [r.motion_samples for r in records if r.motion_samples is not None]
    if len(counts) != len(records):
        return None
    claimed = sum(counts)
    try:
        held = read_motion(path) if results_file(path, "motion recording") else []
    except (OSError, ValueError) as problem:  # not a recording any more (UnicodeError too)
        raise ResultsError(f"{path}: cannot be read as the run's motion recording ({problem}); "
                           "put it back as it was to resume this run, or start a new run") from None
    keep = ("put it back as it was to resume this run, or start a new run (this one is left as "
            "it is)")
    at = 0
    for record, count in zip(records, counts, strict=True):
        mine = held[at:at + count]
        if len(mine) < count:
            found = "is missing" if not path.exists() else f"holds {len(held):,} samples"
            raise ResultsError(
                f"{path}: {found}, but the rows of the run's beh.tsv claim {claimed:,} (trial "
                f"{record.trial}'s are not all there): the motion recording was deleted, cut or "
                f"replaced; {keep}")
        other = next((s.trial for s in mine if s.trial != record.trial), None)
        if other is not None:
            raise ResultsError(
                f"{path}: holds trial {other}'s samples where the rows of the run's beh.tsv, in "
                f"their order, put trial {record.trial}'s: rows were deleted or moved, or the "
                f"recording replaced; put them back as they were to resume this run, or start a "
                "new run (this one is left as it is)")
        at += count
    unclaimed = sorted({s.trial for s in held[at:]})
    if len(unclaimed) > 1:
        raise ResultsError(
            f"{path}: holds samples of trials {', '.join(map(str, unclaimed))} that no row of "
            f"the run's beh.tsv claims (its {len(records)} row(s) claim {claimed:,} samples): "
            "rows were deleted from the beh.tsv; put them back to resume this run, or start a "
            "new run (this one is left as it is)")
    return claimed
