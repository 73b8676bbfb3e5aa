"""The ``--i2c-log`` file: every I2C message as a logic analyser decodes it, one line each.

``t_ns addr rw data_hex ack`` (`I2cMessage.log_line`), t_ns from the onset of the trial the
message belongs to. The driver calls `I2cLog.trial_onset` just before a trial's first timed
write and `I2cLog.trial_end` when the trial is over; what the bus carried between a trial's
end (or the start) and the next onset (arming writes, read-backs) is held back and written
relative to that next onset, so those lines have negative times. The file is flushed and
synced at every trial's end and at `I2cLog.close`, which writes what is still held relative to
the last onset (0 before any).

Memory stays bounded: no more than ``max_held`` messages are held back; past that the oldest
are written relative to the last onset (0 before any), as `close` would.
"""

from __future__ import annotations

import os
from collections import deque
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.hardware.pca9685.i2c import I2cMessage

DEFAULT_MAX_HELD = 65_536


class I2cLog:
    """A listener for an `I2cLink` writing the log file at ``path``."""

    def __init__(self, path: str | Path, max_held: int = DEFAULT_MAX_HELD, append: bool = False):
        """``append``: add to the file (the player process, beside the parent's lines)."""
        try:
            self._file = open(path, "a" if append else "w", encoding="ascii")  # close()
        except OSError as error:
            raise ResultsError(f"cannot write the I2C log {path}: {error.strerror}") from None
        self._path = path
        self._held: deque[I2cMessage] = deque()
        self._max_held = max_held
        self._onset_ns: int | None = None
        self._in_trial = False

    def __call__(self, message: I2cMessage) -> None:
        if self._in_trial:
            self._write(message, self._onset_ns or 0)
            return
        self._held.append(message)
        if len(self._held) > self._max_held:
            self._write(self._held.popleft(), self._onset_ns or 0)

    def trial_onset(self, onset_ns: int) -> None:
        """A trial starts at ``onset_ns`` (clock time): what was held is written relative to it."""
        self._onset_ns = onset_ns
        self._in_trial = True
        self._release(onset_ns)

    def trial_end(self) -> None:
        """The trial is over: later messages wait for the next onset. Flushed to disk."""
        self._in_trial = False
        self._sync()

    def close(self) -> None:
        if self._file.closed:
            return
        self._release(self._onset_ns or 0)
        self._sync()
        self._file.close()

    def _release(self, onset_ns: int) -> None:
        while self._held:
            self._write(self._held.popleft(), onset_ns)

    def _write(self, message: I2cMessage, onset_ns: int) -> None:
        try:
            self._file.write(message.log_line(onset_ns) + "\n")
        except OSError as error:
            raise ResultsError(f"cannot write the I2C log {self._path}: {error.strerror}") from None

    def _sync(self) -> None:
        try:
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as error:
            raise ResultsError(f"cannot write the I2C log {self._path}: {error.strerror}") from None
