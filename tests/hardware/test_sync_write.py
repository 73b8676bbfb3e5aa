"""Goal positions go out as sync writes, byte for byte, and only for servos that changed."""

from pinarray.hardware.feetech.registers import checksum

from .lab import sim_bus


def test_sync_write_bytes_follow_the_reference_packet_format():
    bus = sim_bus()
    bus.write_goals({1: 2100, 2: 2000})
    packet = bus.link.wire.port.writes[-1]
    # FF FF FE len 83 addr L (id lo hi) x 2 chk, len = params + 2
    body = bytes([0xFE, 4 + 2 * 3, 0x83, 42, 2, 1, 0x34, 0x08, 2, 0xD0, 0x07])
    assert packet == b"\xff\xff" + body + bytes([checksum(body)])


def test_sync_write_carries_only_the_servos_whose_goal_changed():
    bus = sim_bus()
    bus.write_goals({i: 2048 for i in range(1, 17)})
    sent_before = len(bus.link.wire.port.writes)
    assert bus.write_goals({i: 2048 for i in range(1, 17)} | {4: 2100, 9: 2000}) == 2
    packet = bus.link.wire.port.writes[-1]
    assert len(bus.link.wire.port.writes) == sent_before + 1
    assert [packet[7], packet[10]] == [4, 9]  # the ids inside the one packet
    assert len(packet) == 8 + 2 * 3


def test_nothing_is_sent_when_no_goal_changed():
    bus = sim_bus()
    bus.write_goals({1: 2100})
    before = bus.stats().bytes_written
    assert bus.write_goals({1: 2100}) == 0
    assert bus.stats().bytes_written == before


def test_a_full_16_servo_frame_is_56_bytes_on_the_wire():
    bus = sim_bus()
    bus.write_goals({i: 2050 for i in range(1, 17)})
    assert len(bus.link.wire.port.writes[-1]) == 56


def test_simulated_servos_move_to_the_sync_written_goal():
    bus = sim_bus()
    bus.write_goals({3: 2200})
    bus.clock.sleep_until_ns(bus.clock.now_ns() + 300_000_000)
    (reading,) = bus.read_telemetry((3,))
    assert reading.position_steps == 2200
