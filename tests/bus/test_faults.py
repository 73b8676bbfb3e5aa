"""Transient faults are retried and counted; persistent ones name the servo and register."""

import pytest

from pinarray.bus.base import PortLost
from pinarray.bus.registers import Register, StatusError
from pinarray.errors import BusError
from pinarray.player import PlaybackAborted, play_trial

from .lab import assert_safe, pulse_train, sim_bus


def test_a_lost_status_packet_is_retried_and_counted():
    bus = sim_bus()
    bus.sim.drop_next = 2
    (reading,) = bus.read_telemetry((4,))
    assert reading.position_steps == 2048
    assert bus.stats().retries == 2


def test_a_corrupt_status_packet_is_retried_and_counted():
    bus = sim_bus()
    bus.sim.corrupt_next = 1
    bus.read(6, Register.PRESENT_POSITION)
    assert bus.stats().retries == 1


def test_persistent_silence_names_servo_register_and_the_sdk_result():
    bus = sim_bus()
    bus.sim.drop_next = 100
    with pytest.raises(BusError) as caught:
        bus.read(9, Register.PRESENT_VOLTAGE)
    message = str(caught.value)
    assert "servo 9" in message and "PRESENT_VOLTAGE" in message
    assert "expected a status packet from servo 9, found no status packet" in message
    assert "4 attempt(s)" in message


def test_persistent_corruption_names_the_servo_and_register():
    bus = sim_bus()
    bus.sim.corrupt_next = 100
    with pytest.raises(BusError, match=r"servo 2: writing TORQUE_ENABLE \(address 40\) failed"):
        bus.write(2, Register.TORQUE_ENABLE, 1)


def test_a_noisy_wire_still_plays_with_retries_counted():
    bus = sim_bus("drop=0.02&corrupt=0.02&seed=7")
    report = play_trial(bus, pulse_train([1, 2], 5, 5), bus.clock)
    assert report.frames_sent == 10
    assert report.retries > 0
    assert_safe(bus)


def test_a_dropped_sync_write_leaves_the_servo_where_it_was():
    bus = sim_bus()
    bus.sim.drop_next = 1
    bus.write_goals({5: 2200})
    assert bus.sim.servos[5].goal_steps == 2048


@pytest.mark.parametrize("fault, words", [
    ("overload", "overload"), ("overheat", "overheat"), ("voltage", "voltage"),
])
def test_a_servo_reporting_a_fault_stops_the_trial_with_pins_at_rest(fault, words):
    bus = sim_bus()
    bus.sim.servos[7].error_bits = StatusError[fault.upper()]
    with pytest.raises(PlaybackAborted, match=f"servo 7 \\(pin 7\\) reports {words}"):
        play_trial(bus, pulse_train([7], 3, 6), bus.clock)
    assert_safe(bus)


def test_a_port_that_disappears_mid_run_stops_playback_and_says_so():
    bus = sim_bus()
    bus.sim.vanish_after_packets = bus.sim.packets_received + 5
    with pytest.raises(PlaybackAborted) as caught:
        play_trial(bus, pulse_train([1], 10, 10), bus.clock)
    assert "lost" in str(caught.value) and "cut servo power" in str(caught.value)
    assert isinstance(caught.value.__cause__, PortLost)
    assert caught.value.safe_stop.port_lost


def test_a_missing_servo_mid_session_is_reported_as_not_confirmed_safe():
    bus = sim_bus()
    del bus.sim.servos[11]  # its cable came loose after connecting
    report = bus.rest_and_release()
    assert report.silent_ids == (11,)
    assert 11 not in report.released_ids and len(report.released_ids) == 15
