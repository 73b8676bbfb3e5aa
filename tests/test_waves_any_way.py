"""Waves up and down a column and along any sequence of pins, answered and scored by the
direction they go; and a localisation train that leaves its frequency to the design."""

import csv
import json
import textwrap

import pytest

from pinarray.errors import ProtocolErrors, ResultsError
from pinarray.journal.manifest import PlanEntry, entry_from_json, entry_to_json
from pinarray.paradigms.apparent_motion.rows import entry_direction
from pinarray.protocol import Direction, WaveKind
from pinarray.protocol.load import load_protocol, parse_protocol
from tests.commands import pinarray_here
from tests.many_ways import MANY_WAYS, write_many_ways
from tests.test_protocol_load import PROTOCOLS


def problems(text: str) -> list[str]:
    with pytest.raises(ProtocolErrors) as caught:
        parse_protocol(textwrap.dedent(text), "p.yaml")
    return [e.located() for e in caught.value.errors]


def one_wave(wave: str) -> str:
    return ("protocol: m\nstimuli:\n  tap: {frequency_hz: 5, duration_s: 0.4}\n"
            f"  w: {wave}\n"
            "design: {paradigm: apparent_motion, configurations: [w]}\n")


def test_a_column_wave_taps_its_pins_bottom_to_top_one_soa_apart():
    protocol = parse_protocol(MANY_WAYS, "p.yaml")
    drives = protocol.wave("upwards").drives()
    assert [(d.pin, d.delay_ns) for d in drives] == [
        (2, 0), (6, 200_000_000), (10, 400_000_000), (14, 600_000_000)]
    assert [d.pin for d in protocol.wave("downwards").drives()] == [15, 11, 7, 3]


def test_a_sequence_wave_visits_its_pins_in_the_order_listed_going_the_way_it_names():
    protocol = parse_protocol(MANY_WAYS, "p.yaml")
    wave = protocol.wave("diagonal")
    assert [d.pin for d in wave.drives()] == [1, 6, 11, 16]
    (condition,) = [c for c in protocol.design.conditions if c.stimulus == "diagonal"]
    assert (condition.kind, condition.direction, condition.row) == (
        WaveKind.SEQUENCE, Direction("up-right"), None)


def test_the_answers_are_the_directions_the_waves_go_then_no_motion_and_unsure():
    many = parse_protocol(MANY_WAYS, "p.yaml").design.answers(16)
    assert list(many) == ["left", "right", "up", "down", "up-right", "none", "unsure"]
    seed = load_protocol(PROTOCOLS / "apparent_motion.yaml").design.answers(16)
    assert list(seed) == ["left", "right", "none", "unsure"]


@pytest.mark.parametrize(("wave", "what"), [
    ("{wave: upwards, pins: [2, 7, 10], train: tap}",
     "found [2, 7, 10]: they leave column 2 (pin 2): pin 7 is in column 3"),
    ("{wave: upwards, pins: [14, 10, 6, 2], train: tap}",
     "found [14, 10, 6, 2]: they go down column 2"),
    ("{wave: downwards, pins: [5, 6, 7], train: tap}",
     "found [5, 6, 7]: they run rightwards along row 2"),
])
def test_a_column_wave_whose_pins_do_not_go_that_way_up_a_column_is_refused_saying_what_they_do(
        wave, what):
    (line,) = problems(one_wave(wave))
    assert line.startswith("p.yaml:4:")  # at the wave's pins
    assert "one column" in line and line.endswith(what)


@pytest.mark.parametrize(("wave", "expected"), [
    ("{wave: sequence, pins: [1, 6, 1], direction: loop, train: tap}",
     "expected each pin of a wave once, found 1 more than once in [1, 6, 1]"),
    ("{wave: sequence, pins: [1, 17], direction: out, train: tap}",
     "expected a pin from 1 to 16 on the 4x4 grid, found 17"),
    ("{wave: sequence, pins: [1, 6], train: tap}", "expected a 'direction' key"),
    ("{wave: sequence, pins: [1, 6], direction: unsure, train: tap}", "neither none nor unsure"),
    ("{wave: sequence, pins: [1, 6], direction: Up Right, train: tap}",
     "lowercase words joined by hyphens"),
    ("{wave: upwards, row: 1, pins: [2, 6], train: tap}", "expected no 'row' for a upwards wave"),
    ("{wave: upwards, train: tap}", "expected a 'pins' key"),
    ("{wave: rightwards, row: 1, direction: up, train: tap}", "expected no 'direction'"),
])
def test_a_sequence_of_pins_must_be_distinct_on_the_grid_and_name_its_direction(wave, expected):
    (line,) = problems(one_wave(wave))
    assert line.startswith("p.yaml:") and expected in line


