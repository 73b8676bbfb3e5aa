"""Clients we did not write, driving `pinarray sim-serve` over its pseudo-terminal.

Two styles, written here from their documented behaviour (nothing imported from them):

vendor
    The Feetech SDK's example programs (FTServo_Python ``sms_sts/*.py``): ``ping``, a
    ``WritePosEx`` (acceleration, goal, time, speed from address 41) without enabling torque,
    ``time.sleep``, a read of Present Position; ``GroupSyncWrite`` and ``GroupSyncRead``.
LeRobot
    ``FeetechMotorsBus`` (src/lerobot/motors/feetech/feetech.py, motors_bus.py): a broadcast
    ping that reads 6-byte status packets until ``6*252`` bytes or a timeout of
    ``6*252*byte_ms + 3*252 + 16`` ms, then reads each finder's model number; ``setup_motor``
    (Torque_Enable 0, Lock 0, write ID, then the baud rate at the new id); ``sync_read`` with
    its patched packet timeout ``byte_ms*length + 3*byte_ms + 50`` ms.

Each client waits longer for a status packet here than it does (`VENDOR_WAIT_MS`): the
simulated servos share the processor with everything else on this machine, and these tests
are about what goes over the wire, not how soon (`make bench`).
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
import types

import pytest
from scservo_sdk import (
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

from pinarray.clock import VirtualClock
from pinarray.hardware.feetech.faults import parse_sim_url
from pinarray.hardware.feetech.models import STS3215_C001
from pinarray.hardware.feetech.registers import BROADCAST_ID, Instruction, Register
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.hardware.feetech.sim import SimBus, SimSerial

from .raw import packet, parse_status

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = pytest.mark.realtime

MAX_ID = 252


@pytest.fixture
def sim_serve(request):
    """``pinarray sim-serve`` in its own process; yields the pseudo-terminal's path."""
    ids = getattr(request, "param", "1")
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", "--ids", ids],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        yield process.stdout.readline().split(" on ")[1].split()[0]
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=10)


# How long the vendor's client waits for a status packet here. The SDK waits for the bytes on
# the wire, twice its adapter latency (LATENCY_TIMER, 16 ms) and 2 ms: 34 ms, which a simulated
# servo starved of the processor on a busy machine may miss (a real servo answers within its
# return delay). As if LATENCY_TIMER were set for a slow adapter: a bound against a hang, and
# an absent servo (a PING that must fail) costs a quarter of a second.
VENDOR_WAIT_MS = 250
# A broadcast ping waits for its answers at most this long between two looks at the clock, s.
BYTES_WAIT_S = 0.005


def vendor_port(path: str) -> tuple[PortHandler, PacketHandler]:
    port = PortHandler(path)
    assert port.openPort() and port.setBaudRate(1_000_000)

    def packet_timeout(packet_length: int) -> None:
        port.packet_start_time = port.getCurrentTime()
        port.packet_timeout = port.tx_time_per_byte * packet_length + VENDOR_WAIT_MS

    port.setPacketTimeout = packet_timeout
    return port, PacketHandler(0)


def write_pos_ex(handler, port, servo_id, position, speed=0, acc=0):
    """The vendor's WritePosEx: 7 bytes from Acceleration (41); torque is never written."""
    data = [acc, position & 0xFF, position >> 8, 0, 0, speed & 0xFF, speed >> 8]
    return handler.writeTxRx(port, servo_id, Register.ACCELERATION.address, len(data), data)


