"""The words say what is computed (issue 46, item 7): each test holds a sentence of the docs
to the computation it describes."""

import inspect
import math
import re
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import pinarray
from pinarray.analysis.fits import AcrossMeasure, across_text
from pinarray.analysis.load import LoadedTrial, RunSelection
from pinarray.analysis.seam import Context
from pinarray.analysis.subjects import IntervalSettings
from pinarray.analysis.tables import number
from pinarray.grid import Grid
from pinarray.paradigms.identification.analysis import (
    Confusion,
    confusion,
    identifications,
    it_bias_bits,
)
from pinarray.paradigms.identification.rows import IdentificationRecord
from pinarray.paradigms.temporal_order.analysis import temporal_orders
from pinarray.paradigms.temporal_order.rows import TemporalOrderRecord
from pinarray.paradigms.two_interval.observer import TwoIntervalObserverModel
from pinarray.protocol.load import load_protocol
from pinarray.protocol.model import Train
from pinarray.schedule import train_pulses

REPO = Path(__file__).resolve().parent.parent


def test_phase_shifts_the_cycle_circularly_and_leaves_the_signal_where_it_was():
    plain = Train(Fraction(10), 200_000_000)
    half = Train(Fraction(10), 200_000_000, phase=Fraction(1, 2))
    starts, widths, up = train_pulses(plain)
    shifted_starts, shifted_widths, shifted_up = train_pulses(half)
    # The same slots from the signal's start (nothing is delayed) ...
    assert list(shifted_starts) == list(starts) and shifted_starts[0] == 0
    # ... each playing the pulse half a cycle (5 slots) further round the cycle.
    assert list(shifted_up) == list(np.roll(up, 5))
    assert list(shifted_widths) == list(np.roll(widths, 5))
    assert not shifted_up[0]  # at phase 1/2 the seed's train begins with its down pulses


def test_a_phase_off_the_slot_grid_moves_every_pulse_by_its_remainder():
    quarter = Train(Fraction(10), 200_000_000, phase=Fraction(1, 4))  # 2.5 slots of 10 ms
    starts, _, up = train_pulses(quarter)
    assert starts[0] == 5_000_000  # the first half slot has no pulse
    first_up = int(np.flatnonzero(up)[0])
    assert starts[first_up] == 25_000_000  # the first up pulse: a quarter period late


def test_the_phase_words_say_circular_shift_not_delay():
    doc = Train.__doc__ or ""
    assert "shifts the cycle circularly" in doc and "delays" not in doc
    # ... and so does the public face's: its docstring and those of its attributes, which
    # the site's reference is built from (read in its source, as the docs build reads them).
    public = " ".join(inspect.getsource(pinarray.Train).split())
    assert "shifts the cycle circularly within the signal" in public
    assert "the cycle shifted circularly within the signal" in public
    assert "delay" not in public.lower()
    readme = (REPO / "protocols" / "README.md").read_text()
    assert "delays the pattern" not in readme and "shifts the cycle circularly" in readme


def test_the_miller_correction_counts_the_answers_given_not_those_offered():
    # 3 patterns presented, answered only "a" and "b" of the answers offered: the matrix has
    # a column for "c" (a pattern presented), empty; C is 2.
    counts = np.array([[4, 1, 0], [1, 4, 0], [3, 2, 0]])
    matrix = Confusion(("a", "b", "c"), ("a", "b", "c"), counts)
    n = int(counts.sum())
    assert it_bias_bits(counts) == pytest.approx((3 - 1) * (2 - 1) / (2 * n * math.log(2)))
    assert matrix.it_bias_bits != pytest.approx((3 - 1) * (3 - 1) / (2 * n * math.log(2)))
    words = (REPO / "docs" / "experimenters" / "results.md").read_text()
    assert "C answers given (an answer offered\nbut never given does not count)" in words


