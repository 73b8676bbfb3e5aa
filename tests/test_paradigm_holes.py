"""The holes a hostile pass found in the lab's paradigms (issue 46, items 3-6, their paradigm
side), each closed through the paradigm seam and each tested here as the pass found it: rows
edited by hand, results files that are no files, a PSS from coin flips, resumes that hung or
ended in a traceback, protocols that ended in an AssertionError, repeated observer keys."""

import json
import math
import os
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pinarray
from pinarray.analysis.load import (
    DamagedResults,
    LoadedTrial,
    ManifestState,
    RunSelection,
    load_runs,
    select_runs,
)
from pinarray.analysis.seam import Context, EstimateStatus
from pinarray.analysis.subjects import IntervalSettings
from pinarray.analysis.tables import number, significant
from pinarray.errors import PinArrayError, ProtocolErrors, ResultsError
from pinarray.grid import Grid
from pinarray.paradigms.temporal_order.analysis import PSS_UNRESOLVED, temporal_orders
from pinarray.paradigms.temporal_order.rows import TemporalOrderRecord
from pinarray.plan import make_plan
from pinarray.protocol.load import parse_protocol
from tests.commands import pinarray_forked, pinarray_here
from tests.lab_protocols import short_copy

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
CONTEXT = Context(RunSelection((), (), False), IntervalSettings(), Grid())


def run_cut_short(protocol_path: Path, results: Path, answers: int = 3) -> Path:
    """A run of ``protocol_path`` stopped after ``answers`` answers: its beh.tsv."""
    protocol = pinarray.load_protocol(protocol_path)
    answer = pinarray.simulated_observer(protocol, "default", seed=1)
    given: list[int] = []

    def stopping(question):
        if len(given) == answers:
            raise KeyboardInterrupt
        given.append(1)
        return answer(question)

    with pytest.raises(KeyboardInterrupt):
        pinarray.run_session(protocol, stopping, subject="01", results=results, seed=1)
    (beh,) = results.rglob("*_beh.tsv")
    return beh


def edited(beh: Path, column: str, value: str, every_row: bool = False) -> None:
    """``beh`` with ``column`` of its second row (or of every row) set to ``value``."""
    header, *rows = beh.read_text().splitlines()
    at = header.split("\t").index(column)
    for n, row in enumerate(rows):
        if every_row or n == 1:
            cells = row.split("\t")
            cells[at] = value
            rows[n] = "\t".join(cells)
    beh.write_text("\n".join([header, *rows]) + "\n")


def correct_as_answered(beh: Path) -> None:
    """``beh``'s identification rows with ``correct`` set again from the answer and the
    pattern, as an editor who knows the columns would leave them."""
    header, *rows = beh.read_text().splitlines()
    names = header.split("\t")
    for n, row in enumerate(rows):
        cells = dict(zip(names, row.split("\t"), strict=True))
        if cells["response"] != "n/a":
            cells["correct"] = str(cells["response"] == cells["pattern"]).lower()
        rows[n] = "\t".join(cells.values())
    beh.write_text("\n".join([header, *rows]) + "\n")


# -- 3. analyse and resume trust no hand-edited row, and miss no run ----------------------

# What is said first: the row's own check (its correct cell no longer follows from the
# edited answer or pattern), else the run's (the plan, the answers offered, the task).
@pytest.mark.parametrize(("column", "value", "every_row", "said"), [
    ("response", "zzz", False, "edited by hand|expected an answer the design offered"),
    ("response", "99", False, "edited by hand|expected an answer the design offered"),
    ("pattern", "zzz", False, "edited by hand|the plan"),
    ("pattern", "L", True, "edited by hand|the plan"),
    ("task", "other", False, "expected the run's task"),
])
def test_an_identification_row_edited_by_hand_is_refused_by_analyse_and_resume(
        tmp_path, column, value, every_row, said):
    results = tmp_path / "results"
    beh = run_cut_short(short_copy("shapes", tmp_path), results)
    edited(beh, column, value, every_row)
    with pytest.raises(DamagedResults, match=said) as raised:
        load_runs([results])
    assert str(raised.value.damaged[0].reason).startswith(f"{beh}:{2 if every_row else 3}: ")
    protocol = pinarray.load_protocol(tmp_path / "shapes.yaml")
    with pytest.raises(ResultsError, match=said):
        pinarray.run_session(protocol, pinarray.simulated_observer(protocol, "default", seed=1),
                             subject="01", results=results, resume=True)