class LeRobotStyleBus:
    """What FeetechMotorsBus does on the wire, re-written from its documented behaviour."""

    def __init__(self, path: str, baud_rate: int = 1_000_000):
        self.port = PortHandler(path)
        assert self.port.openPort() and self.port.setBaudRate(baud_rate)
        self.handler = PacketHandler(0)
        self.port.setPacketTimeout = types.MethodType(self._packet_timeout, self.port)

    @staticmethod
    def _packet_timeout(port, packet_length):
        # LeRobot's patch of the SDK: bytes on the wire, 3 more, and 50 ms; here the vendor
        # client's wait instead of 50 ms (`VENDOR_WAIT_MS`: a starved simulator, not LeRobot).
        port.packet_start_time = port.getCurrentTime()
        port.packet_timeout = port.tx_time_per_byte * (packet_length + 3) + VENDOR_WAIT_MS

    def broadcast_ping(self) -> dict[int, int]:
        """Ids that answer a broadcast PING, with the model number each then reports."""
        port = self.port
        wait_length = 6 * MAX_ID
        byte_ms = 10_000.0 / port.getBaudRate()
        port.clearPort()
        port.writePort(packet(BROADCAST_ID, Instruction.PING))
        port.setPacketTimeoutMillis(wait_length * byte_ms + 3.0 * MAX_ID + 16.0)
        received = b""
        while not port.isPacketTimeout() and len(received) < wait_length:
            # Waiting for bytes, not spinning: the port reads without blocking, and a loop of
            # such reads burned a processor for the whole wait (0.8 s a ping here).
            select.select([port.ser], [], [], BYTES_WAIT_S)
            received += bytes(port.readPort(wait_length - len(received)))
        found, _ = parse_status(received)
        models = {}
        for status in found:
            data, result, error = self.handler.readTxRx(port, status.servo_id, 3, 2)
            if result == COMM_SUCCESS and not error:
                models[status.servo_id] = data[0] | data[1] << 8
        return models

    def write(self, servo_id: int, register: Register, value: int) -> None:
        data = list(value.to_bytes(register.size, "little"))
        result, error = self.handler.writeTxRx(
            self.port, servo_id, register.address, register.size, data
        )
        assert result == COMM_SUCCESS, self.handler.getTxRxResult(result)

    def setup_motor(self, old_id: int, new_id: int) -> None:
        self.write(old_id, Register.TORQUE_ENABLE, 0)
        self.write(old_id, Register.LOCK, 0)
        self.write(old_id, Register.ID, new_id)
        self.write(new_id, Register.BAUD_RATE, 0)  # 1 000 000 bit/s

    def sync_read(self, ids, register: Register) -> dict[int, int] | None:
        reader = GroupSyncRead(self.port, self.handler, register.address, register.size)
        for servo_id in ids:
            reader.addParam(servo_id)
        if reader.txRxPacket() != COMM_SUCCESS:
            return None
        return {i: reader.getData(i, register.address, register.size) for i in ids}

    def close(self) -> None:
        self.port.closePort()


def test_a_fresh_servo_renumbered_by_raw_writes_is_found_only_at_its_new_id(sim_serve):
    lerobot = LeRobotStyleBus(sim_serve)
    assert lerobot.broadcast_ping() == {1: 777}
    port, handler = vendor_port(sim_serve)
    for servo_id, register, value in ((1, Register.LOCK, 0), (1, Register.ID, 5),
                                      (5, Register.LOCK, 1)):
        result, error = handler.write1ByteTxRx(port, servo_id, register.address, value)
        assert (result, error) == (COMM_SUCCESS, 0)
    assert handler.ping(port, 5)[:2] == (777, COMM_SUCCESS)
    assert handler.ping(port, 1)[1] != COMM_SUCCESS
    port.closePort()
    assert lerobot.broadcast_ping() == {5: 777}
    lerobot.close()


def test_lerobots_setup_motor_moves_a_fresh_servo_to_the_id_it_asks_for(sim_serve):
    lerobot = LeRobotStyleBus(sim_serve)
    (found_id,) = lerobot.broadcast_ping()
    lerobot.setup_motor(found_id, 6)
    assert lerobot.broadcast_ping() == {6: 777}
    lerobot.close()


def test_a_broadcast_ping_at_the_wrong_speed_finds_nothing(sim_serve):
    lerobot = LeRobotStyleBus(sim_serve, baud_rate=500_000)
    assert lerobot.broadcast_ping() == {}
    lerobot.close()


def test_vendor_example_ping_write_wait_read_lands_on_the_goal(sim_serve):
    port, handler = vendor_port(sim_serve)
    assert handler.ping(port, 1)[:2] == (777, COMM_SUCCESS)
    assert write_pos_ex(handler, port, 1, 3072) == (COMM_SUCCESS, 0)
    time.sleep(1024 / STS3215_C001.speed_steps_per_s * 1.05 + STS3215_C001.spin_up_s)
    position, result, _ = handler.read2ByteTxRx(port, 1, Register.PRESENT_POSITION.address)
    moving, _, _ = handler.read1ByteTxRx(port, 1, Register.MOVING.address)
    port.closePort()
    assert (result, position, moving) == (COMM_SUCCESS, 3072, 0)


