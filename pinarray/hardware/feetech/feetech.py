"""The Feetech STS driver: a connected array of STS bus servos, an `ArrayDriver`.

Packets are built by `packets` and exchanged by `link`, which drains stale input before every
request and accepts only replies whose id, length and checksum fit it. `FeetechBus` adds
bounded and counted retries of transient failures, goal writes that never leave a pin's
calibrated limits, the read-backs of goals, telemetry and the bring-up pings; its jobs live
beside it: the connect handshake (`handshake`), the read-back and re-send that verify a goal
reached its servo (`readback`), the safe stop (`safety`) and the handover to the player
process (`handover`). EEPROM is written only through the methods named for it
(`write_eeprom`, `unlock_eeprom`, `lock_eeprom`, for `bringup`): `write` refuses it.

Past 400 lines: one class, the only one that puts bytes on an STS bus; what needs none of its
private state (the handshake, the safe stop, the handover, the read-backs' bookkeeping) lives
in the modules beside it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pinarray.clock import Clock
from pinarray.errors import BusError
from pinarray.hardware.delivery import DeliveryLedger, PreparedTrial
from pinarray.hardware.driver import (
    BusStats,
    PortLost,
    Pulses,
    SafeStopReport,
    Targets,
    Telemetry,
)
from pinarray.hardware.feetech import handshake, packets, safety
from pinarray.hardware.feetech.base import BusSetup, GoalReading
from pinarray.hardware.feetech.handover import Handover, handover_of
from pinarray.hardware.feetech.link import Expected, Link, WireLost
from pinarray.hardware.feetech.packets import StatusPacket, StatusReader
from pinarray.hardware.feetech.readback import REWRITE_REQUEST_BYTES, Verifier
from pinarray.hardware.feetech.registers import (
    BROADCAST_ID,
    Register,
    StatusError,
    decode_load,
    decode_position,
    encode_position,
    from_bytes,
    to_bytes,
)
from pinarray.hardware.frames import goal_frames
from pinarray.units import NS_PER_US

if TYPE_CHECKING:
    from pinarray.hardware.feetech.sim import SimBus

# Present position .. present temperature, read in one instruction.
TELEMETRY_START = Register.PRESENT_POSITION
TELEMETRY_LENGTH = Register.PRESENT_TEMPERATURE.address + 1 - TELEMETRY_START.address
# A read-back that samples too: Goal Position (42) through Present Position (56), in one read.
GOAL_TO_POSITION_BYTES = (Register.PRESENT_POSITION.address + Register.PRESENT_POSITION.size
                          - Register.GOAL_POSITION.address)
POSITION_OFFSET = Register.PRESENT_POSITION.address - Register.GOAL_POSITION.address
# Sync reads that get no answer at all, in a row, before read-backs use READs instead.
SYNC_READ_TRIES = 3
# Present Position and its size: a sampled bus reads it every few milliseconds; Goal
# Position and its size: read back after every frame.
_POSITION, _POSITION_BYTES = Register.PRESENT_POSITION, Register.PRESENT_POSITION.size
_GOAL, _GOAL_BYTES = Register.GOAL_POSITION, Register.GOAL_POSITION.size
# Read requests kept made (a trial asks the same few again and again; a bring-up, many once).
READ_REQUESTS_KEPT = 64
# A retry after a silence waits this many times longer than the attempt before it.
PATIENCE_GROWTH = 4


@dataclass(frozen=True)
class BroadcastPing:
    """What came back from a PING at the broadcast id.

    Attributes
    ----------
    servo_ids : tuple of int
        Ids of the well-formed status packets heard, in arrival order.
    garbled_bytes : int
        Bytes that were no well-formed status packet: answers that overlapped on the wire
        (several servos answering after the same return delay) or noise.
    """

    servo_ids: tuple[int, ...]
    garbled_bytes: int

    @property
    def clean(self) -> bool:
        """Every byte heard was a status packet: the ids are all who answered."""
        return not self.garbled_bytes


class FeetechBus:
    """A connected STS bus, real or simulated.

    Use `pinarray.hardware.feetech.transport.open_bus` to make one; it runs the handshake.

    Parameters
    ----------
    link : Link
        Timed, validated exchanges over the serial device or the simulator.
    clock : Clock
        The same clock the link uses; waits for pins to settle use it.
    retries : int
        Extra attempts after a transient failure (no fitting status packet in time).
    """

    def __init__(self, link: Link, clock: Clock, retries: int = 3):
        self.link = link
        self.clock = clock
        self.retries = retries
        self.setup = BusSetup(servos=())
        self.warnings: list[str] = []
        self.sim: SimBus | None = None  # behind a simulated port; for tests and benchmarks
        self._last_goals: dict[int, int] = {}
        self._sync_read_works = True
        self._read_requests: dict[tuple[Register, int, tuple[int, ...], bool],
                                  tuple[bytes, tuple[Expected, ...]]] = {}
        self._sync_reads_unanswered = 0
        self._sync_writes = 0
        self._goals_written = 0
        self._retries = 0

    @property
    def port_name(self) -> str:
        return self.link.name

    # -- low level -----------------------------------------------------------------------

    def _lost(self, action: str, error: OSError) -> PortLost:
        return PortLost(f"servo port {self.port_name} lost while {action}: {error.strerror or error}")

    def _transact(self, servo_id: int, action: str, packet: bytes, params_length: int,
                  retries: int | None = None) -> StatusPacket:
        """One request to one servo and its reply, retried a bounded number of times.

        Each retry waits four times as long as the attempt before it (1, 4, 16, 64 latency
        allowances): a reply held up by a busy host is waited for, and only a servo that stays
        silent costs the whole wait.
        """
        attempts = (self.retries if retries is None else retries) + 1
        expected = (Expected(servo_id, params_length),)
        before = self.link.counters.mismatched_replies
        for attempt in range(attempts):
            if attempt:
                self._retries += 1
            try:
                replies = self.link.exchange(packet, expected, patience=PATIENCE_GROWTH ** attempt)
            except WireLost as error:
                raise self._lost(f"{action} servo {servo_id}" if action == "pinging"
                                 else f"{action} of servo {servo_id}", error) from None
            if servo_id in replies:
                return replies[servo_id]
        mismatched = self.link.counters.mismatched_replies - before
        found = f"{mismatched} status packet(s) that did not fit" if mismatched else "no status packet"
        raise BusError(f"servo {servo_id}: {action} failed after {attempts} attempt(s): "
                       f"expected a status packet from servo {servo_id}, found {found}")

    def read(self, servo_id: int, register: Register, length: int | None = None,
             retries: int | None = None) -> tuple[bytes, StatusError]:
        """Read ``length`` bytes (default: the register's size) from one servo."""
        size = length or register.size
        status = self._transact(
            servo_id, f"reading {register.name} (address {register.address})",
            packets.read(servo_id, register.address, size), size, retries,
        )
        return status.params, StatusError(status.error)

    def write(self, servo_id: int, register: Register, value: int,
              retries: int | None = None) -> StatusError:
        """Write one register of one servo and wait for its acknowledgement."""
        if register.in_eeprom:
            raise BusError(
                f"servo {servo_id}: refusing to write {register.name} (address "
                f"{register.address}), an EEPROM register; EEPROM is only written on purpose"
            )
        status = self._transact(
            servo_id, f"writing {register.name} (address {register.address})",
            packets.write(servo_id, register.address, to_bytes(value, register.size)), 0,
            retries,
        )
        return StatusError(status.error)

    def ping(self, servo_id: int, retry: bool = True) -> int | None:
        """Model number of the servo at ``servo_id``, or None if nothing answers.

        A PING instruction, then a read of MODEL_NUMBER, as the vendor SDK's ``ping`` does.
        """
        retries = None if retry else 0
        try:
            self._transact(servo_id, "pinging", packets.ping(servo_id), 0, retries)
            data, _ = self.read(servo_id, Register.MODEL_NUMBER, retries=retries)
        except PortLost:
            raise
        except BusError:
            return None
        return from_bytes(data)

    def ping_attempt(self, servo_id: int, attempt: int) -> int | None:
        """Model number of the servo at ``servo_id``, or None: one PING, waiting as long as
        the ``attempt``-th try of `ping` would (0: one latency allowance), then the model
        number's read, retried as usual."""
        return self._ping_once(servo_id, None, PATIENCE_GROWTH ** attempt)

    def ping_within(self, servo_id: int, timeout_ns: int) -> int | None:
        """Model number of the servo at ``servo_id``, or None if no PING answer by ``timeout_ns``.

        One PING attempt that waits ``timeout_ns`` (and no longer than `ping`'s attempts would
        together), for sweeping many ids quickly; the model-number read of a servo that
        answered is retried as usual.
        """
        # As many latency allowances as the timeout holds: the wait is the timeout, not the
        # allowance learnt while the host was quiet.
        allowance_ns = max(1, self.link.latency.allowance_ns)
        patience = min(-(-timeout_ns // allowance_ns), sum(PATIENCE_GROWTH ** k for k in range(4)))
        return self._ping_once(servo_id, self.clock.now_ns() + timeout_ns, max(1, patience))

    def _ping_once(self, servo_id: int, deadline_ns: int | None, patience: int) -> int | None:
        """One PING (no answer by ``deadline_ns``, or the reply time with ``patience``: None),
        then the model number's read, retried as usual."""
        try:
            replies = self.link.exchange(packets.ping(servo_id), (Expected(servo_id, 0),),
                                         deadline_ns, patience=patience)
        except WireLost as error:
            raise self._lost(f"pinging servo {servo_id}", error) from None
        if servo_id not in replies:
            return None
        try:
            data, _ = self.read(servo_id, Register.MODEL_NUMBER)
        except PortLost:
            raise
        except BusError:
            return None
        return from_bytes(data)

    def broadcast_ping(self, patience: int = 1) -> BroadcastPing:
        """PING every servo at once (the broadcast id) and listen for all the answers.

        Each servo answers with its own id after its own return delay; several with the same
        delay answer together and garble each other (Feetech: "multiple servos can not use
        broadcast PING instructions on the bus"), so only a `BroadcastPing.clean` answer says
        who is there. Listens as long as the longest return delay and ``patience`` times the
        adapter's latency allowance allow.
        """
        packet = packets.ping(BROADCAST_ID)
        link = self.link
        reader = StatusReader()
        reader.longest_params = 0  # a PING's answer carries no data
        # The last answer may start after the longest return delay; allow the wire for several.
        expected = (Expected(BROADCAST_ID, 0), Expected(BROADCAST_ID, 0))
        limit_ns = self.clock.now_ns() + link.reply_time_ns(len(packet), expected,
                                                            patience=patience)
        ids: list[int] = []
        try:
            link.drain()
            link.send(packet)
            while True:
                data = link.wire.read_some(limit_ns)
                if not data:
                    break
                link.counters.bytes_read += len(data)
                ids.extend(status.servo_id for status in reader.feed(data))
        except WireLost as error:
            raise self._lost("broadcasting a PING", error) from None
        return BroadcastPing(tuple(ids), reader.skipped_bytes + reader.pending_bytes)

    # -- bring-up: EEPROM, written only through these methods, on purpose ---------------

    def unlock_eeprom(self, servo_id: int) -> None:
        """LOCK (address 55) = 0: EEPROM values written from now on survive a power cycle."""
        self.write(servo_id, Register.LOCK, 0)

    def lock_eeprom(self, servo_id: int) -> None:
        """LOCK (address 55) = 1: EEPROM values written from now on last until power-off."""
        self.write(servo_id, Register.LOCK, 1)

    def write_eeprom(self, servo_id: int, register: Register, value: int) -> StatusError:
        """Write one EEPROM register (below address 40) of one servo, once, acknowledged.

        The value is in force at once; it survives a power cycle only if LOCK is 0 (see
        `unlock_eeprom`). Not retried: a write whose acknowledgement was lost may have been
        taken (an ID write changes the id the servo answers at), so the caller checks instead.

        Raises
        ------
        BusError
            For a RAM register (use `write`), or when no acknowledgement came back.
        """
        if not register.in_eeprom:
            raise BusError(f"servo {servo_id}: {register.name} (address {register.address}) "
                           "is a RAM register, not EEPROM; write it with `write`")
        action = f"writing {register.name} (EEPROM address {register.address}) = {value}"
        packet = packets.write(servo_id, register.address, to_bytes(value, register.size))
        status = self._transact(servo_id, action, packet, 0, retries=0)
        return StatusError(status.error)

    def note_return_delay(self, servo_id: int, return_delay_us: int) -> None:
        """The servo now waits ``return_delay_us`` before answering: plan exchanges with it."""
        self.link.return_delay_ns[servo_id] = return_delay_us * NS_PER_US

    # -- handshake -----------------------------------------------------------------------

    def connect(self, setup: BusSetup) -> None:
        """The whole handshake: `check` every servo, then `hold` (torque on)."""
        self.check(setup)
        self.hold()

    def check(self, setup: BusSetup) -> None:
        """Ping every expected id, check models, angle limits and return delays. Reads only.

        See `pinarray.hardware.feetech.handshake.check`.
        """
        handshake.check(self, setup)

    def check_servos(self) -> None:
        """`check` the servos this bus was set up for (`ArrayDriver.check_servos`)."""
        handshake.check(self, self.setup)

    def hold(self) -> None:
        """Torque on for every checked servo, holding where its horn is; speed, acceleration."""
        handshake.hold(self)

    def reconnect(self) -> None:
        """Torque on again after a safe stop: the light way where every servo answers as it
        should, else the whole handshake (`pinarray.hardware.feetech.handshake.hold_again`)."""
        handshake.hold_again(self)

    # -- playback ------------------------------------------------------------------------

    def goal_packet(self, goals_steps: Mapping[int, int]) -> bytes:
        """The sync write of these goals, after checking each against its pin's limits."""
        for servo_id, position in goals_steps.items():
            self._check_limits(servo_id, position)
        return packets.sync_write(
            Register.GOAL_POSITION.address, Register.GOAL_POSITION.size,
            ((i, to_bytes(encode_position(p), 2)) for i, p in goals_steps.items()),
        )

    def send_goals(self, packet: bytes,
                   goals_steps: Mapping[int, int] | tuple[tuple[int, int], ...]) -> None:
        """Put a prepared sync write of ``goals_steps`` on the wire (no reply comes back)."""
        try:
            self.link.send(packet)
        except WireLost as error:
            ids = ", ".join(map(str, dict(goals_steps)))
            raise self._lost(f"sync-writing GOAL_POSITION to servo(s) {ids}", error) from None
        self._last_goals.update(goals_steps)
        self._sync_writes += 1
        self._goals_written += len(goals_steps)

    def write_goals(self, goals_steps: Mapping[int, int], force: bool = False) -> int:
        """Sync-write goal positions of the servos whose goal changed; returns how many.

        Parameters
        ----------
        goals_steps : mapping of servo id to position in steps
            New targets; servos absent keep their goal.
        force : bool
            Write every servo given, changed or not (used when making pins safe).
        """
        changed = {
            i: p for i, p in goals_steps.items() if force or self._last_goals.get(i) != p
        }
        if changed:
            self.send_goals(self.goal_packet(changed), changed)
        return len(changed)

    def _check_limits(self, servo_id: int, position: int) -> None:
        try:
            servo = self.setup.servo(servo_id)
        except KeyError:
            raise BusError(
                f"servo {servo_id} is not part of this device; refusing to move it"
            ) from None
        if not servo.min_steps <= position <= servo.max_steps:
            raise BusError(
                f"pin {servo.pin} (servo {servo_id}): GOAL_POSITION {position} steps is outside "
                f"its calibrated limits {servo.min_steps}..{servo.max_steps}"
            )

    def read_goals(self, servo_ids: tuple[int, ...], deadline_ns: int) -> dict[int, GoalReading]:
        """Read back goal positions, giving up at ``deadline_ns``; a servo missing: no reply.

        One servo: a READ. Several: one SYNC READ, each servo answering in turn (a reply lost
        costs only that servo's reading). One attempt: the player decides when to try again.
        A bus whose servos never answer a SYNC READ (some emulators) falls back to READs.
        """
        replies = self._read_words(_GOAL, _GOAL_BYTES, servo_ids, deadline_ns, "reading back")
        return {i: GoalReading(decode_position(from_bytes(r.params)), StatusError(r.error))
                for i, r in replies.items()}

    def read_goals_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_goals` of these servos should take (to fit it between two frames)."""
        return self._read_words_time_ns(_GOAL, _GOAL_BYTES, servo_ids)

    def read_positions(self, servo_ids: tuple[int, ...], deadline_ns: int) -> dict[int, int]:
        """Where the horns are (Present Position, in steps), as `read_goals` reads goals.

        Each servo samples its encoder when the request reaches it; a servo missing: no reply
        by ``deadline_ns``. The replies' error bits are left to the read-backs and telemetry.
        """
        replies = self._read_words(_POSITION, _POSITION_BYTES, servo_ids, deadline_ns,
                                   "sampling")
        if len(replies) == 1:  # one servo sampled (the usual): the comprehension's one item
            ((servo_id, reply),) = replies.items()
            return {servo_id: decode_position(int.from_bytes(reply.params, "little"))}
        return {i: decode_position(int.from_bytes(r.params, "little"))
                for i, r in replies.items()}

    def read_positions_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_positions` of these servos should take on this bus."""
        return self._read_words_time_ns(_POSITION, _POSITION_BYTES, servo_ids)

    def read_goals_and_positions(self, servo_ids: tuple[int, ...],
                                 deadline_ns: int) -> dict[int, tuple[GoalReading, int]]:
        """Goal and Present Position together, as `read_goals` reads goals: one exchange of
        the registers from GOAL_POSITION (42) to PRESENT_POSITION (56), 16 bytes a servo.

        A read-back that samples the horns too, where two exchanges would not fit: each servo
        reads both as the request reaches it. A servo missing: no reply by ``deadline_ns``.
        """
        replies = self._read_words(_GOAL, GOAL_TO_POSITION_BYTES, servo_ids,
                                   deadline_ns, "reading back and sampling")
        goal, present = slice(0, 2), slice(POSITION_OFFSET, POSITION_OFFSET + 2)
        return {i: (GoalReading(decode_position(from_bytes(r.params[goal])), StatusError(r.error)),
                    decode_position(from_bytes(r.params[present])))
                for i, r in replies.items()}

    def read_goals_and_positions_time_ns(self, servo_ids: tuple[int, ...]) -> int:
        """What `read_goals_and_positions` of these servos should take on this bus."""
        return self._read_words_time_ns(_GOAL, GOAL_TO_POSITION_BYTES, servo_ids)

    def read_request_bytes(self, servo_ids: tuple[int, ...]) -> int:
        """The size of the request `read_goals` or `read_positions` sends for these servos."""
        if len(servo_ids) > 1 and self._sync_read_works:
            return packets.INSTRUCTION_OVERHEAD_BYTES + 2 + len(servo_ids)
        return packets.READ_REQUEST_BYTES

    def _read_request(self, register: Register, length: int,
                      servo_ids: tuple[int, ...]) -> tuple[bytes, tuple[Expected, ...]]:
        """The packet that reads ``length`` bytes from ``register`` on, of these servos, and the
        replies it asks for: one READ, or one SYNC READ of several (made once: a sampled bus
        sends it every few milliseconds)."""
        key = (register, length, servo_ids, self._sync_read_works)
        request = self._read_requests.get(key)
        if request is None:
            if len(servo_ids) == 1 or not self._sync_read_works:
                packet = packets.read(servo_ids[0], register.address, length)
                servo_ids = servo_ids[:1]
            else:
                packet = packets.sync_read(register.address, length, servo_ids)
            request = packet, tuple(Expected(i, length) for i in servo_ids)
            if len(self._read_requests) >= READ_REQUESTS_KEPT:
                self._read_requests.clear()
            self._read_requests[key] = request
        return request

    def _read_words(self, register: Register, length: int, servo_ids: tuple[int, ...],
                    deadline_ns: int, action: str) -> dict[int, StatusPacket]:
        packet, expected = self._read_request(register, length, servo_ids)
        try:
            replies = self.link.exchange(packet, expected, deadline_ns)
        except WireLost as error:
            ids = ", ".join(str(e.servo_id) for e in expected)
            raise self._lost(f"{action} {register.name} of servo(s) {ids}", error) from None
        if len(expected) > 1:
            self._sync_reads_unanswered = 0 if replies else self._sync_reads_unanswered + 1
            if self._sync_reads_unanswered >= SYNC_READ_TRIES:
                self._sync_read_works = False
        return replies

    def _read_words_time_ns(self, register: Register, length: int,
                            servo_ids: tuple[int, ...]) -> int:
        packet, expected = self._read_request(register, length, servo_ids)
        return self.link.reply_time_ns(len(packet), expected, expected=True)

    def rewrite_goal(self, servo_id: int, goal_steps: int, deadline_ns: int) -> StatusError | None:
        """Write one goal again with an acknowledged WRITE; the error bits, or None: no ack."""
        self._check_limits(servo_id, goal_steps)
        register = Register.GOAL_POSITION
        packet = packets.write(servo_id, register.address, to_bytes(encode_position(goal_steps), 2))
        try:
            replies = self.link.exchange(packet, (Expected(servo_id, 0),), deadline_ns)
        except WireLost as error:
            raise self._lost(f"re-writing GOAL_POSITION of servo {servo_id}", error) from None
        status = replies.get(servo_id)
        return None if status is None else StatusError(status.error)

    def prepare(self, targets: Targets, pulses: Pulses) -> PreparedTrial:
        """Bus servos take goal changes: one SYNC WRITE per instant a goal changes."""
        return goal_frames(self, targets)

    def begin(self, trial: PreparedTrial, onset_ns: int) -> None:
        """Nothing to ready: the servos hold their goals until a frame changes them."""

    def verifier(self, clock: Clock, trial: PreparedTrial, onset_ns: int,
                 ledger: DeliveryLedger) -> Verifier:
        """Read-backs of the trial's goal changes in the slack between frames, and heals."""
        return Verifier(self, clock, trial, onset_ns, ledger)

    def heal_time_ns(self, changes_per_frame: int) -> int:
        """Reading back a frame of that many goal changes and writing one again, as usual."""
        ids = self.setup.servo_ids[:changes_per_frame] or self.setup.servo_ids[:1]
        return (self.read_goals_time_ns(ids)
                + self.reply_time_ns(ids[0], REWRITE_REQUEST_BYTES, 0))

    def wire_ns(self, byte_count: int) -> int:
        """Time ``byte_count`` bytes take on the bus at its baud rate."""
        return self.link.wire_ns(byte_count)

    def reply_time_ns(self, servo_id: int, request_bytes: int, reply_params: int) -> int:
        """What one exchange with ``servo_id`` should take: wire, return delay, the adapter's
        usual latency (`Latency.expected_ns`); for fitting a read-back between two frames."""
        return self.link.reply_time_ns(request_bytes, (Expected(servo_id, reply_params),),
                                       expected=True)

    def read_telemetry(self, servo_ids: tuple[int, ...]) -> tuple[Telemetry, ...]:
        """Position, load, voltage, temperature and error bits, one read per servo."""
        readings = []
        for servo_id in servo_ids:
            data, errors = self.read(servo_id, TELEMETRY_START, TELEMETRY_LENGTH)
            readings.append(
                Telemetry(
                    servo_id=servo_id,
                    position_steps=decode_position(from_bytes(data[0:2])),
                    load_permille=decode_load(from_bytes(data[4:6])),
                    voltage_v=data[6] / 10.0,
                    temperature_c=data[7],
                    errors=errors,
                )
            )
        return tuple(readings)

    # -- safety --------------------------------------------------------------------------

    def move_to_rest(self, timeout_ns: int = safety.REST_TIMEOUT_NS) -> tuple[int, ...]:
        """Send every pin to rest and wait until they report it; returns the ids at rest."""
        return safety.move_to_rest(self, timeout_ns)

    def rest_and_release(self, timeout_ns: int = safety.REST_TIMEOUT_NS) -> SafeStopReport:
        """Pins to rest, then torque off, on every servo that still answers. Never raises."""
        return safety.rest_and_release(self, timeout_ns)

    # -- another process on the same port ----------------------------------------------

    def handover(self) -> Handover:
        """What a process given this port's descriptor needs to drive the same servos."""
        return handover_of(self)

    @property
    def descriptor(self) -> int | None:
        """The serial device's descriptor (None: the in-process simulator has none)."""
        return getattr(self.link.wire, "fd", None)

    @property
    def latency_timer_ms(self) -> int | None:
        """The USB adapter's latency timer, when known (None on the simulator)."""
        return None if self.sim is not None else self.link.latency.timer_ms

    def assume_goals(self, goals_steps: Mapping[int, int]) -> None:
        """Another process (the player's) left these goals on the servos."""
        self._last_goals.update(goals_steps)

    # -- bookkeeping ---------------------------------------------------------------------

    def stats(self) -> BusStats:
        counters = self.link.counters
        return BusStats(
            bytes_written=counters.bytes_written,
            bytes_read=counters.bytes_read,
            sync_writes=self._sync_writes,
            goals_written=self._goals_written,
            retries=self._retries,
            stale_bytes=counters.stale_bytes,
            mismatched_replies=counters.mismatched_replies,
        )

    def close(self) -> None:
        self.link.close()
