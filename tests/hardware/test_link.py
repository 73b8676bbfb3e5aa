"""Exchanges: a late or stale reply never answers the wrong request, and nothing escapes raw."""

from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.clock import VirtualClock
from pinarray.errors import BusError
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech import packets
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.feetech import FeetechBus
from pinarray.hardware.feetech.link import Expected, Latency, Link, WireLost
from pinarray.hardware.feetech.registers import Register
from pinarray.hardware.feetech.sim import status_packet

from .lab import sim_bus

MS = 1_000_000


class ScriptedWire:
    """A wire whose servo answers as ``answer(packet)`` says: [(delay_ns, reply bytes)]."""

    name = "scripted"

    def __init__(self, clock: VirtualClock, answer: Callable[[bytes], list[tuple[int, bytes]]]):
        self.clock = clock
        self.answer = answer
        self.arriving: list[tuple[int, bytes]] = []
        self.requests: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.requests.append(data)
        now = self.clock.now_ns()
        self.arriving += [(now + delay, reply) for delay, reply in self.answer(data)]
        self.arriving.sort(key=lambda item: item[0])

    def _take_arrived(self) -> bytes:
        now = self.clock.now_ns()
        arrived = [reply for at, reply in self.arriving if at <= now]
        self.arriving = [(at, reply) for at, reply in self.arriving if at > now]
        return b"".join(arrived)

    def read_some(self, deadline_ns: int) -> bytes:
        while True:
            data = self._take_arrived()
            if data:
                return data
            if self.clock.now_ns() >= deadline_ns:
                return b""
            next_ns = min([at for at, _ in self.arriving] + [deadline_ns])
            self.clock.sleep_until_ns(next_ns)

    def discard_input(self) -> int:
        return len(self._take_arrived())

    def close(self) -> None:
        pass


def link_with(answer, timer_ms=1) -> tuple[Link, ScriptedWire]:
    clock = VirtualClock()
    wire = ScriptedWire(clock, answer)
    link = Link(wire, clock, 1_000_000, Latency(timer_ms))
    link.return_delay_ns = {i: 0 for i in range(254)}
    return link, wire


def position_reply(servo_id: int, position: int) -> bytes:
    return status_packet(servo_id, 0, position.to_bytes(2, "little"))


def test_a_reply_that_arrives_after_the_timeout_is_not_taken_for_the_next_request():
    # Servo 5's first answer comes 50 ms late; its second at once. The late one must be
    # drained, not read as the answer to the second request.
    late = [True]

    def answer(packet):
        servo_id = packet[2]
        value = 1111 if late[0] else 2222
        delay = 50 * MS if late[0] else 0
        late[0] = False
        return [(delay, position_reply(servo_id, value))]

    link, wire = link_with(answer)
    read = packets.read(5, 56, 2)
    assert link.exchange(read, [Expected(5, 2)]) == {}  # timed out: nothing accepted
    link.clock.sleep_until_ns(link.clock.now_ns() + 60 * MS)  # the late reply is in by now
    (status,) = link.exchange(read, [Expected(5, 2)]).values()
    assert int.from_bytes(status.params, "little") == 2222
    assert link.counters.stale_bytes == 8 and link.counters.timeouts == 1


def test_a_reply_from_another_servo_or_of_another_length_is_counted_and_skipped():
    def answer(packet):
        return [(100_000, position_reply(6, 999)),  # another servo's stale answer
                (200_000, status_packet(5, 0, b"\x01\x02\x03\x04")),  # same servo, wrong length
                (300_000, position_reply(5, 2048))]

    link, _ = link_with(answer)
    replies = link.exchange(packets.read(5, 56, 2), [Expected(5, 2)])
    assert int.from_bytes(replies[5].params, "little") == 2048
    assert link.counters.mismatched_replies == 1  # servo 6's
    assert link.reader.skipped_bytes > 0  # the too-long one is not even a reply to this request


def test_a_sync_read_keeps_the_replies_that_came_when_one_servo_is_silent():
    def answer(packet):
        return [(100_000, position_reply(1, 10)), (300_000, position_reply(3, 30))]

    link, _ = link_with(answer)
    replies = link.exchange(packets.sync_read(56, 2, [1, 2, 3]),
                            [Expected(1, 2), Expected(2, 2), Expected(3, 2)])
    assert sorted(replies) == [1, 3]


chunks = st.lists(st.tuples(st.integers(0, 3_000_000), st.binary(max_size=12)), max_size=6)


@settings(max_examples=200)
@given(chunks, st.sampled_from([3, 5, 9]))
def test_no_garbage_on_the_wire_makes_a_read_raise_or_answer_for_the_wrong_servo(junk, servo_id):
    """Random bytes at random times, then silence: a clean BusError naming the servo."""

    def answer(packet):
        return list(junk)

    clock = VirtualClock()
    bus = FeetechBus(Link(ScriptedWire(clock, answer), clock, 1_000_000, Latency(1)), clock)
    try:
        data, _ = bus.read(servo_id, Register.PRESENT_POSITION)
    except BusError as error:
        assert f"servo {servo_id}" in str(error) and "PRESENT_POSITION" in str(error)
    else:
        # Only a checksum-correct packet from this servo with two data bytes can answer.
        assert any(position_reply(servo_id, int.from_bytes(data, "little")) in chunk
                   for _, chunk in junk)


