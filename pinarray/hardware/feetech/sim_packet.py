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
from pinarray.hardware.feetech.registers import BROADCAST_ID, checksum
from pinarray.hardware.feetech.sim_serial import SimSerial

# Requests kept parsed (a sampled bus sends the same few every few milliseconds).
REQUESTS_KEPT = 256

Request = tuple[int, int, bytes]  # servo id, instruction, parameters


def _request(packet: bytes) -> Request | None:
    """``packet`` as the servos take it when it is one whole instruction packet (as
    `SimBus.receive` finds it); None for anything else."""
    size = len(packet)
    if (size >= 6 and packet[0] == 0xFF and packet[1] == 0xFF and packet[2] != 0xFF
            and packet[3] >= 2 and size == packet[3] + 4
            and checksum(packet[2:-1]) == packet[-1]):
        return packet[2], packet[4], packet[5:-1]
    return None


def _status(data: bytes, longest_params: int) -> StatusPacket | None:
    """The one status packet `StatusReader.feed` finds in exactly ``data`` (its buffer empty,
    every byte taken), or None where the reader would do anything else with them."""
    size = len(data)
    if (size >= 6 and data[0] == 0xFF and data[1] == 0xFF and data[2] != 0xFF
            and data[2] != BROADCAST_ID and data[3] >= 2 and data[3] - 2 <= longest_params
            and data[4] <= MAX_ERROR_BYTE and size == data[3] + 4
            and checksum(data[2:-1]) == data[-1]):
        return StatusPacket(data[2], data[4], data[5:-1])
    return None


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
        self._requests: dict[bytes, Request | None] = {}

    def _send_and_collect(self, packet: bytes, wanted: dict[int, int],
                          limit_ns: int) -> dict[int, StatusPacket]:
        port = self.port
        try:
            request = self._requests[packet]
        except KeyError:
            if len(self._requests) >= REQUESTS_KEPT:
                self._requests.clear()
            request = self._requests[packet] = _request(packet)
        if request is None or not port.computable():
            return super()._send_and_collect(packet, wanted, limit_ns)
        counters, clock, longest = self.counters, self.clock, self.reader.longest_params
        counters.bytes_written += len(packet)
        counters.exchanges += 1
        arriving = port.write_whole(packet, *request)
        replies: dict[int, StatusPacket] = {}
        for index, sent in enumerate(arriving):
            status = None
            if len(replies) < len(wanted) and sent.end_ns <= limit_ns:
                status = _status(sent.data, longest)
            if status is None:  # the reader's own way with the bytes from here on
                port.put_on_wire(arriving[index:])
                break
            clock.sleep_until_ns(sent.end_ns)
            port.took(len(sent.data))
            counters.bytes_read += len(sent.data)
            length = wanted.get(status.servo_id)
            if length is None or length != len(status.params) or status.servo_id in replies:
                counters.mismatched_replies += 1
                continue
            replies[status.servo_id] = status
        if len(replies) < len(wanted):
            return self.collect(wanted, limit_ns, replies)
        return replies