# A dataset shared as BIDS leaves sourcedata/ (the manifests) out; the run's sidecar still
# says its task, the answers it offered and each pattern's pins.
@pytest.mark.parametrize(("column", "value", "every_row", "said"), [
    ("response", "zzz", False, "expected a response the run's sidecar .* lists"),
    ("response", "99", False, "expected a response the run's sidecar .* lists"),
    ("pattern", "zzz", False, "expected a pattern the run's sidecar .* lists"),
    ("pattern", "L", True, "pattern 'L' raises pins .*, the row says"),
    ("task", "other", False, "expected a task the run's sidecar .* lists"),
    ("practice", "true", False, "practice is true in block 1 \\(block 0 is the practice"),
])
def test_an_identification_row_edited_by_hand_is_refused_without_the_manifest(
        tmp_path, column, value, every_row, said):
    results = tmp_path / "results"
    beh = run_cut_short(short_copy("shapes", tmp_path), results)
    shutil.rmtree(results / "sourcedata")
    edited(beh, column, value, every_row)
    correct_as_answered(beh)  # edited with care: no cell contradicts another
    with pytest.raises(DamagedResults, match=said) as raised:
        load_runs([results])
    assert str(raised.value.damaged[0].reason).startswith(f"{beh}:{2 if every_row else 3}: ")
    alone = tmp_path / "alone"  # the file and its sidecar handed over together
    alone.mkdir()
    for path in (beh, beh.with_name(beh.name.replace(".tsv", ".json"))):
        shutil.copy(path, alone)
    with pytest.raises(DamagedResults, match=said):
        load_runs([alone])


@pytest.mark.parametrize("name", ["shapes", "localisation", "apparent_motion", "two_point"])
def test_a_run_shared_without_its_manifest_counts_its_rows_checked_against_its_sidecar(
        tmp_path, name):
    results = tmp_path / "results"
    run_cut_short(short_copy(name, tmp_path), results)
    shutil.rmtree(results / "sourcedata")
    (run,) = select_runs(load_runs([results]), include_incomplete=True).included
    assert run.state is ManifestState.MISSING and run.counted


def test_a_sidecar_without_the_patterns_leaves_the_run_unchecked_not_counted(tmp_path):
    # The repro with the sidecar's pattern entry deleted too: every pattern set to L
    # would be counted with nothing to check it against.
    results = tmp_path / "results"
    beh = run_cut_short(short_copy("shapes", tmp_path), results)
    shutil.rmtree(results / "sourcedata")
    edited(beh, "pattern", "L", True)
    correct_as_answered(beh)
    sidecar = beh.with_name(beh.name.replace(".tsv", ".json"))
    described = json.loads(sidecar.read_text())
    del described["pattern"]["Levels"]
    sidecar.write_text(json.dumps(described))
    runs = select_runs(load_runs([results]), include_incomplete=True)
    assert runs.included == ()
    (run,) = runs.excluded
    assert run.state is ManifestState.UNCHECKED and run.incomplete_reason.startswith(
        f"no manifest, and its sidecar {sidecar.name} gives no Levels of pattern (")


@pytest.mark.parametrize(("name", "design"), [
    ("toj", "soa"), ("flutter_2ifc", "compared_parameter, standard, comparison")])
def test_a_run_whose_sidecar_does_not_record_its_design_is_not_counted_without_its_manifest(
        tmp_path, name, design):
    # Its SOAs, standards and comparisons are the plan's, which only the manifest holds: an
    # SOA or a standard edited to one the design never had could not be caught.
    results = tmp_path / "results"
    beh = run_cut_short(short_copy(name, tmp_path), results)
    shutil.rmtree(results / "sourcedata")
    runs = select_runs(load_runs([results]), include_incomplete=True)
    assert runs.included == ()
    (run,) = runs.excluded
    assert run.state is ManifestState.UNCHECKED and run.counted
    assert run.incomplete_reason == (
        f"no manifest, and its sidecar {beh.name.replace('.tsv', '.json')} gives no Levels of "
        f"{design} (the design's values its rows must hold): its rows cannot be checked "
        "against the design the run offered, so it is not counted, even with "
        "--include-incomplete (keep its manifest in sourcedata/, or its _beh.json beside it)")