def test_a_vendor_style_move_takes_the_datasheet_time_within_5_percent():
    # The vendor SDK over the in-process port in virtual time: "wait" costs nothing and the
    # read happens exactly when asked. Half a turn at 0.222 s per 60 degrees: 0.666 s.
    clock = VirtualClock()
    sim = SimBus(parse_sim_url("sim://?ids=1"), clock)
    port = PortHandler("sim://")
    port.ser, port.is_open, port.baudrate = SimSerial(sim, clock, 1_000_000), True, 1_000_000
    port.tx_time_per_byte = 0.01
    handler = PacketHandler(0)
    datasheet_s = 180 / 60 * 0.222
    assert write_pos_ex(handler, port, 1, 0) == (COMM_SUCCESS, 0)
    sent_ns = clock.now_ns()
    positions = []
    for share in (0.95, 1.05):
        clock.sleep_until_ns(sent_ns + round(share * datasheet_s * 1e9))
        position, result, _ = handler.read2ByteTxRx(port, 1, Register.PRESENT_POSITION.address)
        positions.append(position)
    assert 0 < positions[0] < 2048 * 0.1 and positions[1] == 0


@pytest.mark.parametrize("sim_serve", ["1-4"], indirect=True)
def test_vendor_sync_write_then_sync_read_reports_every_servo(sim_serve):
    port, handler = vendor_port(sim_serve)
    writer = GroupSyncWrite(port, handler, Register.ACCELERATION.address, 7)
    for servo_id, goal in ((1, 1900), (2, 2000), (3, 2100), (4, 2200)):
        writer.addParam(servo_id, [0, goal & 0xFF, goal >> 8, 0, 0, 0, 0])
    assert writer.txPacket() == COMM_SUCCESS
    time.sleep(0.3)
    reader = GroupSyncRead(port, handler, Register.PRESENT_POSITION.address, 4)
    for servo_id in (1, 2, 3, 4):
        reader.addParam(servo_id)
    assert reader.txRxPacket() == COMM_SUCCESS
    positions = [reader.getData(i, Register.PRESENT_POSITION.address, 2) for i in (1, 2, 3, 4)]
    port.closePort()
    assert positions == [1900, 2000, 2100, 2200]


@pytest.mark.parametrize("sim_serve", ["1-16"], indirect=True)
def test_lerobot_sync_reads_keep_answering_while_all_16_servos_move(sim_serve):
    lerobot = LeRobotStyleBus(sim_serve)
    ids = list(range(1, 17))
    port, handler = lerobot.port, lerobot.handler
    writer = GroupSyncWrite(port, handler, Register.GOAL_POSITION.address, 2)
    for servo_id in ids:
        writer.addParam(servo_id, [0x00, 0x0C])  # 3072: a 90-degree turn for everyone
    assert writer.txPacket() == COMM_SUCCESS
    readings = []
    for _ in range(20):
        # As LeRobot's sync_read(..., num_retry=2): a stall of this shared machine may cost
        # one attempt, a simulator that falls behind while servos move costs them all.
        attempts = (lerobot.sync_read(ids, Register.PRESENT_POSITION) for _ in range(3))
        readings.append(next((r for r in attempts if r is not None), None))
        time.sleep(0.01)
    lerobot.close()
    assert None not in readings
    for reading in readings:
        assert sorted(reading) == ids and all(2048 <= p <= 3072 for p in reading.values())
    assert readings[0][1] < readings[-1][1]  # they were moving while being read


def test_the_pseudo_terminal_round_trip_moves_the_horn_in_the_datasheet_time():
    # The same move through a real pseudo-terminal, timed from the instruction's arrival.
    server = PtyServer(parse_sim_url("sim://?ids=1"), record_arrivals=True).start()
    try:
        port, handler = vendor_port(server.path)
        assert write_pos_ex(handler, port, 1, 0) == (COMM_SUCCESS, 0)
        port.closePort()
    finally:
        server.stop()
    (arrival,) = [a for a in server.arrivals if a.instruction == Instruction.WRITE]
    servo = server.sim.servos[1]
    datasheet_ns = round(180 / 60 * 0.222 * 1e9)
    assert servo.position_at_ns(arrival.arrival_ns + round(0.95 * datasheet_ns)) > 0
    assert servo.position_at_ns(arrival.arrival_ns + round(1.05 * datasheet_ns)) == 0
