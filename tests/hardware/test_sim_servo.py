"""A simulated STS3215 as a client that only sends bytes sees it: table, instructions, bring-up."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.hardware.feetech.models import STS3215_C001
from pinarray.hardware.feetech.registers import (
    BROADCAST_ID,
    Instruction,
    Register,
    StatusError,
    encode_position,
    to_bytes,
)

from .raw import RawBus, packet

UNLOCK, LOCK = bytes([0]), bytes([1])


def reg(register: Register, value: int) -> tuple[int, bytes]:
    return register.address, to_bytes(value, register.size)


def test_a_fresh_servo_reads_the_vendors_factory_table():
    bus = RawBus("ids=1")
    expected = {
        Register.FIRMWARE_MAJOR: 3, Register.FIRMWARE_MINOR: 6, Register.MODEL_NUMBER: 777,
        Register.ID: 1, Register.BAUD_RATE: 0, Register.RETURN_DELAY_TIME: 250,
        Register.STATUS_RETURN_LEVEL: 1, Register.MIN_ANGLE_LIMIT: 0,
        Register.MAX_ANGLE_LIMIT: 4095, Register.MAX_TEMPERATURE_LIMIT: 70,
        Register.MAX_VOLTAGE_LIMIT: 80, Register.MIN_VOLTAGE_LIMIT: 40,
        Register.MAX_TORQUE: 1000, Register.PHASE: 12, Register.TORQUE_LIMIT: 1000,
        Register.TORQUE_ENABLE: 0, Register.LOCK: 0, Register.PRESENT_VOLTAGE: 74,
    }
    found = {r: bus.read_int(1, r.address, r.size) for r in expected}
    assert found == expected


def test_renumbering_with_unlock_write_lock_moves_the_servo_to_its_new_id():
    bus = RawBus("ids=1")
    assert bus.write(1, *reg(Register.LOCK, 0))
    (ack,) = bus.write(1, *reg(Register.ID, 7))
    assert ack.servo_id == 1  # the answer carries the id the instruction was sent to
    assert bus.write(7, *reg(Register.LOCK, 1))
    assert bus.ping(1) == []
    assert [s.servo_id for s in bus.ping(7)] == [7]
    assert list(bus.sim.servos) == [7]
    assert bus.sim.servos[7].eeprom_writes == [(Register.ID, bytes([7]))]


def test_every_write_whose_bytes_reach_the_id_register_renumbers_and_others_do_not():
    bus = RawBus("ids=1-3")
    bus.write(1, 3, bytes([0, 0, 9]))  # from the (read-only) model number on, ID included
    bus.send(BROADCAST_ID, Instruction.SYNC_WRITE, bytes([Register.ID.address, 1, 2, 12, 3, 13]))
    assert sorted(bus.sim.servos) == [9, 12, 13]
    bus.write(9, Register.BAUD_RATE.address, bytes([0, 0]))  # right after the ID: stays 9
    bus.send(BROADCAST_ID, Instruction.SYNC_WRITE, bytes([Register.LOCK.address, 1, 12, 0, 13, 0]))
    assert sorted(bus.sim.servos) == [9, 12, 13]
    assert [s.servo_id for s in bus.ping(9) + bus.ping(12) + bus.ping(13)] == [9, 12, 13]
    assert bus.ping(1) == bus.ping(2) == bus.ping(3) == []


def test_an_id_written_while_locked_works_until_power_off_and_one_written_unlocked_stays():
    bus = RawBus("ids=1-2")
    bus.write(1, *reg(Register.LOCK, 1))
    bus.write(1, *reg(Register.ID, 11))
    bus.write(2, *reg(Register.LOCK, 0))
    bus.write(2, *reg(Register.ID, 12))
    assert bus.ping(11) and bus.ping(12) and not bus.ping(1)
    bus.sim.power_cycle()
    assert bus.ping(1) and bus.ping(12) and not bus.ping(11)
    assert sorted(bus.sim.servos) == [1, 12]


def test_bring_up_one_fresh_servo_at_a_time_each_shipping_at_id_1():
    bus = RawBus("ids=1")
    for new_id in (2, 3):
        bus.write(1, *reg(Register.ID, new_id))
        bus.sim.plug_in()  # the next servo from the box
    assert sorted(bus.sim.servos) == [1, 2, 3]
    assert [bus.read_int(i, Register.MODEL_NUMBER.address, 2) for i in (1, 2, 3)] == [777] * 3


def test_a_new_baud_rate_takes_effect_at_once():
    bus = RawBus("ids=1&baud=1000000")
    bus.write(1, *reg(Register.BAUD_RATE, 4))  # code 4 = 115200 bit/s
    assert bus.ping(1) == []
    bus.port.baudrate = 115_200
    assert [s.servo_id for s in bus.ping(1)] == [1]


def test_status_return_level_0_answers_only_read_and_ping():
    bus = RawBus("ids=3")
    assert bus.write(3, *reg(Register.STATUS_RETURN_LEVEL, 0)) == []  # in force at once
    assert bus.write(3, *reg(Register.ACCELERATION, 20)) == []
    assert bus.read_int(3, Register.ACCELERATION.address, 1) == 20
    assert [s.servo_id for s in bus.ping(3)] == [3]


def test_reg_write_waits_for_action_and_is_acknowledged():
    bus = RawBus("ids=1-2")
    goal = to_bytes(encode_position(2300), 2)
    for servo_id in (1, 2):
        (ack,) = bus.send(servo_id, Instruction.REG_WRITE, bytes([42]) + goal)
        assert ack.servo_id == servo_id
    assert bus.read_int(1, Register.REG_WRITE_PENDING.address, 1) == 1
    assert bus.sim.servos[1].goal_steps == 0 and not bus.sim.servos[1].torque_enabled
    assert bus.send(BROADCAST_ID, Instruction.ACTION) == []  # broadcast: nobody answers
    assert [bus.sim.servos[i].goal_steps for i in (1, 2)] == [2300, 2300]
    assert bus.read_int(2, Register.REG_WRITE_PENDING.address, 1) == 0


def test_reset_restores_the_factory_table_but_keeps_the_id():
    bus = RawBus("ids=4&return_delay_us=0")
    bus.write(4, *reg(Register.MAX_ANGLE_LIMIT, 3000))
    bus.write(4, *reg(Register.STATUS_RETURN_LEVEL, 1))
    (ack,) = bus.send(4, Instruction.RESET)
    assert ack.servo_id == 4
    assert bus.read_int(4, Register.MAX_ANGLE_LIMIT.address, 2) == 4095
    assert bus.read_int(4, Register.RETURN_DELAY_TIME.address, 1) == 250


def test_one_servo_answers_a_broadcast_ping_with_its_own_id():
    bus = RawBus("ids=9")
    assert [(s.servo_id, s.error) for s in bus.broadcast_ping()] == [(9, 0)]


def test_several_servos_answering_a_broadcast_ping_together_collide():
    # Feetech's manual: "multiple servos can not use broadcast PING instructions on the bus".
    bus = RawBus("ids=1-3")
    heard = bus.broadcast_ping()
    assert len(heard) < 3 and bus.garbage > 0


def test_broadcast_ping_answers_apart_in_time_are_all_heard():
    bus = RawBus("ids=1-3")
    for servo_id, delay in ((1, 0), (2, 100), (3, 200)):  # 0, 200 and 400 us apart
        bus.write(servo_id, *reg(Register.RETURN_DELAY_TIME, delay))
    assert [s.servo_id for s in bus.broadcast_ping()] == [1, 2, 3]


def test_two_servos_renumbered_onto_one_id_both_answer_and_collide():
    bus = RawBus("ids=1-2&return_delay_us=0")
    bus.write(2, *reg(Register.ID, 1))
    assert list(bus.sim.servos) == [1]
    bus.write(1, *reg(Register.TORQUE_LIMIT, 999))  # both hear it; answers overlap
    assert [s.get(Register.TORQUE_LIMIT) for s in bus.sim.all_servos()] == [999, 999]


@pytest.mark.parametrize("goal, reached", [
    (5000, 4095), (encode_position(-5), 0), (2200, 2200),
])
def test_goals_outside_the_angle_limits_are_clamped(goal, reached):
    bus = RawBus("ids=1&backlash_deg=0")
    bus.write(1, *reg(Register.GOAL_POSITION, goal))
    bus.wait_ns(3_000_000_000)
    assert bus.present_steps(1) == reached
    assert bus.read_int(1, Register.GOAL_POSITION.address, 2) == goal  # kept as written


def test_calibrated_angle_limits_clamp_too():
    bus = RawBus("ids=1&backlash_deg=0")
    bus.write(1, *reg(Register.MIN_ANGLE_LIMIT, 1900))
    bus.write(1, *reg(Register.MAX_ANGLE_LIMIT, 2300))
    bus.write(1, *reg(Register.GOAL_POSITION, 2500))
    bus.wait_ns(1_000_000_000)
    assert bus.present_steps(1) == 2300


def test_a_goal_written_with_torque_off_turns_torque_on_and_moves_the_horn():
    bus = RawBus("ids=1")
    # The vendor's WritePosEx: acceleration, goal, time, speed from address 41, no torque write.
    bus.write(1, 41, bytes([0]) + to_bytes(2500, 2) + bytes(2) + to_bytes(0, 2))
    assert bus.read_int(1, Register.TORQUE_ENABLE.address, 1) == 1
    bus.wait_ns(1_000_000_000)
    assert bus.present_steps(1) == 2500


def test_torque_off_leaves_the_horn_where_it_is():
    bus = RawBus("ids=1")
    bus.write(1, *reg(Register.GOAL_POSITION, 3000))
    bus.wait_ns(100_000_000)
    bus.write(1, *reg(Register.TORQUE_ENABLE, 0))
    stopped = bus.present_steps(1)
    bus.wait_ns(1_000_000_000)
    assert 2048 < stopped < 3000
    assert bus.present_steps(1) == stopped
    assert bus.read_int(1, Register.MOVING.address, 1) == 0


def test_enabling_torque_before_any_goal_sends_the_horn_to_the_stale_goal_0():
    bus = RawBus("ids=1&backlash_deg=0")
    bus.write(1, *reg(Register.TORQUE_ENABLE, 1))
    bus.wait_ns(2_000_000_000)
    assert bus.present_steps(1) == 0


def test_torque_128_makes_the_present_position_read_2048():
    bus = RawBus("ids=1&backlash_deg=0")
    bus.write(1, *reg(Register.GOAL_POSITION, 3000))
    bus.wait_ns(1_000_000_000)
    bus.write(1, *reg(Register.TORQUE_ENABLE, 128))
    assert bus.present_steps(1) == 2048
    assert bus.read_int(1, Register.TORQUE_ENABLE.address, 1) == 1
    bus.wait_ns(1_000_000_000)
    assert bus.present_steps(1) == 2048  # it held still


def test_a_supply_outside_the_voltage_limits_shows_in_every_status_packet():
    bus = RawBus("ids=1&supply_v=12")  # a 7.4 V servo on a 12 V supply
    (status,) = bus.ping(1)
    assert status.error == StatusError.VOLTAGE
    assert bus.read_int(1, Register.PRESENT_VOLTAGE.address, 1) == 120


def test_a_sync_read_is_answered_in_the_order_of_the_ids_asked():
    bus = RawBus("ids=1-4")
    replies = bus.send(BROADCAST_ID, Instruction.SYNC_READ, bytes([56, 2, 3, 1, 4]))
    assert [s.servo_id for s in replies] == [3, 1, 4]


def test_a_sync_write_reaches_only_the_servos_named():
    bus = RawBus("ids=1-4")
    body = bytes([42, 2]) + bytes([2]) + to_bytes(2100, 2) + bytes([4]) + to_bytes(1900, 2)
    assert bus.send(BROADCAST_ID, Instruction.SYNC_WRITE, body) == []
    assert [bus.sim.servos[i].goal_steps for i in (1, 2, 3, 4)] == [0, 2100, 0, 1900]


def test_read_only_registers_ignore_writes():
    bus = RawBus("ids=1")
    bus.write(1, *reg(Register.MODEL_NUMBER, 1234))
    assert bus.read_int(1, Register.MODEL_NUMBER.address, 2) == 777


def test_an_unknown_instruction_gets_no_answer():
    bus = RawBus("ids=1")
    assert bus.send(1, 0x0B, to_bytes(2048, 2)) == []


@pytest.mark.parametrize("length", [245, 253, 254, 255])
def test_a_read_asking_more_than_one_packet_can_carry_gets_no_answer_and_the_bus_goes_on(length):
    # A status packet carries at most 250 - 6 = 244 data bytes; the servo cannot answer more.
    bus = RawBus("ids=1-2")
    assert bus.send(1, Instruction.READ, bytes([0, length])) == []
    assert bus.send(BROADCAST_ID, Instruction.SYNC_READ, bytes([0, length, 1, 2])) == []
    assert [s.servo_id for s in bus.ping(1)] == [1]
    assert bus.read_int(2, Register.MODEL_NUMBER.address, 2) == 777
    assert [len(s.params) for s in bus.send(1, Instruction.READ, bytes([0, 244]))] == [244]


def test_a_torn_packet_split_across_writes_is_still_understood():
    bus = RawBus("ids=1")
    ping = packet(1, Instruction.PING)
    bus.port.write(ping[:3])
    bus.port.write(ping[3:])
    bus.wait_ns(5_000_000)
    assert bus.port.read(64) == bytes.fromhex("ffff010200fc")


def test_the_default_model_is_the_7v4_sts3215():
    assert RawBus().sim.servos[1].model is STS3215_C001


@given(start=st.integers(56, 70), length=st.integers(1, 15), after_ms=st.integers(0, 80),
       faults=st.sampled_from(["", "&overload=1", "&voltage=1", "&overheat=1&load=0.3"]))
@settings(max_examples=60)
def test_any_part_of_the_feedback_block_reads_as_the_whole_block_does(start, length, after_ms,
                                                                       faults):
    """The simulator works out only the feedback registers a read asks for; what it answers
    is the same slice as a read of the whole block at that instant."""
    length = min(length, 71 - start)
    reads = []
    for part in ((start, length), (56, 15)):
        bus = RawBus("ids=1" + faults)
        bus.write(1, *reg(Register.GOAL_POSITION, 2400))
        bus.clock.sleep_until_ns(bus.clock.now_ns() + after_ms * 1_000_000)
        reads.append(bus.read(1, *part))
    part, whole = reads
    assert part == whole[start - 56 : start - 56 + length]