def test_a_results_file_handed_over_without_manifest_or_sidecar_is_not_counted(tmp_path):
    beh = run_cut_short(short_copy("shapes", tmp_path), tmp_path / "results")
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(beh, alone)
    runs = select_runs(load_runs([alone]), include_incomplete=True)
    assert runs.included == ()
    (run,) = runs.excluded
    assert run.state is ManifestState.UNCHECKED and run.counted
    assert run.incomplete_reason.startswith(
        f"no manifest and no sidecar {alone / beh.name.replace('.tsv', '.json')}: its rows "
        "cannot be checked")
    (alone / beh.name.replace(".tsv", ".json")).write_text("{not json")
    (run,) = select_runs(load_runs([alone]), include_incomplete=True).excluded
    assert run.incomplete_reason.startswith("no manifest, and its sidecar unreadable (")


@pytest.mark.parametrize("kind", ["folder", "fifo"])
def test_a_completed_run_whose_rows_are_no_file_is_named_not_left_out(tmp_path, kind):
    results = tmp_path / "results"
    protocol = pinarray.load_protocol(short_copy("toj", tmp_path))
    pinarray.run_session(protocol, pinarray.simulated_observer(protocol, "default", seed=1),
                         subject="01", results=results, seed=1)
    (beh,) = results.rglob("*_beh.tsv")
    beh.unlink()
    beh.mkdir() if kind == "folder" else os.mkfifo(beh)
    with pytest.raises(DamagedResults, match="expected a results file, found a "
                                             + ("folder" if kind == "folder" else "FIFO")):
        load_runs([results])


# -- 4. a PSS from coin flips says the answers do not place it ----------------------------

@pytest.mark.parametrize("soas_ms", [(-2, -1, 1, 2), (-120, -60, -30, -15, 15, 30, 60, 120)])
def test_a_pss_from_answers_that_ignore_the_soa_is_not_resolved(soas_ms):
    rng = np.random.default_rng(0)
    placed = 0
    for subject in range(30):
        rows = [LoadedTrial(f"{subject}", "1", 1, None, TemporalOrderRecord(
            trial=n, block=1, task="toj", onset_ns=0, duration_ns=1, pins=(6, 7),
            soa_ns=soa * 1_000_000, response="6" if rng.random() < 0.5 else "7"))
            for n, soa in enumerate([s for s in soas_ms for _ in range(12)], start=1)]
        found = temporal_orders(rows, CONTEXT)
        (fit,) = found.fits
        if fit.jnd.words != "estimated":  # the answers bound no JND from above ...
            assert fit.pss.status is EstimateStatus.NOT_RESOLVED  # ... nor place a PSS
            assert fit.pss.words == PSS_UNRESOLVED and math.isnan(fit.pss.ci_low)
        else:
            placed += 1
    assert placed <= 3  # a rare subject's coin flips do look like a steep function


# -- 5. resume ends in one line, never a hang or a traceback --------------------------------

RESUME_TIMEOUT_S = 60
HUNG = ("fifo", "zeros")  # the damage that made a resume wait for ever


@pytest.mark.parametrize("damage", ["fifo", "zeros", "folder", "not utf-8", "seed abc",
                                    "soa 1e308"])
def test_resuming_damaged_results_says_what_is_wrong_in_one_line(tmp_path, damage):
    results = tmp_path / "results"
    protocol_path = short_copy("toj", tmp_path)
    beh = run_cut_short(protocol_path, results)
    (manifest,) = results.rglob("*_manifest.json")
    if damage in ("fifo", "zeros", "folder"):
        beh.unlink()
        {"fifo": os.mkfifo, "folder": os.mkdir,
         "zeros": lambda p: os.symlink("/dev/zero", p)}[damage](beh)
    elif damage == "not utf-8":
        beh.write_bytes(beh.read_bytes() + b"\xff\xfe\n")
    elif damage == "seed abc":
        manifest.write_text(manifest.read_text().replace('"seed": 1,', '"seed": "abc",'))
    else:
        edited(beh, "soa", "1e308")
    resume = ["batch", str(protocol_path), "--subject", "01", "--observer", "default",
              "--results", str(results), "--resume"]
    if damage in HUNG:  # in a process of its own, where a hang fails the test
        result = pinarray_forked(tmp_path / "resume", *resume, timeout=RESUME_TIMEOUT_S)
    else:
        result = pinarray_here(*resume)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("pinarray: ") and str(tmp_path) in line


# -- 6. protocols and options that ended in tracebacks -------------------------------------

