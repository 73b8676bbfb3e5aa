"""Which serial port is the array? `find_servo_ports` asks each port who answers, as a script
or PsychoPy's device manager does before opening one (simulated buses here, in virtual time)."""

from pathlib import Path

import pinarray
from pinarray.testing import ArrayOpener

LOCALISATION = Path(__file__).resolve().parents[1] / "protocols" / "localisation.yaml"


def test_a_whole_array_answers_with_its_sixteen_ids_though_their_answers_collide():
    (found,) = pinarray.find_servo_ports(["sim://"])
    assert found == pinarray.ServoPort("sim://", "", tuple(range(1, 17)))


def test_unplugged_servos_are_missing_from_the_ids_and_a_port_where_none_answer_is_left_out():
    found = pinarray.find_servo_ports(["sim://?missing=1-16", "sim://?missing=2,5",
                                       "/dev/pinarray-no-such-port"])
    assert [(p.port, p.servo_ids) for p in found] == [
        ("sim://?missing=2,5", (1, 3, 4, *range(6, 17)))]


def test_a_port_found_opens_as_the_protocols_array():
    (found,) = pinarray.find_servo_ports(["sim://?ids=1-16"])
    with ArrayOpener() as open_simulated:
        array = open_simulated(LOCALISATION, found.port)
        assert array.present(pinarray.find_condition(array.protocol, pin=6,
                                                     frequency_hz=10)).delivered


def test_nothing_is_found_where_the_system_lists_no_servos(monkeypatch):
    import serial.tools.list_ports

    monkeypatch.setattr(serial.tools.list_ports, "comports", lambda: [])
    assert pinarray.find_servo_ports() == ()