def test_a_column_and_a_diagonal_wave_run_in_batch_with_a_simulated_subject(tmp_path):
    path = write_many_ways(tmp_path)
    result = pinarray_here("batch", path, "--subject", "w1", "--observer", "default", "--seed",
                           "4", "--results", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    (beh,) = (tmp_path / "out").rglob("*_beh.tsv")
    rows = list(csv.DictReader(beh.open(), delimiter="\t"))
    assert len(rows) == 7  # one practice, then the six configurations
    offered = {"left", "right", "up", "down", "up-right", "none", "unsure"}
    assert {r["response"] for r in rows} <= offered
    by_direction = {r["direction"]: r for r in rows if r["practice"] == "false"}
    assert set(by_direction) == {"left", "right", "up", "down", "up-right", "none"}
    for direction in ("up", "down", "up-right"):
        assert by_direction[direction]["row"] == "n/a"  # not along a row
    for row in rows:
        if row["direction"] != "none" and row["response"] not in ("none", "unsure"):
            assert row["direction_correct"] == str(row["response"] == row["direction"]).lower()
    (sidecar,) = (tmp_path / "out").rglob("*_beh.json")
    levels = json.loads(sidecar.read_text())
    assert list(levels["response"]["Levels"]) == [
        "left", "right", "up", "down", "up-right", "none", "unsure"]
    assert "up-right" in levels["direction"]["Levels"]
    assert "up" in levels["direction"]["Levels"]


def test_a_wave_not_along_a_row_is_kept_in_the_plan_with_its_pins_and_direction():
    entry = PlanEntry(trial=3, stimulus="diagonal",
                      fields={"pin": None, "frequency_hz": None, "direction": "sequence",
                              "row": None, "pins": [1, 6, 11, 16], "towards": "up-right"})
    back = entry_from_json(json.loads(json.dumps(entry_to_json(entry))), "m.json",
                           "apparent_motion")
    assert back == entry and entry_direction(back) == "up-right"
    # A row's wave is stored as it always was, so plans written before read the same.
    row = entry_from_json({"trial": 1, "direction": "leftwards", "row": 2}, "m.json",
                          "apparent_motion")
    assert entry_direction(row) == "left" and row["pins"] is None
    with pytest.raises(ResultsError, match="not an apparent_motion trial"):
        entry_from_json({"trial": 1, "direction": "sideways", "row": 2}, "m.json",
                        "apparent_motion")


# -- a localisation train without frequency_hz ---------------------------------------------------

SHAPE_ONLY = """\
protocol: m
stimuli:
  buzz: {duration_s: 1}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 2]
  frequencies_hz: [3, 10]
"""


def test_a_localisation_train_may_leave_its_frequency_to_the_design():
    protocol = parse_protocol(SHAPE_ONLY, "p.yaml")
    assert sorted({c.frequency_hz for c in protocol.design.conditions}) == [3, 10]


def test_the_shipped_localisation_protocol_gives_no_dummy_frequency():
    assert "frequency_hz: 10" not in (PROTOCOLS / "localisation.yaml").read_text()
    assert len(load_protocol(PROTOCOLS / "localisation.yaml").design.conditions) == 24


def test_a_train_no_design_frequency_reaches_must_give_its_own():
    text = SHAPE_ONLY.replace("  buzz: {duration_s: 1}", "  buzz: {duration_s: 1}\n  spare: {duration_s: 2}")
    (line,) = problems(text)
    assert line == ("p.yaml:4:10: expected a frequency_hz in train 'spare', found none: only the "
                    "stimulus of a localisation design may leave it to the design's frequencies_hz")


def test_a_wave_whose_train_has_no_frequency_is_refused_where_it_names_the_train():
    text = one_wave("{wave: upwards, pins: [2, 6], train: tap}").replace(
        "{frequency_hz: 5, duration_s: 0.4}", "{duration_s: 0.4}")
    lines = problems(text)
    assert any(line.startswith("p.yaml:4:") and "expected a train with a frequency_hz for a "
               "wave, found train 'tap' without one" in line for line in lines)


def test_a_design_frequency_too_high_for_the_signal_length_is_refused_at_that_frequency():
    text = SHAPE_ONLY.replace("{duration_s: 1}", "{duration_s: 0.001}")
    three, ten = problems(text)  # each frequency the signal is too short for, where it is written
    assert three.startswith("p.yaml:8:20:") and "at least one pulse period (33.3333 ms at 3 Hz)" in three
    assert ten.startswith("p.yaml:8:23:") and "(10 ms at 10 Hz), found 1 ms" in ten
