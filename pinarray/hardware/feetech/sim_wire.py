"""When status packets reach the host over a half-duplex wire: return delays, order, collisions.

Pure timing, shared by the in-process `SimSerial` and the pseudo-terminal server. A byte costs
10 bit times (start, 8 data, stop). A servo starts answering its return delay after the
instruction's last byte; answers to a SYNC READ queue behind one another ("each servo will
respond in the order its ID appeared"), while answers to a broadcast PING (or from two servos
sharing an id) all start after their own delay. Feetech's protocol manual warns that "multiple
servos can not use broadcast PING instructions on the bus": overlapping answers collide, and
the host receives the wired-AND of the bytes on the line in each byte slot.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

BITS_PER_BYTE = 10
# A status packet with no parameters: FF FF id len error checksum.
STATUS_OVERHEAD_BYTES = 6


def byte_time_ns(baud_rate: float) -> float:
    """Nanoseconds one byte occupies the wire at ``baud_rate`` bit/s."""
    return BITS_PER_BYTE * 1e9 / baud_rate


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """``FF FF id len err params chk`` with ``len = len(params) + 2``."""
    length = len(params) + 2
    # `checksum` of id, length, error and params, summed here instead of over a joined body.
    total = servo_id + length + error + sum(params)
    return b"\xff\xff" + bytes((servo_id, length, error)) + params + bytes((~total & 0xFF,))


class Answer(NamedTuple):
    """A status packet a servo is to send, before it is bytes: its id, error byte and data,
    the servo's return delay (ns), and whether it waits for the line (a SYNC READ's)."""

    reply_id: int
    error: int
    params: bytes
    delay_ns: int
    chained: bool = False

    @property
    def size(self) -> int:
        """Its bytes on the wire."""
        return STATUS_OVERHEAD_BYTES + len(self.params)


class StatusReply(NamedTuple):
    """A status packet a servo sends ``delay_ns`` after the instruction finished arriving.

    Attributes
    ----------
    delay_ns : int
        The servo's return delay, in nanoseconds.
    packet : bytes
        The status packet as the servo sends it.
    instruction_end_ns : int
        Clock time the instruction's last byte arrived, in nanoseconds.
    chained : bool
        True for answers to a SYNC READ: the servo waits until the line is free.
    late_ns : int
        Injected extra lateness (0 = on time); a late answer does not hold up the others.
    """

    delay_ns: int
    packet: bytes
    instruction_end_ns: int = 0
    chained: bool = False
    late_ns: int = 0


class Transmission(NamedTuple):
    """Bytes arriving at the host one every ``byte_ns`` from ``start_ns`` (first start bit)."""

    start_ns: int
    data: bytes
    byte_ns: float

    def arrival_ns(self, index: int) -> int:
        """When byte ``index`` has fully arrived."""
        return self.start_ns + round((index + 1) * self.byte_ns)

    @property
    def end_ns(self) -> int:
        """When the last byte has arrived."""
        return self.arrival_ns(len(self.data) - 1)


def schedule(
    replies: Sequence[StatusReply], line_free_ns: int, byte_ns: float
) -> tuple[list[Transmission], int]:
    """Place ``replies`` on the wire; returns them in arrival order and when the line is free.

    Parameters
    ----------
    replies : sequence of StatusReply
        In the order the servos would send them.
    line_free_ns : int
        When the line stops being busy with earlier traffic, in nanoseconds.
    byte_ns : float
        Wire time of one byte, in nanoseconds.
    """
    if len(replies) == 1 and not replies[0].late_ns:  # the usual answer: nothing to collide
        reply = replies[0]
        after_ns = reply.instruction_end_ns
        if reply.chained:
            after_ns = max(line_free_ns, after_ns)
        sent = Transmission(after_ns + reply.delay_ns, reply.packet, byte_ns)
        return [sent], max(line_free_ns, sent.end_ns)
    on_time: list[Transmission] = []
    late: list[Transmission] = []
    free_ns = line_free_ns
    for reply in replies:
        after_ns = reply.instruction_end_ns
        if reply.chained:
            after_ns = max(free_ns, after_ns)
        start_ns = after_ns + reply.delay_ns
        if reply.late_ns:
            late.append(Transmission(start_ns + reply.late_ns, reply.packet, byte_ns))
            continue
        sent = Transmission(start_ns, reply.packet, byte_ns)
        on_time.append(sent)
        free_ns = max(free_ns, sent.end_ns)
    arrived = _collide(on_time) + late
    arrived.sort(key=lambda t: t.start_ns)
    return arrived, free_ns


def _collide(transmissions: list[Transmission]) -> list[Transmission]:
    """Merge transmissions that overlap in time into one garbled one (wired-AND per slot)."""
    ordered = sorted(transmissions, key=lambda t: t.start_ns)
    groups: list[list[Transmission]] = []
    group_end = None
    for sent in ordered:
        if groups and group_end is not None and sent.start_ns < group_end:
            groups[-1].append(sent)
            group_end = max(group_end, sent.end_ns)
        else:
            groups.append([sent])
            group_end = sent.end_ns
    merged: list[Transmission] = []
    for group in groups:
        if len(group) == 1:
            merged.append(group[0])
            continue
        origin = group[0].start_ns
        byte_ns = group[0].byte_ns
        slots: dict[int, int] = {}
        for sent in group:
            first = round((sent.start_ns - origin) / byte_ns)
            for index, value in enumerate(sent.data):
                slot = first + index
                slots[slot] = slots.get(slot, 0xFF) & value
        data = bytes(slots.get(slot, 0xFF) for slot in range(max(slots) + 1))
        merged.append(Transmission(origin, data, byte_ns))
    return merged
