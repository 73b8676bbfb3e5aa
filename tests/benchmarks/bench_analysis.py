"""Cost of crash-safe rows and of analysis, and what a study of N simulated subjects shows.

Timings are printed, never asserted. The study table answers "how many subjects do I need?"
for the seed's localisation design (8 pins x 3 frequencies, one trial each per subject):
how often the pooled correct rate comes out rising 3 < 5 < 10 Hz and error A on top.
"""

import tempfile
import time
from pathlib import Path

import numpy as np

from pinarray.analysis.load import load_results
from pinarray.analysis.stats import localisation_by_frequency, summarise_subjects
from pinarray.grid import classify
from pinarray.observer import ObserverModel, SimulatedObserver
from pinarray.results import RunWriter, TrialRecord

PINS = (1, 4, 6, 7, 10, 11, 13, 16)
FREQUENCIES_HZ = (3.0, 5.0, 10.0)


def _localisation_rows(observer: SimulatedObserver) -> list[TrialRecord]:
    rows = []
    for n, (pin, frequency) in enumerate(
        ((p, f) for p in PINS for f in FREQUENCIES_HZ), start=1
    ):
        answer = observer.respond_localisation(pin, frequency)
        rows.append(TrialRecord(
            trial=n, block=1, task="localisation", onset_s=12.0 * n, duration_s=10.0,
            response=str(answer) if answer else "none", pin=pin, frequency_hz=frequency,
            error_class=classify(pin, answer) if answer else "none"))
    return rows


def _bench_writing(root: Path, rows: int) -> None:
    observer = SimulatedObserver(seed=0)
    records = (_localisation_rows(observer) * (rows // 24 + 1))[:rows]
    writer = RunWriter.start(root, "bench", 1, "localisation", [{"trial": 1}], seed=0,
                             protocol_sha256="", port="sim://")
    started = time.perf_counter()
    for record in records:
        writer.write_trial(record)
    elapsed = time.perf_counter() - started
    writer.finish()
    print(f"{'rows written (fsync each)':<34} {rows:>8} {1e3 * elapsed / rows:>10.3f} ms/row")
    started = time.perf_counter()
    loaded = load_results([root])
    summarise_subjects((t.subject, t.record) for t in loaded)
    elapsed = time.perf_counter() - started
    print(f"{'rows loaded and summarised':<34} {len(loaded):>8} "
          f"{1e6 * elapsed / len(loaded):>10.1f} us/row")


def _study_table(repeats: int) -> None:
    model = ObserverModel(calibration_pins=PINS)
    expected = [model.expected_localisation(f)["correct"] for f in FREQUENCIES_HZ]
    print("\nexpected correct at 3/5/10 Hz on the seed's 8 pins: "
          + " / ".join(f"{100 * e:.1f} %" for e in expected))
    print(f"{'subjects':>8} {'10 Hz mean':>10} {'10 Hz sd':>9} {'3<5<10':>8} {'A on top':>9}")
    rng = np.random.default_rng(2024)
    for subjects in (4, 8, 16, 32):
        tens, rising, a_top = [], 0, 0
        for _ in range(repeats):
            rows = [r for _ in range(subjects)
                    for r in _localisation_rows(SimulatedObserver(model, seed=rng))]
            by_frequency = localisation_by_frequency(rows)
            correct = [row.correct.pct for row in by_frequency]
            tens.append(correct[-1])
            rising += correct[0] < correct[1] < correct[2]
            a_top += all(row.error_counts[0] > max(row.error_counts[1:]) for row in by_frequency)
        print(f"{subjects:>8} {np.mean(tens):>9.1f}% {np.std(tens):>8.1f}% "
              f"{100 * rising / repeats:>7.0f}% {100 * a_top / repeats:>8.0f}%")


def run() -> None:
    print(f"{'what':<34} {'count':>8} {'cost':>13}")
    with tempfile.TemporaryDirectory() as folder:
        _bench_writing(Path(folder), 2000)
    _study_table(repeats=200)