def test_the_observers_weber_is_its_81_6_percent_point_and_its_75_percent_point_as_documented():
    model = TwoIntervalObserverModel(weber=0.2, slope=3.0, lapse=0.0, subject_sd=0.0)
    at_weber = model.p_right(10.0, 10.0 * (1 + model.weber))
    assert at_weber == pytest.approx(0.5 + 0.5 * (1 - math.exp(-1)))
    assert round(100 * at_weber, 1) == 81.6
    # The 75 % point, as the docstring converts it: weber x (ln 2)^(1/slope).
    at_75 = 0.2 * math.log(2) ** (1 / 3.0)
    assert model.p_right(10.0, 10.0 * (1 + at_75)) == pytest.approx(0.75)
    assert round(at_75 / 0.2, 3) == 0.885 and round(at_75, 3) == 0.177
    lapsing = TwoIntervalObserverModel(weber=0.2, slope=3.0, lapse=0.02, subject_sd=0.0)
    assert round(100 * lapsing.p_right(10.0, 12.0), 1) == 80.3
    doc = (REPO / "pinarray" / "paradigms" / "two_interval" / "observer.py").read_text()
    for words in ("81.6 % at a lapse rate of 0 (80.3 % at the default 0.02)", "0.885 x",
                  "75 % Weber fraction of 0.177"):
        assert words in " ".join(doc.split())


def test_the_staircase_interval_width_states_the_thresholds_it_comes_from():
    values = load_protocol(REPO / "protocols" / "staircase_motion.yaml").design.adaptive
    assert values is not None
    spread = f"{float(values.values[0]):g}-{float(values.values[-1]):g} ms"
    assert spread == "20-300 ms"
    words = " ".join((REPO / "docs" / "experimenters" / "adaptive.md").read_text().split())
    assert re.search(rf"median width 56 ms over thresholds spread across {spread}", words)


def test_the_across_subject_row_says_no_subject_resolved_it_not_one_subject():
    # Six subjects whose answers ignore the SOA: each PSS is not resolved, and the
    # across-subject cell says so of all six (it said "n/a n/a (one subject)").
    rows = [LoadedTrial(f"s{subject}", "1", 1, None, TemporalOrderRecord(
        trial=n, block=1, task="toj", onset_ns=0, duration_ns=1, pins=(6, 7),
        soa_ns=soa * 1_000_000, response="6" if n % 2 else "7"))
        for subject in range(6)
        for n, soa in enumerate([s for s in (-120, -60, -30, 30, 60, 120) for _ in range(8)],
                                start=1)]
    found = temporal_orders(rows, Context(RunSelection((), (), False), IntervalSettings(),
                                          Grid()))
    (all_row,) = [line for line in found.sections() if line.startswith("| all |")]
    assert "not resolved in any of 6 subjects" in all_row and "one subject" not in all_row


@pytest.mark.parametrize(("values", "subjects", "said"), [
    ((), 1, "not resolved (one subject)"),
    ((), 4, "not resolved in any of 4 subjects"),
    ((("a", 2.0),), 1, "2.00, no interval (one subject with a number)"),
    ((("a", 2.0),), 3, "2.00, no interval (one subject with a number of 3)"),
    ((("a", 2.0), ("b", 4.0)), 3, "3.00 [1.00, 5.00] (2 subjects with a number of 3)"),
    ((("a", 2.0), ("b", 4.0)), 2, "3.00 [1.00, 5.00]"),
])
def test_an_across_subject_cell_says_how_many_subjects_it_is_the_mean_of(values, subjects, said):
    numbers = [v for _, v in values]
    interval = (1.0, 5.0) if len(numbers) > 1 else (math.nan, math.nan)
    measure = AcrossMeasure("toj", "pss_ms", "ms", values,
                            float(np.mean(numbers)) if numbers else math.nan, interval)
    assert across_text(measure, subjects, 2) == said


def test_the_corrected_information_is_said_as_the_bias_subtracted_and_floored_at_zero():
    # Few trials, answers spread: the bias exceeds the estimate, the corrected value is 0.
    records = [IdentificationRecord(trial=n, block=1, task="shapes", onset_ns=0, duration_ns=1,
                                    pins=(1,), pattern=pattern, response=answer)
               for n, (pattern, answer) in enumerate(
                   [("L", "L"), ("L", "T"), ("T", "T"), ("T", "square"), ("square", "L"),
                    ("square", "square"), ("L", "square")], start=1)]
    matrix = confusion(records)
    assert matrix.it_bias_bits > matrix.it_bits and matrix.it_corrected_bits == 0
    found = identifications([LoadedTrial("a", "1", 1, None, r) for r in records],
                            Context(RunSelection((), (), False), IntervalSettings(), Grid()))
    (line,) = found.lines()
    assert (f"its small-sample bias {number(matrix.it_bias_bits, 3)} bits; less the bias, "
            "floored at 0: 0.000 bits" in line)
    words = (REPO / "docs" / "experimenters" / "results.md").read_text()
    assert "`it_corrected_bits`, which is floored at 0" in words
