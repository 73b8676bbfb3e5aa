"""`pinarray compile --daq-rate HZ --out FILE.npz`: the 16 lines' samples for a DAQ card.

The archive holds every trial's samples back to back in one uint16 array, ``samples`` (bit
``n - 1`` = pin ``n``), and where each trial's run of them begins and how long it is. Between
trials there is nothing: a sitting waits for the subject's answer and then the protocol's
inter-trial interval, which no file can know, so a lab plays one trial's run as one finite
hardware-timed task at the trial's onset. Each run ends on a sample low on every line, so the
lines rest low after it.

The samples are streamed into their ``.npy`` member a block at a time as each trial is
compiled (ZIP64, stored, as `np.savez` writes): memory is one trial's pulse list and a few
blocks, never the samples of a trial, let alone of the file.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from fractions import Fraction
from typing import TYPE_CHECKING

from pinarray.cli import common
from pinarray.errors import PinArrayError

if TYPE_CHECKING:
    from pinarray.plan import PlannedTrial, TrialPlan
    from pinarray.protocol import Protocol
    from pinarray.schedule import TrialSchedule

# The work a samples file may take: 10 000 000 000 samples are 20 GB, written in about a
# minute here (an hour of the seed train at 100 kHz, 360 000 000 samples, takes 2 s). A 48 h
# train at 10 MHz would be 1.7e12 samples, 3.5 TB: refused with what to change.
MAX_DAQ_SAMPLES = 10_000_000_000
SAMPLES_PER_S = MAX_DAQ_SAMPLES / 60  # written here, about
SAMPLE_BYTES = 2

# A trial's condition as columns of the archive: (name, dtype, value when it does not apply).
_CONDITION_COLUMNS = (
    ("block", "int32", 0),
    ("practice", "bool", False),
    ("stimulus", "U", ""),
    ("pin", "int16", 0),
    ("frequency_hz", "float64", float("nan")),
    ("direction", "U", ""),
    ("row", "int16", 0),
)


def check_out(path: str) -> None:
    """Refuse an ``--out`` that cannot hold the samples: they are a numpy archive, named so."""
    if not path.lower().endswith(".npz"):
        raise PinArrayError(
            f"--daq-rate: expected --out FILE.npz (the samples are a numpy archive), found {path!r}"
        )


class DaqSamples:
    """The samples archive of one plan.

    The trials' lengths are known from their drives before anything is compiled, so the
    samples' header is written first and each trial streamed into it as it is compiled; a pin
    past the 16 lines is refused before the file is opened. The file is opened at once so
    that an unwritable path fails before the compile.
    """

    def __init__(self, path: str, protocol: Protocol, plan: TrialPlan, rate_hz: int) -> None:
        import numpy as np

        from pinarray.protocol.drives import trial_drives
        from pinarray.schedule import DAQ_LINES, daq_sample_count

        self.plan, self.rate_hz = plan, rate_hz
        counts = []
        for planned in plan.trials:
            drives = trial_drives(protocol, planned.condition)
            for drive in drives:
                if drive.pin > DAQ_LINES:
                    raise PinArrayError(
                        f"{protocol.source}: trial {planned.trial} drives pin {drive.pin}: "
                        f"expected pins 1 to {DAQ_LINES}, one per line of the DAQ's uint16 "
                        "samples")
            # The trial's end as the schedule computes it: its last drive's end.
            end_ns = max((d.delay_ns + d.train.duration_ns for d in drives), default=0)
            counts.append(daq_sample_count(end_ns, rate_hz))
        self.counts = np.array(counts, dtype=np.int64)
        self.firsts = np.concatenate(([0], np.cumsum(self.counts)[:-1])).astype(np.int64)
        _check_work(path, self.total, rate_hz)
        self.output = common.OutputFile(path, binary=True)

    @property
    def total(self) -> int:
        """Samples in the file, every trial's."""
        return int(self.counts.sum())

    def write(self, trials: Iterable[tuple[PlannedTrial, TrialSchedule]]) -> None:
        """Write the archive from every trial of the plan, compiled, in plan order."""
        import zipfile

        import numpy as np

        from pinarray.cli.protocols import _cannot_write, _Unseekable

        # A device: zipfile would trust its position (/dev/null's stays 0) for the offsets.
        device = self.output.temporary is None
        stream = _Unseekable(self.output.stream) if device else self.output.stream
        try:
            with zipfile.ZipFile(stream, "w", zipfile.ZIP_STORED) as archive:
                with archive.open("samples.npy", "w", force_zip64=True) as member:
                    header = {"descr": "<u2", "fortran_order": False, "shape": (self.total,)}
                    np.lib.format.write_array_header_1_0(member, header)
                    self._write_samples(member, trials)
                for name, array in self._layout().items():
                    with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                        np.lib.format.write_array(member, array, allow_pickle=False)
        except OSError as problem:
            _cannot_write(self.output, problem)
        self.output.flush()

    def _write_samples(self, member, trials: Iterable[tuple[PlannedTrial, TrialSchedule]]):
        from pinarray.schedule import daq_words

        written = 0
        tell = common.progress("compile: samples written", self.total,
                               self.total / SAMPLES_PER_S)
        for planned, schedule in trials:
            index = planned.trial - 1
            assert written == self.firsts[index], "trials come in plan order"
            for words in daq_words(schedule.pulses, self.rate_hz, int(self.counts[index])):
                member.write(words)
                written += len(words)
                tell(written)
        assert written == self.total

    def _layout(self) -> dict:
        """The sample rate, and per trial its run of samples and its condition."""
        import numpy as np

        records = [t.record() for t in self.plan.trials]
        for record in records:  # a float to compute with; `plan` keeps the exact fraction
            if record["frequency_hz"] is not None:
                record["frequency_hz"] = float(Fraction(record["frequency_hz"]))
        return {
            "sample_rate_hz": np.array(self.rate_hz, dtype=np.int64),
            "trial": np.array([r["trial"] for r in records], dtype=np.int32),
            "trial_first_sample": self.firsts,
            "trial_sample_count": self.counts,
            **{f"trial_{name}": np.array([default if r[name] is None else r[name]
                                          for r in records], dtype=dtype)
               for name, dtype, default in _CONDITION_COLUMNS},
            "plan": np.array(self.plan.to_json()),  # the seed, and the exact frequencies
        }


