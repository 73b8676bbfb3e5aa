"""Cost of crash-safe rows and of the analysis, and how many subjects the seed's designs need.

Timings are printed, never asserted: each beside a reference measured in the same run, with
the ratio, min/median/max over repeats. The study tables answer "how many subjects do I
need?" with simulated subjects who differ from one another (`pinarray.paradigms.localisation.observer`), analysed
with subjects as the unit (`pinarray.analysis.power`), as `pinarray power` prints them.
"""

import csv
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from pinarray.analysis.load import load_runs, select_runs
from pinarray.analysis.power import power_study
from pinarray.analysis.seam import analysis_of
from pinarray.analysis.study import study
from pinarray.grid import classify
from pinarray.journal.rows import trial_row
from pinarray.paradigms.localisation.frequency_effect import Cell, _Data, fit_frequency_effect
from pinarray.paradigms.localisation.observer import ObserverModel, SimulatedObserver
from pinarray.paradigms.localisation.power import protocol_design, simulate_subject
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.protocol.load import load_protocol
from tests.runs import plan_of, start_run

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
REPEATS = 5


def _timed(action: Callable[[], object], repeats: int = REPEATS) -> list[float]:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        action()
        times.append(time.perf_counter() - started)
    return times


def _row(what: str, unit: str, scale: float, measured: list[float], reference: list[float],
         reference_name: str) -> None:
    cells = [scale * min(measured), scale * statistics.median(measured), scale * max(measured)]
    ref = scale * statistics.median(reference)
    print(f"{what:<34} {cells[0]:>9.3f} {cells[1]:>9.3f} {cells[2]:>9.3f} {unit:<7} "
          f"{ref:>9.3f}  {cells[1] / ref:>7.1f}x  {reference_name}")


def _localisation_rows(observer: SimulatedObserver, pins, frequencies) -> list[LocalisationRecord]:
    rows = []
    for n, (pin, frequency) in enumerate(((p, f) for p in pins for f in frequencies), start=1):
        answer = observer.respond_localisation(pin, frequency)
        rows.append(LocalisationRecord(
            trial=n, block=1, task="localisation", onset_ns=12 * n * 10**9, duration_ns=10**10,
            response=str(answer) if answer else "none", pin=pin, frequency_hz=frequency,
            error_class=classify(pin, answer) if answer else "none"))
    return rows


def costs(root: Path) -> None:
    protocol = load_protocol(PROTOCOLS / "localisation.yaml")
    design = protocol_design(protocol)
    model = ObserverModel().for_protocol(protocol)
    print(f"{'what':<34} {'min':>9} {'median':>9} {'max':>9} {'unit':<7} {'reference':>9}  "
          f"{'ratio':>8}  reference is")
    rows = 400
    once = _localisation_rows(SimulatedObserver(model, seed=0), design.pins, design.frequencies_hz)
    # Numbered 1..rows: a run holds one ok row per trial.
    records = [replace(r, trial=n) for n, r in enumerate((once * (rows // len(once) + 1))[:rows],
                                                          start=1)]
    run = iter(range(1, 10_000))

    def write_fsynced() -> None:
        writer = start_run(root / "writes", f"w{next(run)}", "localisation", plan_of(records))
        for record in records:
            writer.write_trial(record)
        writer.finish()

    def write_plain() -> None:
        with open(root / "plain.tsv", "w", encoding="utf-8") as out:
            for record in records:
                out.write("\t".join(trial_row(record)) + "\n")

    _row("row written (fsync each)", "ms/row", 1e3 / rows, _timed(write_fsynced),
         _timed(write_plain), "plain write, no fsync")

    # A study of 24 subjects' localisation runs, read and analysed as `analyse` does.
    data = root / "study"
    rng_seed = iter(range(1000))
    for s in range(24):
        observer = SimulatedObserver(model, seed=next(rng_seed))
        rows = _localisation_rows(observer, design.pins, design.frequencies_hz)
        writer = start_run(data, f"S{s}", "localisation", plan_of(rows))
        for record in rows:
            writer.write_trial(record)
        writer.finish()
    files = sorted(data.rglob("*_beh.tsv"))
    trials = 24 * len(design.trials)

    def analysed() -> None:
        study(select_runs(load_runs([data])))

    def parsed() -> None:
        for path in files:
            with open(path, newline="", encoding="utf-8") as handle:
                list(csv.reader(handle, delimiter="\t"))

    _row(f"load + analyse (24 subj., {trials} rows)", "ms", 1e3, _timed(analysed, 3),
         _timed(parsed), "csv.reader of the same files")

    cells = [Cell(f"S{s}", f, (s + int(f)) % 8, 8) for s in range(8) for f in (3.0, 5.0, 10.0)]
    data_8 = _Data(cells, 25)
    _row("mixed-effects fit (8 subjects)", "ms", 1e3, _timed(lambda: fit_frequency_effect(cells)),
         _timed(lambda: [data_8.negative_log_likelihood(0.0, 0.5, -0.5) for _ in range(10)]),
         "10 likelihood evaluations")

    bare = SimulatedObserver(model, seed=1)

    def bare_answers() -> None:
        for pin, frequency in design.trials * 50:
            bare.respond_localisation(pin, frequency)

    def fresh_subjects() -> None:
        for k in range(50):
            simulate_subject(design, SimulatedObserver(model, seed=k))

    _row("simulated subject (24 trials)", "ms", 1e3 / 50, _timed(fresh_subjects),
         _timed(bare_answers), "24 answers of one ready subject")


def study_tables(studies: int) -> None:
    for name in ("localisation.yaml", "apparent_motion.yaml"):
        protocol = load_protocol(PROTOCOLS / name)
        # each paradigm's own power model, as `pinarray power` builds it (its default subjects)
        model = analysis_of(protocol.design.paradigm.name).power(protocol, "default")
        assert model is not None
        curves = power_study(protocol.name, model, [4, 6, 8, 12, 16, 24, 32], studies,
                             seed=2024)
        print(f"\n{protocol.name}: {studies} simulated studies per number of subjects, "
              f"subject SD {model.subject_sd:g} logit, seed 2024")
        for line in curves.table_lines():
            print(line)


def run() -> None:
    with tempfile.TemporaryDirectory() as folder:
        costs(Path(folder))
    study_tables(studies=200)
