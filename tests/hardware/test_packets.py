"""Packets on the wire are the vendor SDK's, byte for byte; replies are found in any noise."""

from hypothesis import given
from hypothesis import strategies as st
from scservo_sdk import GroupSyncRead, GroupSyncWrite, PacketHandler

from pinarray.hardware.feetech import packets
from pinarray.hardware.feetech.packets import StatusPacket, StatusReader
from pinarray.hardware.feetech.sim import status_packet


class RecordingPort:
    """Just enough of the SDK's PortHandler to see what it would write; nothing answers."""

    def __init__(self):
        self.is_using = False
        self.written = []

    def clearPort(self):  # noqa: N802 - the SDK's name
        pass

    def writePort(self, packet):  # noqa: N802
        self.written.append(bytes(packet))
        return len(packet)

    def readPort(self, length):  # noqa: N802
        return b""

    def setPacketTimeout(self, length):  # noqa: N802
        pass

    def isPacketTimeout(self):  # noqa: N802
        return True


def sdk_bytes(call) -> bytes:
    port = RecordingPort()
    call(port, PacketHandler(0))
    (packet,) = port.written
    return packet


servo_ids = st.integers(0, 253)
addresses = st.integers(0, 255)


@given(servo_ids)
def test_ping_is_the_sdks_ping(servo_id):
    expected = sdk_bytes(lambda port, sdk: sdk.txRxPacket(port, [0, 0, servo_id, 2, 1, 0]))
    assert packets.ping(servo_id) == expected


@given(servo_ids, addresses, st.integers(1, 64))
def test_read_is_the_sdks_read(servo_id, address, length):
    expected = sdk_bytes(lambda port, sdk: sdk.readTxRx(port, servo_id, address, length))
    assert packets.read(servo_id, address, length) == expected


@given(servo_ids, addresses, st.binary(min_size=1, max_size=8))
def test_write_is_the_sdks_write(servo_id, address, data):
    expected = sdk_bytes(
        lambda port, sdk: sdk.writeTxRx(port, servo_id, address, len(data), list(data)))
    assert packets.write(servo_id, address, data) == expected


@given(st.dictionaries(st.integers(0, 252), st.integers(0, 65535), min_size=1, max_size=16))
def test_a_goal_sync_write_is_the_sdks_group_sync_write(goals):
    def call(port, sdk):
        group = GroupSyncWrite(port, sdk, 42, 2)
        for servo_id, value in goals.items():
            group.addParam(servo_id, list(value.to_bytes(2, "little")))
        group.txPacket()

    items = [(i, v.to_bytes(2, "little")) for i, v in goals.items()]
    assert packets.sync_write(42, 2, items) == sdk_bytes(call)


@given(st.lists(st.integers(0, 252), min_size=1, max_size=16, unique=True))
def test_a_sync_read_is_the_sdks_group_sync_read(ids):
    def call(port, sdk):
        group = GroupSyncRead(port, sdk, 56, 2)
        for servo_id in ids:
            group.addParam(servo_id)
        group.txPacket()

    assert packets.sync_read(56, 2, ids) == sdk_bytes(call)


status_packets = st.builds(
    StatusPacket, servo_id=st.integers(0, 253), error=st.integers(0, 0x7F),
    params=st.binary(max_size=12),
)


def wire_bytes(status: StatusPacket) -> bytes:
    return status_packet(status.servo_id, status.error, status.params)


@given(st.lists(st.tuples(status_packets, st.binary(max_size=6)), max_size=8),
       st.lists(st.integers(1, 7), max_size=30))
def test_every_status_packet_is_found_however_the_bytes_are_chopped(items, chops):
    # Noise that cannot hold a header between whole packets: all packets come out, in order.
    stream = b"".join(wire_bytes(s) + noise.replace(b"\xff", b"") for s, noise in items)
    reader, found, position = StatusReader(), [], 0
    for size in chops + [len(stream)]:
        found += reader.feed(stream[position : position + size])
        position += size
    assert found == [s for s, _ in items]


@given(st.one_of(status_packets.map(wire_bytes), st.binary(min_size=6, max_size=20).map(
    lambda noise: b"\xff\xff" + noise)), st.integers(0, 20), st.integers(0, 255))
def test_bytes_read_at_once_are_taken_as_when_they_come_byte_by_byte(data, longest, flip):
    # A reader with nothing half read takes one whole answer in one step: the same packets,
    # skipped bytes and bad checksums as its byte-by-byte hunt, for answers, damaged answers
    # and noise alike.
    if flip:
        damaged = bytearray(data)
        damaged[flip % len(data)] ^= 1 << (flip % 8)
        data = bytes(damaged)
    at_once, byte_by_byte = StatusReader(), StatusReader()
    at_once.longest_params = byte_by_byte.longest_params = longest
    found = [*at_once.feed(data)]
    found_slowly = [packet for k in range(len(data)) for packet in byte_by_byte.feed(data[k:k + 1])]
    assert found == found_slowly
    assert (at_once.skipped_bytes, at_once.bad_checksums, at_once.pending_bytes) == (
        byte_by_byte.skipped_bytes, byte_by_byte.bad_checksums, byte_by_byte.pending_bytes)


@given(status_packets, st.integers(0, 50))
def test_a_corrupt_packet_is_dropped_and_does_not_hide_the_next(status, flipped_bit):
    good = wire_bytes(status)
    bad = bytearray(good)
    bad[2 + flipped_bit % (len(good) - 2)] ^= 1 << (flipped_bit % 8)
    reader = StatusReader()
    reader.longest_params = len(status.params)  # as the link sets it for the reply it awaits
    found = reader.feed(bytes(bad) + good)
    # The good copy is always found. A flipped bit elsewhere breaks the checksum; one in the
    # length byte may, once in 256, frame a shorter packet whose checksum happens to fit: never
    # of the awaited length, which the link checks, so never taken for the reply.
    assert found[-1] == status
    assert all(len(other.params) != len(status.params) for other in found[:-1])


def test_a_half_received_packet_waits_for_the_rest_and_can_be_dropped():
    reader = StatusReader()
    packet = status_packet(5, 0, b"\x00\x08")
    assert reader.feed(packet[:5]) == []
    assert reader.pending_bytes == 5
    assert reader.clear() == 5
    assert reader.feed(packet[5:]) == []  # the tail alone is noise, never a packet


def test_an_error_byte_with_bit_7_set_is_noise_as_the_vendor_sdk_has_it():
    reader = StatusReader()
    good = status_packet(5, 0, b"\x00\x08")
    assert reader.feed(status_packet(5, 0x80, b"\x00\x08") + good) == [StatusPacket(5, 0, b"\x00\x08")]