def _check_work(path: str, total: int, rate_hz: int) -> None:
    """Refuse, before anything is written, samples that would take too long or not fit on the
    disk: one line with the size and what to change."""
    from pinarray.units import duration_words

    size = total * SAMPLE_BYTES
    if total > MAX_DAQ_SAMPLES:
        fits = max(1, rate_hz * MAX_DAQ_SAMPLES // total)
        raise PinArrayError(
            f"--daq-rate: {total:,} samples at {rate_hz:,} Hz, a file of {_bytes(size)} (about "
            f"{duration_words(total / SAMPLES_PER_S)} to write); at most "
            f"{MAX_DAQ_SAMPLES:,} samples: lower --daq-rate (at most {fits:,} Hz for this plan) "
            "or compile fewer or shorter trials")
    if os.path.exists(path) and not os.path.isfile(path):
        return  # a device such as /dev/null: no disk to fill
    folder = os.path.dirname(os.path.realpath(path))
    try:
        info = os.statvfs(folder)
    except OSError:
        return  # the output's own open says what is wrong with the folder
    free = info.f_bavail * info.f_frsize
    if size > free:
        raise PinArrayError(f"{path}: cannot write: {total:,} samples take {_bytes(size)}, the "
                            f"disk has {_bytes(free)} free; lower --daq-rate or make room")


def _bytes(size: int) -> str:
    for unit, scale in (("TB", 10**12), ("GB", 10**9), ("MB", 10**6), ("kB", 10**3)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size} bytes"
