"""Odd input found by issue 46's hostile pass (item 6): a key longer than YAML reads, and
digits of other scripts where a number is typed (int() and float() read ``１`` as 1)."""

from pathlib import Path

import pytest

from pinarray.cli.calibrate import parse_jog
from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError, ProtocolErrors, ResultsError
from pinarray.hardware.feetech.faults import parse_ids, parse_sim_url
from pinarray.hardware.pca9685.sim import SimI2cLink
from pinarray.journal.columns import Cell, Column, cell_value, pins_cell
from pinarray.journal.timebase import ns_from_seconds
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.protocol.load import parse_protocol

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"


def located(text: str) -> list[str]:
    with pytest.raises(ProtocolErrors) as caught:
        parse_protocol(text, "p.yaml")
    return [e.located() for e in caught.value.errors]


def test_a_stimulus_name_of_5000_characters_is_refused_where_it_starts_saying_why():
    name = "f" * 5000
    text = (PROTOCOLS / "flutter_2ifc.yaml").read_text().replace(
        "  flutter:\n", f"  {name}:\n").replace("stimulus: flutter", f"stimulus: {name}")
    line = text.splitlines().index(f"  {name}:") + 1
    assert located(text) == [f"p.yaml:{line}:3: expected a key of at most 1024 characters "
                             "(the longest YAML reads), found one of 5000"]


def test_a_key_of_1024_characters_is_read_and_one_more_is_refused():
    base = "protocol: x\nstimuli:\n  {key}: {{frequency_hz: 5, duration_s: 1}}\n"
    fits = located(base.format(key="k" * 1024))
    assert not any("at most 1024" in line for line in fits)  # read: other problems follow
    assert located(base.format(key="k" * 1025)) == [
        "p.yaml:3:3: expected a key of at most 1024 characters (the longest YAML reads), "
        "found one of 1025"]


@pytest.mark.parametrize("url", ["sim://?seed=１", "sim://?baud=１000000", "sim://?late_ms=０.5",
                                 "sim://?ids=１-4", "sim://?missing=３"])
def test_a_sim_url_takes_ascii_digits_only(url):
    with pytest.raises(PinArrayError, match="sim URL key .*: expected"):
        parse_sim_url(url)


def test_servo_ids_take_ascii_digits_only():
    assert parse_ids("1-3") == (1, 2, 3)
    with pytest.raises(PinArrayError, match="expected servo ids"):
        parse_ids("１-3")


@pytest.mark.parametrize("url", ["sim://pca9685?seed=１", "sim://pca9685?osc_hz=２5000000",
                                 "sim://pca9685?address=６４"])
def test_a_simulated_board_url_takes_ascii_digits_only(url):
    with pytest.raises(PinArrayError, match="sim URL key"):
        SimI2cLink(url, VirtualClock())


def test_a_board_address_in_a_protocol_takes_ascii_digits_only():
    text = (PROTOCOLS / "localisation_pwm.yaml").read_text()
    assert 'address: "0x40"' in text
    problems = located(text.replace('address: "0x40"', 'address: "６４"'))
    assert len(problems) == 1 and "expected an I2C address such as \"0x40\"" in problems[0]


@pytest.mark.parametrize("typed", ["+１", "=２０", "+²"])
def test_jogging_takes_ascii_digits_only(typed):
    with pytest.raises(ValueError, match="expected"):
        parse_jog(typed, 1)


def test_a_results_cell_takes_ascii_digits_only():
    with pytest.raises(ResultsError):
        cell_value(Column("trial", Cell.INTEGER, ""), "１", "line 2")
    with pytest.raises(ResultsError):
        cell_value(Column("x", Cell.NUMBER, ""), "０.5", "line 2")
    with pytest.raises(ResultsError):
        pins_cell("６ 7", "line 2")
    with pytest.raises(ValueError):
        ns_from_seconds("１.5")
    assert cell_value(Column("trial", Cell.INTEGER, ""), "12", "line 2") == 12


def test_a_localisation_response_of_other_digits_is_refused_not_a_traceback():
    with pytest.raises(ResultsError, match="a localisation response must be a pin number"):
        LocalisationRecord(trial=1, block=0, task="t", onset_ns=0, duration_ns=1,
                           pin=6, frequency_hz=10.0, response="²")
