"""A simulated STS servo bus, byte-faithful, that the real ``scservo_sdk`` (or any client) talks to.

`SimBus` is the servos on the wire: it takes the bytes the host sends, finds instruction
packets in them byte by byte, applies them to `SimServo` control tables and returns the status
packets the servos would send, with checksums, error bits and injected faults. It knows
nothing about time except the instant each packet finished arriving. In front of it:
`pinarray.hardware.feetech.sim_serial.SimSerial` (pyserial's face, charging wire time against
a clock), `pinarray.hardware.feetech.serve` (a pseudo-terminal), and the coarser levels of
`pinarray.hardware.feetech.sim_levels` (exchanges computed whole, without bytes).

Who answers what (Feetech communication protocol manual V1.01): PING always answers, also at
the broadcast id; READ and SYNC READ answer with data; WRITE, REG WRITE, ACTION and RESET
answer only at status return level 1 and never at the broadcast id. The answer carries the
id the instruction addressed, also when the instruction changed that id. A request a servo
cannot carry out (an unknown instruction, parameters missing, a READ whose answer would be
longer than the longest packet the firmware sends) gets no answer: the STS error byte has no
bit for it.

Past 400 lines on purpose: packet framing, faults and every instruction's answer are one
device as a client sees it.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass

from pinarray.clock import Clock
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.models import FACTORY_RETURN_DELAY_US, servo_model
from pinarray.hardware.feetech.packets import MAX_PACKET_BYTES, status_size
from pinarray.hardware.feetech.registers import (
    BAUD_RATE_BY_CODE,
    BROADCAST_ID,
    WRITE_INSTRUCTIONS,
    Instruction,
    Register,
    StatusError,
    checksum,
)
from pinarray.hardware.feetech.sim_serial import POLL_NS, WRITE_LOG, SimSerial
from pinarray.hardware.feetech.sim_servo import SimServo
from pinarray.hardware.feetech.sim_wire import Answer, StatusReply, status_packet

# Instructions that only ask: no servo's id can change by them.
ASKING = frozenset({Instruction.PING, Instruction.READ, Instruction.SYNC_READ})
# Instruction codes as plain ints, for the comparisons every packet makes.
_PING, _READ = int(Instruction.PING), int(Instruction.READ)
_SYNC_READ, _SYNC_WRITE = int(Instruction.SYNC_READ), int(Instruction.SYNC_WRITE)
_WRITE = int(Instruction.WRITE)
# Where the ID register sits: a write elsewhere cannot renumber a servo (`_may_renumber`).
_ID_ADDRESS = Register.ID.address
# The longest READ answer one status packet can carry, in data bytes.
_LONGEST_READ = MAX_PACKET_BYTES - status_size(0)
# Whole instruction packets kept parsed (a sampled bus sends the same few every few ms).
PACKETS_KEPT = 256

Request = tuple[int, int, bytes]  # servo id, instruction, parameters

__all__ = ["POLL_NS", "WRITE_LOG", "Answer", "InstructionPacket", "SimBus", "SimSerial",
           "StatusReply", "status_packet"]


@dataclass(frozen=True)
class InstructionPacket:
    """One well-formed instruction packet as it arrived at the servos.

    ``end_ns`` is when its last byte arrived; ``delivered`` is False when an injected fault
    lost it on the wire.
    """

    end_ns: int
    servo_id: int
    instruction: int
    params: bytes
    delivered: bool


def _may_renumber(instruction: int, params: bytes) -> bool:
    """Whether carrying out this packet may have changed a servo's ID register: all but a WRITE
    or SYNC WRITE whose bytes all land elsewhere (a goal, a speed), which most packets are."""
    if instruction == _SYNC_WRITE and len(params) >= 2:
        start, end = params[0], params[0] + params[1]
    elif instruction == _WRITE and params:
        start, end = params[0], params[0] + len(params) - 1
    else:
        return True
    return start <= _ID_ADDRESS < end


def _whole(data: bytes | bytearray) -> bool:
    """Whether ``data`` is framed as one whole instruction packet and nothing else (a header,
    a length that fits, its id no header byte), its checksum not yet looked at."""
    size = len(data)
    return (size >= 6 and data[0] == 0xFF and data[1] == 0xFF and data[2] != 0xFF
            and data[3] >= 2 and size == data[3] + 4)


def _fits(length: int) -> bool:
    """Whether an answer of ``length`` data bytes fits in one packet the servos can send."""
    return length <= _LONGEST_READ


class SimBus:
    """The servos on a simulated wire, with fault injection.

    Parameters
    ----------
    config : SimConfig
        Which ids answer, their wire settings and physics, and the faults to inject.
    clock : Clock
        Time source; the servos power on at its current time.
    follow_host_baud : bool, optional
        With no ``baud`` in the config, let the servos listen at the first speed the host
        uses (one of the STS rates). Default: True in-process; the pseudo-terminal server
        passes False, so its servos sit at the factory 1000000 bit/s.
    """

    def __init__(self, config: SimConfig, clock: Clock, follow_host_baud: bool = True):
        self.config = config
        self.clock = clock
        self.servos: dict[int, SimServo] = {
            servo_id: self._new_servo(servo_id, config.return_delay_us, config.baud_rate)
            for servo_id in config.answering_ids
        }
        for servo_id, bits in config.faults.error_bits:
            if servo_id in self.servos:
                self.servos[servo_id].error_bits = StatusError(bits)
        faults = config.faults
        self.drop_rate = faults.drop_rate
        self.drop_write_rate = faults.drop_write_rate
        self.corrupt_rate = faults.corrupt_rate
        self.late_rate = faults.late_rate
        self.late_ns = faults.late_ns
        self.vanish_after_packets = faults.vanish_after_packets
        self.drop_next = 0
        self.drop_writes_next = 0
        self.corrupt_next = 0
        self.late_next = 0
        self.packets_received = 0
        self.packets_rejected = 0
        self.packet_listener: Callable[[InstructionPacket], None] | None = None
        # The wire the host talks on, set by the port in front of the bus (SimSerial, PtyServer).
        self.byte_ns = 0.0
        self.host_baud_rate: int | None = None
        self._follow_baud = follow_host_baud and config.baud_rate is None
        self._setup_baud_rate = config.baud_rate
        self._shadowed: list[SimServo] = []  # servos renumbered onto an id already taken
        self._random = random.Random(faults.seed)
        self._buffer = bytearray()
        self._parsed: dict[bytes, Request] = {}  # `whole_packet`'s answers, by the bytes

    @property
    def vanished(self) -> bool:
        """True once the port has "disappeared" (see ``vanish_after``)."""
        limit = self.vanish_after_packets
        return limit is not None and self.packets_received >= limit

    @property
    def whole_packets(self) -> bool:
        """Whether packets can be taken whole, their bytes unseen (the packet level): no half
        packet waiting for its rest, no fault that acts on bytes (corrupt or late answers, a
        vanishing port), no host speed still to learn."""
        return not (self._buffer or self._follow_baud or self.vanish_after_packets is not None
                    or self.corrupt_rate or self.corrupt_next or self.late_rate or self.late_next)

    def receive(
        self, data: bytes, at_ns: int, byte_ns: float | None = None, baud_rate: int | None = None
    ) -> list[StatusReply]:
        """Bytes from the host, the last of which arrived at ``at_ns``; returns the answers.

        Parameters
        ----------
        data : bytes
            What the host sent (any split of packets).
        at_ns : int
            When the last byte of ``data`` arrived, in nanoseconds.
        byte_ns : float, optional
            Wire time of one byte, so packets earlier in ``data`` get earlier arrival times;
            default `byte_ns`, which the port in front of the bus keeps up to date.
        baud_rate : int, optional
            The host's speed in bit/s (default `host_baud_rate`); servos listening at another
            speed hear only noise. None: unknown, every servo hears.
        """
        byte_ns = self.byte_ns if byte_ns is None else byte_ns
        baud_rate = self.host_baud_rate if baud_rate is None else baud_rate
        if self._follow_baud and baud_rate in BAUD_RATE_BY_CODE:
            self._follow_baud = False
            self._setup_baud_rate = baud_rate
            for servo in self.all_servos():
                servo.set_up_baud(baud_rate)
        buffer = self._buffer
        if not buffer and type(data) is bytes:
            # The usual write: one whole packet and nothing else (`_next_packet`'s first round).
            request = self.whole_packet(data)
            if request is not None:
                servo_id, instruction, params = request
                return self.deliver(servo_id, instruction, params, at_ns, baud_rate)
            if _whole(data):  # its checksum failed
                self.packets_rejected += 1
                return []
        buffer.extend(data)
        replies: list[StatusReply] = []
        if len(buffer) < 4:  # the tail of a packet to come: nothing whole yet
            return replies
        while (packet := self._next_packet()) is not None:
            servo_id, instruction, params = packet
            end_ns = at_ns - round(len(buffer) * byte_ns)
            replies.extend(self.deliver(servo_id, instruction, params, end_ns, baud_rate))
        return replies

    def deliver(self, servo_id: int, instruction: int, params: bytes, end_ns: int,
                baud_rate: int | None) -> list[StatusReply]:
        """One well-formed instruction packet, whole at the servos at ``end_ns``: counted, lost
        to an injected fault or carried out; returns the answers, as the servos send them.

        Parameters
        ----------
        servo_id, instruction : int
            Whom it addresses (maybe the broadcast id) and what it asks.
        params : bytes
            Its parameters.
        end_ns : int
            When its last byte arrived, in nanoseconds.
        baud_rate : int or None
            The host's speed in bit/s; servos listening at another speed hear only noise.
        """
        answers = self.carry_out(servo_id, instruction, params, end_ns, baud_rate)
        if len(answers) == 1:  # the usual: one servo answers
            return [self.reply(answers[0], end_ns)]
        return [self.reply(answer, end_ns) for answer in answers]

    def carry_out(self, servo_id: int, instruction: int, params: bytes, end_ns: int,
                  baud_rate: int | None) -> list[Answer]:
        """`deliver`, the answers not yet bytes (see `reply`)."""
        self.packets_received += 1
        delivered = not ((self.drop_next or self.drop_rate or self.drop_writes_next
                          or self.drop_write_rate) and self._lost(instruction))
        if self.packet_listener is not None:
            self.packet_listener(InstructionPacket(end_ns, servo_id, instruction, params, delivered))
        if not delivered:
            return []
        answers = self._execute(servo_id, instruction, params, end_ns, baud_rate)
        if instruction not in ASKING and _may_renumber(instruction, params):
            self._renumber()
        return answers

    def whole_packet(self, data: bytes) -> Request | None:
        """``data`` as the servos take it when it is one whole instruction packet with a right
        checksum and nothing else (`_next_packet`'s first round, its buffer empty): whom it
        addresses, what it asks, its parameters; None for anything else. Kept by the bytes,
        whose parse cannot change."""
        request = self._parsed.get(data)
        if request is None and _whole(data) and checksum(data[2:-1]) == data[-1]:
            if len(self._parsed) >= PACKETS_KEPT:
                self._parsed.clear()
            request = self._parsed[data] = data[2], data[4], data[5:-1]
        return request

    def _lost(self, instruction: int) -> bool:
        if not (self.drop_next or self.drop_rate or self.drop_writes_next
                or self.drop_write_rate):
            return False  # the usual wire: nothing is lost
        if self.drop_next > 0:
            self.drop_next -= 1
            return True
        if self.drop_rate and self._random.random() < self.drop_rate:
            return True
        if instruction in WRITE_INSTRUCTIONS:
            if self.drop_writes_next > 0:
                self.drop_writes_next -= 1
                return True
            if self.drop_write_rate and self._random.random() < self.drop_write_rate:
                return True
        return False

    def _next_packet(self) -> tuple[int, int, bytes] | None:
        buffer = self._buffer
        if not buffer:
            return None
        if _whole(buffer):
            # The usual case, the loop below's first round: one whole packet and nothing else.
            packet = bytes(buffer)
            buffer.clear()
            if checksum(packet[2:-1]) != packet[-1]:
                self.packets_rejected += 1
                return None
            return packet[2], packet[4], packet[5:-1]
        while True:
            # Hunt for the FF FF header one byte at a time, as the servo's UART does.
            while len(buffer) >= 2 and not (buffer[0] == 0xFF and buffer[1] == 0xFF):
                del buffer[0]
            while len(buffer) >= 3 and buffer[2] == 0xFF:
                del buffer[0]  # FF FF FF: the first FF was noise
            if len(buffer) < 4:
                return None
            total = buffer[3] + 4
            if buffer[3] < 2:
                del buffer[:2]
                continue
            if len(buffer) < total:
                return None
            packet = bytes(buffer[:total])
            if len(buffer) == total:
                buffer.clear()
            else:
                del buffer[:total]
            if checksum(packet[2:-1]) != packet[-1]:
                self.packets_rejected += 1  # a servo silently ignores a bad checksum
                continue
            return packet[2], packet[4], packet[5:-1]

    # -- who is on the bus ---------------------------------------------------------------

    def all_servos(self) -> list[SimServo]:
        """Every servo on the bus, also those renumbered onto an id another one has."""
        return [*self.servos.values(), *self._shadowed]

    def _new_servo(self, servo_id: int, return_delay_us: int, baud_rate: int | None) -> SimServo:
        config = self.config
        model = servo_model(config.model)
        backlash = None if config.backlash_deg is None else (
            config.backlash_deg * model.steps_per_turn / 360.0
        )
        return SimServo(
            servo_id,
            self.clock.now_ns(),
            return_delay_us=return_delay_us,
            model=model,
            baud_rate=baud_rate or 1_000_000,
            supply_v=config.supply_v,
            backlash_steps=backlash,
            load_fraction=config.load_fraction,
            top_speed_steps_per_s=config.speed_steps_per_s,
        )

    def plug_in(self, servo_id: int = 1) -> SimServo:
        """A factory-fresh servo joins the bus (at id 1, as shipped); shares a taken id.

        It listens at the speed the bus was set up with (the URL's ``baud``, or the host's
        first speed in-process, else the factory's 1000000 bit/s).
        """
        servo = self._new_servo(servo_id, FACTORY_RETURN_DELAY_US, self._setup_baud_rate)
        if servo_id in self.servos:
            self._shadowed.append(servo)
        else:
            self.servos[servo_id] = servo
        return servo

    def power_cycle(self) -> None:
        """Switch the servos' supply off and on: unsaved EEPROM values and RAM are lost."""
        now_ns = self.clock.now_ns()
        for servo in self.all_servos():
            servo.power_cycle(now_ns)
        self._renumber()

    def reopen(self, clock: Clock) -> None:
        """A new connection opens the port, on ``clock``: the servos were powered all along.

        Closing a port does nothing to servos, and releasing them only turns torque off: RAM
        and EEPROM stay as they were (a return delay lowered until power-off included). The
        time since the last connection passed with nobody talking: the servos go on from the
        new clock's now (moves ended), and the injected faults count from the new port's
        first packet, as a new bus's would.
        """
        if clock is not self.clock:
            now_ns = clock.now_ns()
            for servo in self.all_servos():
                servo.carry_on_at(now_ns)
            self.clock = clock
        self._buffer.clear()  # half a packet on a closed port never ends
        self.packets_received = 0
        self.packets_rejected = 0

    def _at(self, servo_id: int, baud_rate: int | None) -> list[SimServo]:
        """Every servo answering at ``servo_id`` that hears the host's speed."""
        servo = self.servos.get(servo_id)
        found = [servo] if servo is not None and servo.hears(baud_rate) else []
        if self._shadowed:
            found += [s for s in self._shadowed if s.servo_id == servo_id and s.hears(baud_rate)]
        return found

    def _renumber(self) -> None:
        """Keep `servos` keyed by each servo's current ID register after an ID write."""
        moved = [s for key, s in self.servos.items() if s.servo_id != key]
        if not moved and not self._shadowed:
            return
        for key in [key for key, s in self.servos.items() if s.servo_id != key]:
            del self.servos[key]
        waiting, self._shadowed = [*moved, *self._shadowed], []
        for servo in waiting:
            if servo.servo_id in self.servos:
                self._shadowed.append(servo)  # two servos now share an id: both answer
            else:
                self.servos[servo.servo_id] = servo

    # -- instructions --------------------------------------------------------------------

    def _execute(
        self, servo_id: int, instruction: int, params: bytes, end_ns: int, baud: int | None
    ) -> list[Answer]:
        broadcast = servo_id == BROADCAST_ID
        if instruction == _READ and not broadcast:  # the usual request: one servo's bytes
            if len(params) != 2 or params[1] > _LONGEST_READ:  # (`_fits`)
                return []
            if not self._shadowed:  # one servo at most answers at an id
                servo = self.servos.get(servo_id)
                if servo is None or not (baud is None or baud == servo.baud_rate):  # `hears`
                    return []
                data = servo.read(params[0], params[1], end_ns)  # `_answer`, inline
                return [Answer(servo_id, servo.status_error_byte, data, servo.return_delay_ns)]
            return [_answer(servo, servo_id, servo.read(params[0], params[1], end_ns))
                    for servo in self._at(servo_id, baud)]
        if instruction == _SYNC_WRITE:
            if broadcast and len(params) >= 2:
                self._sync_write(params, end_ns, baud)
            return []
        if instruction == _SYNC_READ:
            if not broadcast or len(params) < 2 or not _fits(params[1]):
                return []
            address, length = params[0], params[1]
            return [
                _answer(servo, target, servo.read(address, length, end_ns), chained=True)
                for target in params[2:]
                for servo in self._at(target, baud)
            ]
        targets = (
            [s for s in self.all_servos() if s.hears(baud)] if broadcast
            else self._at(servo_id, baud)
        )
        answers = []
        for servo in targets:
            carried = self._apply(servo, instruction, params, end_ns)
            if carried is None:
                continue
            if instruction == Instruction.PING:
                # PING answers at the broadcast id too, with the servo's own id.
                answers.append(_answer(servo, servo.servo_id, b""))
            elif not broadcast and (
                instruction == Instruction.READ or servo.status_return_level >= 1
            ):
                answers.append(_answer(servo, servo_id, carried))
        return answers

    def _apply(
        self, servo: SimServo, instruction: int, params: bytes, end_ns: int
    ) -> bytes | None:
        """Carry out one instruction on one servo; its answer's parameters, or None (ignored)."""
        match instruction:
            case Instruction.PING:
                return b""
            case Instruction.READ if len(params) == 2 and _fits(params[1]):
                return servo.read(params[0], params[1], end_ns)
            case Instruction.WRITE if len(params) >= 1:
                servo.write(params[0], params[1:], end_ns)
                return b""
            case Instruction.REG_WRITE if len(params) >= 1:
                servo.reg_write(params[0], params[1:])
                return b""
            case Instruction.ACTION:
                servo.action(end_ns)
                return b""
            case Instruction.RESET:
                servo.factory_reset(end_ns)
                return b""
            case Instruction.CLEAR_STATUS:
                return b""  # nothing to clear in position mode; acknowledged
            case Instruction.REBOOT:
                servo.power_cycle(end_ns)
                return None  # it is busy restarting: no answer
        return None

    def _sync_write(self, params: bytes, end_ns: int, baud: int | None) -> None:
        address, length = params[0], params[1]
        body = params[2:]
        for offset in range(0, len(body) - length, length + 1):
            for servo in self._at(body[offset], baud):
                servo.write(address, body[offset + 1 : offset + 1 + length], end_ns)

    def reply(self, answer: Answer, end_ns: int) -> StatusReply:
        """``answer`` as the servo sends it after an instruction whole at ``end_ns``: its bytes,
        corrupted or made late where the faults say."""
        packet = status_packet(answer.reply_id, answer.error, answer.params)
        if not (self.corrupt_next or self.corrupt_rate or self.late_next or self.late_rate):
            return StatusReply(answer.delay_ns, packet, end_ns, answer.chained, 0)
        corrupt = self.corrupt_next > 0 or (
            self.corrupt_rate and self._random.random() < self.corrupt_rate
        )
        if corrupt:
            self.corrupt_next = max(0, self.corrupt_next - 1)
            packet = packet[:-1] + bytes((packet[-1] ^ 0x5A,))  # a flip the checksum cannot miss
        late = self.late_next > 0 or (self.late_rate and self._random.random() < self.late_rate)
        if late:
            self.late_next = max(0, self.late_next - 1)
        return StatusReply(
            answer.delay_ns, packet, end_ns, answer.chained, self.late_ns if late else 0
        )


def _answer(servo: SimServo, reply_id: int, params: bytes, chained: bool = False) -> Answer:
    """What ``servo`` answers now (its error bits and return delay as they are)."""
    return Answer(reply_id, servo.status_error_byte, params, servo.return_delay_ns, chained)
