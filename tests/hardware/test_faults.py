"""Transient faults are retried and counted; persistent ones name the servo and register."""

import re

import pytest

from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.driver import PortLost
from pinarray.hardware.feetech.registers import Register, StatusError
from pinarray.player.playback import PlaybackAborted, play_trial

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


def test_lost_writes_fail_loudly_while_reads_still_work():
    bus = sim_bus("drop_writes=1", connect=False)
    (reading,) = bus.read_telemetry((4,))
    assert reading.voltage_v == 7.4
    with pytest.raises(BusError, match=r"servo 4: writing TORQUE_ENABLE .*no status packet"):
        bus.write(4, Register.TORQUE_ENABLE, 1)
    assert not bus.sim.servos[4].torque_enabled


def test_a_lost_sync_write_is_silent_and_the_next_one_arrives():
    bus = sim_bus()
    bus.sim.drop_writes_next = 1
    bus.write_goals({5: 2200, 6: 2100})
    assert [bus.sim.servos[i].goal_steps for i in (5, 6)] == [2048, 2048]
    bus.write_goals({5: 2201, 6: 2101})
    assert [bus.sim.servos[i].goal_steps for i in (5, 6)] == [2201, 2101]


def test_a_late_status_packet_is_retried_and_then_arrives_after_the_host_gave_up():
    bus = sim_bus()
    bus.sim.late_next = 1
    before = bus.sim.late_ns
    (reading,) = bus.read_telemetry((4,))
    assert reading.position_steps == 2048 and bus.stats().retries == 1
    port = bus.link.wire.port  # the in-process SimSerial
    assert port.in_waiting == 0
    bus.clock.sleep_until_ns(bus.clock.now_ns() + before)
    assert port.in_waiting > 0  # the stale answer now waits in the input buffer


def test_late_answers_come_late_by_late_ms_in_virtual_time():
    from .raw import RawBus, packet, parse_status

    bus = RawBus("ids=1&late=1&late_ms=40")
    bus.port.write(packet(1, 0x01))
    bus.wait_ns(39_000_000)
    assert bus.port.read(64) == b""
    bus.wait_ns(2_000_000)
    assert [s.servo_id for s in parse_status(bus.port.read(64))[0]] == [1]


@pytest.mark.parametrize("query, key", [
    ("return_delay_us=-2", "return_delay_us"),
    ("return_delay_us=100000", "return_delay_us"),
    ("baud=0", "baud"),
    ("baud=-9600", "baud"),
    ("baud=9600", "baud"),
    ("drop=1.5", "drop"),
    ("drop_writes=-0.1", "drop_writes"),
    ("corrupt=nan", "corrupt"),
    ("late=2", "late"),
    ("late_ms=-1", "late_ms"),
    ("late_ms=1e9", "late_ms"),
    ("vanish_after=-1", "vanish_after"),
    ("seed=-3", "seed"),
    ("supply_v=0", "supply_v"),
    ("backlash_deg=45", "backlash_deg"),
    ("load=2", "load"),
    ("model=sts9999", "model"),
    ("drop=lots", "drop"),
    ("seed=1.5", "seed"),
])
def test_a_sim_url_value_out_of_range_is_one_line_naming_the_key(query, key):
    from pinarray.hardware.feetech.faults import parse_sim_url

    with pytest.raises(PinArrayError) as caught:
        parse_sim_url(f"sim://?{query}")
    message = str(caught.value)
    assert f"key {key}:" in message and "\n" not in message and query.split("=")[1] in message


def test_every_new_key_reads_into_the_config():
    from pinarray.hardware.feetech.faults import parse_sim_url

    config = parse_sim_url(
        "sim://?drop_writes=0.1&late=0.2&late_ms=30&model=sts3215-12v&supply_v=11.5"
        "&backlash_deg=0.5&load=0.25&baud=500000&return_delay_us=0"
    )
    faults = config.faults
    assert (faults.drop_write_rate, faults.late_rate, faults.late_ns) == (0.1, 0.2, 30_000_000)
    assert (config.model, config.supply_v, config.backlash_deg) == ("sts3215-12v", 11.5, 0.5)
    assert (config.load_fraction, config.baud_rate, config.return_delay_us) == (0.25, 500_000, 0)


def test_servos_that_lost_power_with_the_usb_still_up_do_not_hold_up_the_safe_stop():
    # Every servo goes silent after connect (their supply cut, the adapter still there): the
    # stop waits for rest at most its timeout, tries each torque-off twice, and says who is
    # silent. Measured in virtual time: 16 silent servos cost the rest timeout and about 5
    # reply allowances (1 + 4) each, not 85 per read and per write.
    bus = sim_bus()
    bus.sim.servos.clear()
    started_ns = bus.clock.now_ns()
    report = bus.rest_and_release()
    took_ns = bus.clock.now_ns() - started_ns
    assert report.silent_ids == tuple(range(1, 17)) and not report.complete
    assert took_ns < 2_000_000_000 + 16 * 5 * 3_000_000


@pytest.mark.parametrize("url", ["sim://?ids=1&ids=2", "sim://?drop=0.1&seed=3&drop=0.2"])
def test_a_sim_url_key_given_twice_is_refused_not_read_as_its_last_value(url):
    from pinarray.hardware.feetech.faults import parse_sim_url

    with pytest.raises(PinArrayError, match="expected it once .* found it twice"):
        parse_sim_url(url)


@pytest.mark.parametrize(("url", "said"), [
    ("sim://pca9685?address=0x40", "found 'pca9685' after sim:// (sim://pca9685 simulates a "
                                   "PCA9685 board, not STS servos)"),
    ("sim://pca968", "found 'pca968' after sim://"),
    ("sim://host/ids=1", "found 'host/ids=1' after sim://"),
])
def test_a_sim_url_naming_something_else_than_sts_servos_is_refused_not_simulated_as_them(
        url, said):
    # `pinarray play` of a servo-bus protocol once ran simulated STS servos for a board's URL.
    from pinarray.hardware.feetech.faults import parse_sim_url

    with pytest.raises(PinArrayError, match=re.escape(said)):
        parse_sim_url(url)
    assert parse_sim_url("sim://").ids == parse_sim_url("sim://?").ids == tuple(range(1, 17))