@pytest.mark.parametrize(("written", "said"), [
    ("frequency_hz: 0", "expected the frequency more than 0 Hz, found 0"),
    ("frequency_hz: -10", "expected the frequency more than 0 Hz, found -10"),
    ("frequency_hz: .nan", "expected a finite number of Hz for the frequency"),
    ("frequency_hz: .inf", "expected a finite number of Hz for the frequency"),
    ("frequency_hz: 0.001", "expected a signal length of at least one pulse period"),
    ("frequency_hz: 1e6", "expected the frequency of at most 1000 Hz"),
    ("duration_s: 1e-9", "expected a signal length of at least one pulse period"),
])
def test_a_patterns_broken_train_is_said_where_it_is_written_not_asserted(written, said):
    text = (PROTOCOLS / "flutter_2ifc.yaml").read_text()
    old = ("frequency_hz: 10          # the standard; the design sets each interval's frequency"
           if written.startswith("frequency") else "duration_s: 1\n")
    text = text.replace(old, written + ("\n" if old.endswith("\n") else ""), 1)
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "p.yaml")
    first = raised.value.errors[0]
    assert said in first.message and first.line in (20, 21)


def test_a_one_pattern_stimulus_asked_for_an_soa_is_said_where_the_value_is_written():
    text = (PROTOCOLS / "flutter_2ifc.yaml").read_text().replace(
        "  compare: frequency_hz       # what the two intervals differ in\n  standard: 10\n"
        "  comparisons: [7, 8, 9, 11, 12, 13]\n",
        "  compare: soa_ms\n  standard: 10\n  comparisons: [20, 30]\n")
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "p.yaml")
    first = raised.value.errors[0]
    assert first.line == 32 and ("expected a stimulus with an SOA (frames or a wave), found "
                                 "'flutter', one pattern") in first.message


@pytest.mark.parametrize(("protocol", "spec"), [
    ("toj", "jnd_ms=5,jnd_ms=60"), ("flutter_2ifc", "weber=0.1,weber=0.3"),
    ("shapes", "identify_correct=0.5,identify_correct=0.9"),
    ("two_point", "threshold_mm=2,threshold_mm=4"),
])
def test_an_observer_key_given_twice_is_refused(protocol, spec):
    loaded = pinarray.load_protocol(PROTOCOLS / f"{protocol}.yaml")
    with pytest.raises(PinArrayError, match="is given twice; give each parameter once"):
        pinarray.simulated_observer(loaded, spec, seed=1)


@pytest.mark.parametrize("seed", [True, 1.5, "3"])
def test_a_plan_seed_that_is_no_whole_number_is_refused(seed):
    protocol = pinarray.load_protocol(PROTOCOLS / "toj.yaml")
    # The public door says it in its words (issue 44); the plan's own check stands behind it.
    with pytest.raises(PinArrayError, match="plan_trials: seed: expected an int"):
        pinarray.plan_trials(protocol, seed=seed)
    with pytest.raises(PinArrayError, match="a plan seed must be a whole number"):
        make_plan(protocol, seed)


def test_a_table_never_prints_minus_zero():
    assert [number(v, 3) for v in (-0.0001, -0.0, 0.0004)] == ["0.000"] * 3
    assert number(-0.0006, 3) == "-0.001" and number(-0.4, 0) == "0"
    assert [significant(v, 2) for v in (-0.0, 0.0)] == ["0", "0"]
    assert significant(-0.00001, 2) == "-1e-05" and significant(-0.0123) == "-0.0123"


def test_a_caption_never_prints_minus_zero():
    # Three subjects whose mean PSS is -0.012 ms: the caption said "Mean PSS -0.0 ms".
    rows = [LoadedTrial("1", "1", 1, None, TemporalOrderRecord(
        trial=n, block=1, task="toj", onset_ns=0, duration_ns=1, pins=(6, 7),
        soa_ns=soa * 1_000_000, response="6" if soa > 0 else "7"))
        for n, soa in enumerate([s for s in (-60, -30, 30, 60) for _ in range(6)], start=1)]
    found = temporal_orders(rows, CONTEXT)
    near_zero = replace(found, across=tuple(replace(m, mean=-0.012) for m in found.across))
    caption = near_zero.caption("toj")
    assert "Mean PSS 0.0 ms over 1 subject(s), mean JND 0.0 ms" in caption
    assert "-0.0" not in caption
