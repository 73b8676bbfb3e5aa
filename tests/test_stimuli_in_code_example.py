"""examples/stimuli_in_code.py, as a lab runs it: on the simulated array without a protocol,
and through a serial port served by the simulated bus (the player process driving it) with
the protocol that calibrates the rig; every stimulus delivered, one row each saying what was
presented, and the stimulus the bus cannot carry refused first."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import pytest

import pinarray
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.serve import PtyServer
from tests.test_stimuli_in_code import RIG

realtime = pytest.mark.realtime  # the wall clock and a pseudo-terminal: run apart (tests/suite.py)
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "stimuli_in_code.py"


def example():
    spec = importlib.util.spec_from_file_location("stimuli_in_code", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def rows_written(log: Path) -> list[dict[str, str]]:
    with log.open(newline="", encoding="utf-8") as file:
        return list(csv.DictReader(file))


def test_the_example_plays_its_stimuli_on_the_simulated_array_without_a_protocol(tmp_path,
                                                                                   capsys):
    script = example()
    assert script.main(["--log", str(tmp_path / "log.csv")]) == 0
    rows = rows_written(tmp_path / "log.csv")
    assert [row["stimulus"] for row in rows] == [repr(s) for s in script.stimuli()]
    assert all(row["delivered"] == "True" for row in rows)
    assert rows[0]["strokes_steps"] == "6:114 7:114 10:114 11:114"
    said = capsys.readouterr().out
    assert "refused, nothing moved: present: Pattern: pins: pin 1 cannot follow 80 Hz" in said


@realtime
def test_the_example_plays_its_stimuli_through_a_serial_port(tmp_path, capsys):
    protocol = tmp_path / "rig.yaml"
    protocol.write_text(RIG)
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    try:
        script = example()
        status = script.main(["--protocol", str(protocol), "--port", server.path,
                              "--log", str(tmp_path / "log.csv")])
    finally:
        server.stop()
    said = capsys.readouterr().out
    assert status == 0, said
    rows = rows_written(tmp_path / "log.csv")
    assert [row["stimulus"] for row in rows] == [repr(s) for s in script.stimuli()]
    assert "refused, nothing moved: present: Pattern: pins: the servo bus cannot deliver it" \
        in said


def test_real_servos_without_their_protocol_are_refused_before_the_port_is_opened(tmp_path):
    with pytest.raises(pinarray.PinArrayError, match="real servos need the protocol that calibrates them"):
        example().main(["--port", "/dev/ttyUSB9", "--log", str(tmp_path / "log.csv")])


PATTERNS = EXAMPLE.with_name("psychopy_patterns.psyexp")


def test_the_builder_patterns_example_asks_only_for_what_the_default_device_delivers():
    # The Builder example's patterns (its conditions file's pins and frequencies on the
    # dialog's train), each delivered in full on the simulated default device in virtual time,
    # where no load can make one late: what its PsychoPy run presents (tests/psychopy).
    import xml.etree.ElementTree as ElementTree

    touch = ElementTree.parse(PATTERNS).find(".//PinArrayTouchComponent")
    assert touch is not None
    dialog = {param.get("name"): param.get("val") for param in touch.iter("Param")}
    assert (dialog["pins"], dialog["frequency"], dialog["protocol"]) == ("$pins",
                                                                          "$frequency_hz", "")
    conditions = rows_written(PATTERNS.with_name("psychopy_patterns.csv"))
    assert len(conditions) == 6
    with pinarray.open_array(clock=pinarray.VirtualClock()) as array:
        for row in conditions:
            pins = [int(pin) for pin in row["pins"].strip("[]").split(",")]
            stimulus = pinarray.Pattern(pins=pins, train=pinarray.Train(
                frequency_hz=float(row["frequency_hz"]),
                duration_s=float(dialog["trainDuration"]),
                duty_cycle=float(dialog["dutyCycle"])))
            delivery = array.present(stimulus)
            assert delivery.delivered, (row, delivery.problem)
            for stroke in delivery.strokes:
                assert stroke.unmeasured_cycles == 0 and stroke.achieved_steps == 114, stroke
