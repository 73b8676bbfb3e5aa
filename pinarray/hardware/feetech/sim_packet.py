"""The packet level: exchanges with the simulated servos computed whole, without their bytes.

A `PacketLink` is the `Link` the in-process simulator gets unless its URL asks for the wire
(`pinarray.hardware.feetech.sim_levels`). An exchange whose request is one whole instruction
packet, sent while nothing else is on the wire, is carried out by the simulated servos at
the instant its last byte would arrive (`SimSerial.write_whole`); each answer is taken whole
at the instant its last byte would reach the host, checked as `StatusReader` would check its
bytes, and matched to the request as `Link.collect` matches it. Whatever the reader would
treat otherwise (an answer it would skip as noise, one due after the deadline, answers the
request did not wait for) goes on the wire byte by byte and is read as the wire level reads
it, as does every exchange while a fault acts on bytes. So the replies, the counters, the
clock and what is left on the wire are the wire level's: only fewer steps lead there.
"""

from __future__ import annotations

from pinarray.clock import Clock
from pinarray.hardware.feetech.link import Latency, Link, PolledWire
from pinarray.hardware.feetech.packets import MAX_ERROR_BYTE, StatusPacket
from pinarray.hardware.feetech.registers import BROADCAST_ID
from pinarray.hardware.feetech.sim_serial import SimSerial
from pinarray.hardware.feetech.sim_wire import STATUS_OVERHEAD_BYTES, Answer


def _readable(answer: Answer, longest_params: int) -> bool:
    """Whether `StatusReader.feed`, its buffer empty, takes ``answer``'s bytes whole as one
    status packet (anything else: the bytes go to the reader)."""
    return (answer.reply_id < BROADCAST_ID and len(answer.params) <= longest_params
            and answer.error <= MAX_ERROR_BYTE)


class PacketLink(Link):
    """A `Link` to the in-process simulator whose exchanges are computed whole.

    Parameters
    ----------
    port : SimSerial
        The simulated port; its bytes are used whenever they could differ.
    clock : Clock
        The simulator's clock.
    baud_rate : int
        Bits per second on the servo bus.
    latency : Latency
        The adapter's latency allowance (the simulator's has none to learn).
    name : str
        The port's URL, for messages.
    """

    def __init__(self, port: SimSerial, clock: Clock, baud_rate: int, latency: Latency,
                 name: str):
        super().__init__(PolledWire(port, clock, name), clock, baud_rate, latency)
        self.port = port

    def _send_and_collect(self, packet: bytes, wanted: dict[int, int],
                          limit_ns: int) -> dict[int, StatusPacket]:
        port = self.port
        request = port.bus.whole_packet(packet)
        if request is None or not port.computable():
            return super()._send_and_collect(packet, wanted, limit_ns)
        counters, clock, longest = self.counters, self.clock, self.reader.longest_params
        counters.bytes_written += len(packet)
        counters.exchanges += 1
        servo_id, instruction, params = request
        end_ns, answers = port.write_whole(packet, servo_id, instruction, params)
        if len(answers) == 1 and len(wanted) == 1:
            return self._one_answer(answers[0], end_ns, wanted, limit_ns)
        if len(answers) > 1 and not all(answer.chained for answer in answers):
            port.schedule_answers(answers, end_ns)  # answers at once may collide: bytes
            return self.collect(wanted, limit_ns, {})
        # Each answer starts its return delay after the line is free (as `sim_wire.schedule`
        # places them) and is whole when its last byte has arrived.
        byte_ns, free_ns = port.byte_ns, end_ns
        starts = []
        for answer in answers:
            starts.append(free_ns + answer.delay_ns)
            free_ns = starts[-1] + round(answer.size * byte_ns)
        port.answered(free_ns)
        replies: dict[int, StatusPacket] = {}
        for index, answer in enumerate(answers):
            whole_ns = starts[index] + round(answer.size * byte_ns)
            if (len(replies) == len(wanted) or whole_ns > limit_ns
                    or not _readable(answer, longest)):  # the reader's own way from here on
                port.put_on_wire(list(zip(starts[index:], answers[index:], strict=True)))
                break
            clock.sleep_until_ns(whole_ns)
            port.took(answer.size)
            counters.bytes_read += answer.size
            length = wanted.get(answer.reply_id)
            if length is None or length != len(answer.params) or answer.reply_id in replies:
                counters.mismatched_replies += 1
                continue
            replies[answer.reply_id] = StatusPacket(answer.reply_id, answer.error, answer.params)
        if len(replies) < len(wanted):
            return self.collect(wanted, limit_ns, replies)
        return replies

    def _one_answer(self, answer: Answer, end_ns: int, wanted: dict[int, int],
                    limit_ns: int) -> dict[int, StatusPacket]:
        """`_send_and_collect` where one answer comes and one is wanted (a READ, a sample):
        the same steps, the loop unrolled (this runs for every sample of a batch)."""
        port, counters = self.port, self.counters
        params = answer.params
        size = STATUS_OVERHEAD_BYTES + len(params)
        start_ns = end_ns + answer.delay_ns
        whole_ns = start_ns + round(size * port.byte_ns)
        port.answered(whole_ns)
        if (whole_ns > limit_ns or answer.reply_id >= BROADCAST_ID
                or len(params) > self.reader.longest_params or answer.error > MAX_ERROR_BYTE):
            port.put_on_wire([(start_ns, answer)])  # the reader's own way from here on
            return self.collect(wanted, limit_ns, {})
        self.clock.sleep_until_ns(whole_ns)
        port.took(size)
        counters.bytes_read += size
        if wanted.get(answer.reply_id) != len(params):
            counters.mismatched_replies += 1
            return self.collect(wanted, limit_ns, {})
        return {answer.reply_id: StatusPacket(answer.reply_id, answer.error, params)}

    def drain(self) -> None:
        """As `Link.drain`; nothing to do while the port is computable and nothing half read
        (no bytes on their way, none kept)."""
        if not self.port.computable() or self.reader.pending_bytes:
            super().drain()
