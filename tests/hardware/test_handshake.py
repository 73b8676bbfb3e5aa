"""Connecting: every expected servo is pinged, and every problem is reported at once."""

import pytest

from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.feetech.registers import Register

from .lab import device_setup, sim_bus


def test_a_complete_array_connects_with_torque_on_and_no_eeprom_writes():
    bus = sim_bus()
    for servo in bus.sim.servos.values():
        assert servo.torque_enabled
        assert servo.get(Register.GOAL_SPEED) == 3000
        assert servo.eeprom_writes == []


def test_all_missing_servos_are_named_in_one_error():
    with pytest.raises(BusError) as caught:
        sim_bus("missing=3,7,12")
    message = str(caught.value)
    assert "no answer from servo id(s) 3, 7, 12" in message


def test_a_servo_of_the_wrong_model_is_named_with_what_it_reports():
    bus = sim_bus(connect=False)
    bus.sim.servos[5].table[3:5] = (1020).to_bytes(2, "little")
    with pytest.raises(BusError, match="expected model 777, but id 5 reports model 1020"):
        bus.connect(device_setup())


def test_a_failed_handshake_leaves_no_servo_holding_torque():
    bus = sim_bus(connect=False)
    del bus.sim.servos[16]
    with pytest.raises(BusError, match="16"):
        bus.connect(device_setup())
    assert not any(s.torque_enabled for s in bus.sim.servos.values())


def test_the_driver_refuses_to_write_eeprom():
    bus = sim_bus()
    with pytest.raises(BusError, match="servo 1: refusing to write RETURN_DELAY_TIME"):
        bus.write(1, Register.RETURN_DELAY_TIME, 0)


def test_a_sim_url_with_an_unknown_key_is_a_user_error():
    with pytest.raises(PinArrayError, match="unknown key"):
        sim_bus("dorp=0.1")


def test_angle_limits_that_would_clamp_a_calibrated_stroke_are_refused_at_connect():
    bus = sim_bus(connect=False)
    bus.sim.servos[3].table[11:13] = (2070).to_bytes(2, "little")  # MAX_ANGLE_LIMIT
    with pytest.raises(BusError) as caught:
        bus.connect(device_setup())
    message = str(caught.value)
    assert "pin 3 (servo 3)" in message and "MAX_ANGLE_LIMIT 2070" in message
    assert "calibrated stroke 1900..2300" in message
    assert not any(s.torque_enabled for s in bus.sim.servos.values())