def test_the_latency_allowance_comes_from_the_adapters_timer_or_is_measured():
    assert Latency(timer_ms=16).allowance_ns == 17 * MS  # an FTDI adapter left at 16 ms
    assert Latency(timer_ms=1).allowance_ns == 2 * MS
    unknown = Latency(timer_ms=None)
    assert unknown.allowance_ns == 34 * MS  # the vendor SDK's caution until measured
    for _ in range(3):
        unknown.record(200_000)  # a pseudo-terminal answering within 0.2 ms
    assert unknown.allowance_ns == 1 * MS


def test_a_vanished_device_is_a_lost_port_naming_what_was_being_done():
    class Gone(ScriptedWire):
        def write(self, data):
            raise WireLost(5, "write failed: Input/output error")

    clock = VirtualClock()
    bus = FeetechBus(Link(Gone(clock, lambda p: []), clock, 1_000_000, Latency(1)), clock)
    bus.setup = BusSetup((ServoSetup(4, 4, 2048, 1900, 2300),))
    with pytest.raises(BusError, match="lost while reading TORQUE_ENABLE .* of servo 4"):
        bus.read(4, Register.TORQUE_ENABLE)


def test_one_slow_reply_at_connect_does_not_stop_read_backs_from_being_planned():
    latency = Latency(timer_ms=None)
    latency.record(40 * MS)  # a simulator process still starting up
    for _ in range(30):
        latency.record(150_000)
    assert latency.allowance_ns == 120 * MS  # waiting for a reply stays patient...
    assert latency.expected_ns == 1 * MS  # ...but a read-back plans for the usual 0.15 ms


def test_a_device_that_goes_away_is_told_from_a_quiet_one():
    import os

    from pinarray.hardware.feetech.link import FdWire

    read_end, write_end = os.pipe()
    os.set_blocking(read_end, False)
    wire = FdWire(read_end, __import__("pinarray.clock").clock.MonotonicClock(), "a pipe")
    assert wire.read_some(wire.clock.now_ns() + 1_000_000) == b""  # quiet: nothing yet
    os.close(write_end)  # the other end is gone: reads return nothing, and it is no tty
    with pytest.raises(WireLost, match="the device is gone"):
        wire.read_some(wire.clock.now_ns() + 1_000_000)
    wire.close()


def test_a_port_lost_mid_stop_still_broadcasts_torque_off():
    class ReadsFail(ScriptedWire):
        def read_some(self, deadline_ns):
            raise WireLost(5, "read failed: Input/output error")

    clock = VirtualClock()
    wire = ReadsFail(clock, lambda packet: [])
    bus = FeetechBus(Link(wire, clock, 1_000_000, Latency(1)), clock)
    bus.setup = BusSetup((ServoSetup(4, 4, 2048, 1900, 2300),))
    report = bus.rest_and_release()
    assert report.port_lost
    assert wire.requests[-1] == packets.write(0xFE, Register.TORQUE_ENABLE.address, b"\x00")


def test_a_reply_held_up_by_a_busy_host_is_waited_for_on_retry():
    # The allowance learnt on a quiet pseudo-terminal is 1 ms; then the host stalls the
    # simulator for 12 ms on every request. The retries wait longer each time and get it.
    def answer(packet):
        return [(12 * MS, position_reply(packet[2], 2048))]

    clock = VirtualClock()
    wire = ScriptedWire(clock, answer)
    latency = Latency(timer_ms=None)
    for _ in range(3):
        latency.record(200_000)
    link = Link(wire, clock, 1_000_000, latency)
    bus = FeetechBus(link, clock)
    data, _ = bus.read(5, Register.PRESENT_POSITION)
    assert int.from_bytes(data, "little") == 2048
    assert len(wire.requests) == 3  # 1 ms, 4 ms, then 16 ms: the third attempt waits long enough


def test_a_silent_servo_costs_the_whole_growing_wait_and_is_named():
    clock = VirtualClock()
    latency = Latency(timer_ms=1)  # 2 ms allowance
    bus = FeetechBus(Link(ScriptedWire(clock, lambda packet: []), clock, 1_000_000, latency), clock)
    start_ns = clock.now_ns()
    with pytest.raises(BusError, match="servo 7: reading PRESENT_POSITION .* after 4 attempt"):
        bus.read(7, Register.PRESENT_POSITION)
    waited_ns = clock.now_ns() - start_ns
    assert (1 + 4 + 16 + 64) * 2 * MS <= waited_ns < (1 + 4 + 16 + 64) * 2 * MS + 20 * MS


@pytest.mark.parametrize("baud", [115_200, 38_400])
def test_a_read_back_written_behind_a_frame_still_on_the_wire_waits_for_it(baud):
    # 16 goals take 4.9 ms on the wire at 115 200 baud (14.6 ms at 38 400): the request goes
    # out behind them, and so do the answers; counted from its own write, the last answer
    # would be given up for lost.
    bus = sim_bus(f"baud={baud}")
    ids = tuple(range(1, 17))
    bus.write_goals({i: 2100 for i in ids})
    readings = bus.read_goals((13, 14, 15, 16), bus.clock.now_ns() + 200 * MS)
    assert {i: r.goal_steps for i, r in readings.items()} == {13: 2100, 14: 2100, 15: 2100,
                                                             16: 2100}
