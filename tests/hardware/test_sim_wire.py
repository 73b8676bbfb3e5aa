"""When answers reach the host: return delays, sync-read queues, collisions, late packets."""

from pinarray.hardware.feetech.sim_wire import StatusReply, Transmission, schedule

BYTE_NS = 10_000.0  # 1 Mbit/s
PING_ANSWER = bytes.fromhex("ffff010200fc")


def test_sync_read_answers_queue_one_behind_the_other():
    replies = [StatusReply(500_000, PING_ANSWER, 1_000_000, chained=True) for _ in range(3)]
    arrived, free_ns = schedule(replies, 0, BYTE_NS)
    starts = [t.start_ns for t in arrived]
    assert starts == [1_500_000, 2_060_000, 2_620_000]  # delay, 6 bytes, delay, ...
    assert free_ns == arrived[-1].end_ns == 2_680_000


def test_answers_that_overlap_on_the_wire_arrive_as_one_wired_and():
    other = bytes.fromhex("ffff020200fb")
    replies = [StatusReply(0, PING_ANSWER, 0), StatusReply(0, other, 0)]
    (garbled,), _ = schedule(replies, 0, BYTE_NS)
    assert garbled.data == bytes(a & b for a, b in zip(PING_ANSWER, other, strict=True))


def test_a_late_answer_neither_collides_nor_holds_up_the_line():
    replies = [StatusReply(0, PING_ANSWER, 0, late_ns=50_000_000), StatusReply(0, PING_ANSWER, 0)]
    arrived, free_ns = schedule(replies, 0, BYTE_NS)
    assert [t.data for t in arrived] == [PING_ANSWER, PING_ANSWER]
    assert [t.start_ns for t in arrived] == [0, 50_000_000]
    assert free_ns == 60_000


def test_a_byte_arrives_when_its_stop_bit_does():
    sent = Transmission(1_000, PING_ANSWER, BYTE_NS)
    assert [sent.arrival_ns(i) for i in (0, 5)] == [11_000, 61_000] and sent.end_ns == 61_000
