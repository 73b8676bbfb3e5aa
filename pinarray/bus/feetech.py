"""The Feetech STS driver: the only module that imports ``scservo_sdk``.

Every packet goes through the vendor SDK's own code. What this module adds is what the SDK
leaves to its callers: a clock-driven port (so the simulator can run in virtual time), a
connect handshake that reports every missing servo at once, sync writes of only the goals
that changed, bounded retries of transient "no status packet" / corrupt replies, and a
safe stop that puts every pin at rest and releases torque wherever the bus still answers.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

import serial
from scservo_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

from pinarray.bus.base import BusSetup, BusStats, PortLost, SafeStopReport, Telemetry
from pinarray.bus.registers import (
    Register,
    StatusError,
    decode_load,
    decode_position,
    encode_position,
    from_bytes,
    to_bytes,
)
from pinarray.clock import Clock
from pinarray.errors import BusError
from pinarray.signals import deferred_signals

if TYPE_CHECKING:
    from pinarray.bus.sim import SimBus

TRANSIENT_RESULTS = (COMM_RX_TIMEOUT, COMM_RX_CORRUPT)
REST_TOLERANCE_STEPS = 4
# Present position .. moving flag, read in one instruction while waiting for pins to settle.
MOTION_LENGTH = Register.MOVING.address + 1 - Register.PRESENT_POSITION.address
REST_POLL_NS = 10_000_000
# Present position .. present temperature, read in one instruction.
TELEMETRY_START = Register.PRESENT_POSITION
TELEMETRY_LENGTH = Register.PRESENT_TEMPERATURE.address + 1 - TELEMETRY_START.address


class ClockedPortHandler(PortHandler):
    """The SDK's PortHandler with a pluggable serial object, clock and latency budget.

    The SDK times packets with ``time.time()`` and assumes a 16 ms USB latency timer; here
    the clock is injected (virtual time in tests) and the latency budget is what the
    adapter really has, so a missing servo costs a few milliseconds, not 34.
    """

    def __init__(
        self,
        port_name: str,
        clock: Clock,
        open_serial: Callable[[], object],
        latency_ms: float,
        baud_rate: int,
    ):
        super().__init__(port_name)
        self.clock = clock
        self.baudrate = baud_rate
        self._open_serial = open_serial
        self.latency_ms = latency_ms
        self.bytes_written = 0
        self.bytes_read = 0

    def setupPort(self, cflag_baud):  # noqa: N802 - SDK method name
        if self.is_open:
            self.closePort()
        self.ser = self._open_serial()
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True

    def writePort(self, packet):  # noqa: N802 - SDK method name
        written = self.ser.write(packet)
        self.bytes_written += written or 0
        return written

    def readPort(self, length):  # noqa: N802 - SDK method name
        data = self.ser.read(length)
        self.bytes_read += len(data)
        return data

    def getCurrentTime(self):  # noqa: N802 - SDK method name
        return self.clock.now_ns() / 1_000_000.0

    def setPacketTimeout(self, packet_length):  # noqa: N802 - SDK method name
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.latency_ms * 2.0 + 2.0


class FeetechBus:
    """A connected STS bus, real or simulated, driven through ``scservo_sdk``.

    Use `pinarray.bus.transport.open_bus` to make one; it runs the handshake.

    Parameters
    ----------
    port : ClockedPortHandler
        Opened port.
    clock : Clock
        The same clock the port uses; waits for pins to settle use it.
    retries : int
        Extra attempts after a transient failure (no status packet, corrupt status packet).
    """

    def __init__(self, port: ClockedPortHandler, clock: Clock, retries: int = 3):
        self.port = port
        self.clock = clock
        self.retries = retries
        self.packets = PacketHandler(0)
        self.setup = BusSetup(servos=())
        self.warnings: list[str] = []
        self.sim: SimBus | None = None  # behind a simulated port; for tests and benchmarks
        self._last_goals: dict[int, int] = {}
        self._sync_writes = 0
        self._goals_written = 0
        self._retries = 0

    # -- low level -----------------------------------------------------------------------

    def _call(self, servo_id: int, register: Register, action: str, attempt: Callable):
        """Run one SDK exchange with bounded retries; returns its data and error byte."""
        last_result = COMM_SUCCESS
        for index in range(self.retries + 1):
            if index:
                self._retries += 1
                self._discard_stale_input()
            try:
                data, result, error = attempt()
            except (serial.SerialException, OSError) as exc:
                self.port.is_using = False  # the SDK leaves its busy flag set when I/O raises
                raise PortLost(
                    f"servo port {self.port.getPortName()} lost while {action} {register.name} "
                    f"of servo {servo_id}: {exc}"
                ) from None
            if result == COMM_SUCCESS:
                return data, StatusError(error)
            last_result = result
            if result not in TRANSIENT_RESULTS:
                break
        raise BusError(
            f"servo {servo_id}: {action} {register.name} (address {register.address}) failed "
            f"after {index + 1} attempt(s): {self.packets.getTxRxResult(last_result)}"
        )

    def _discard_stale_input(self) -> None:
        # A late or half-received answer would otherwise be taken for the next one's.
        self.port.is_using = False
        try:
            self.port.ser.reset_input_buffer()
        except (serial.SerialException, OSError):
            pass

    def read(self, servo_id: int, register: Register, length: int | None = None):
        """Read ``length`` bytes (default: the register's size) from one servo."""
        size = length or register.size

        def attempt():
            return self.packets.readTxRx(self.port, servo_id, register.address, size)

        data, error = self._call(servo_id, register, "reading", attempt)
        return bytes(data), error

    def write(self, servo_id: int, register: Register, value: int) -> StatusError:
        """Write one register of one servo and wait for its acknowledgement."""
        if register.in_eeprom:
            raise BusError(
                f"servo {servo_id}: refusing to write {register.name}, an EEPROM register; "
                "EEPROM is only written on purpose, with the servo vendor's tool"
            )
        data = list(to_bytes(value, register.size))

        def attempt():
            result, error = self.packets.writeTxRx(
                self.port, servo_id, register.address, register.size, data
            )
            return None, result, error

        return self._call(servo_id, register, "writing", attempt)[1]

    def ping(self, servo_id: int, retry: bool = True) -> int | None:
        """Model number of the servo at ``servo_id``, or None if nothing answers.

        Uses the SDK's ping (a PING instruction, then a read of MODEL_NUMBER).
        """

        def attempt():
            return self.packets.ping(self.port, servo_id)

        retries, self.retries = self.retries, self.retries if retry else 0
        try:
            model, _ = self._call(servo_id, Register.MODEL_NUMBER, "pinging for", attempt)
        except PortLost:
            raise
        except BusError:
            return None
        finally:
            self.retries = retries
        return model

    # -- handshake -----------------------------------------------------------------------

    def connect(self, setup: BusSetup) -> None:
        """Ping every expected id, check models, then set torque, speed and acceleration.

        Raises
        ------
        BusError
            Naming every missing id and every id with the wrong model, in one message.
        """
        self.setup = setup
        found = {servo_id: self.ping(servo_id) for servo_id in setup.servo_ids}
        missing = sorted(i for i, model in found.items() if model is None)
        wrong = sorted(
            (i, model) for i, model in found.items() if model not in (None, setup.model_number)
        )
        if missing or wrong:
            problems = []
            if missing:
                ids = ", ".join(map(str, missing))
                problems.append(f"no answer from servo id(s) {ids}")
            if wrong:
                found_text = ", ".join(f"id {i} reports model {m}" for i, m in wrong)
                problems.append(f"expected model {setup.model_number}, but {found_text}")
            answered = sorted(set(found) - set(missing))
            raise BusError(
                f"servo handshake on {self.port.getPortName()}: " + "; ".join(problems)
                + f" (answered: {', '.join(map(str, answered)) or 'none'})"
            )
        enabled: list[int] = []
        try:
            for servo in setup.servos:
                # Hold where the horn is before torque comes on, so it cannot jerk a pin.
                data, _ = self.read(servo.servo_id, Register.PRESENT_POSITION)
                self.write(servo.servo_id, Register.GOAL_POSITION, from_bytes(data))
                self.write(servo.servo_id, Register.ACCELERATION, setup.acceleration_register)
                self.write(servo.servo_id, Register.GOAL_SPEED, setup.speed_steps_per_s)
                self.write(servo.servo_id, Register.TORQUE_ENABLE, 1)
                enabled.append(servo.servo_id)
                self._last_goals[servo.servo_id] = decode_position(from_bytes(data))
        except BaseException:
            # A half-finished handshake must not leave some servos holding torque.
            for servo_id in enabled:
                try:
                    self.write(servo_id, Register.TORQUE_ENABLE, 0)
                except BusError:
                    pass
            raise

    # -- playback ------------------------------------------------------------------------

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
        if not changed:
            return 0
        for servo_id, position in changed.items():
            self._check_limits(servo_id, position)
        group = GroupSyncWrite(
            self.port, self.packets, Register.GOAL_POSITION.address, Register.GOAL_POSITION.size
        )
        for servo_id, position in changed.items():
            group.addParam(servo_id, list(to_bytes(encode_position(position), 2)))
        try:
            result = group.txPacket()
        except (serial.SerialException, OSError) as exc:
            self.port.is_using = False
            ids = ", ".join(map(str, changed))
            raise PortLost(
                f"servo port {self.port.getPortName()} lost while sync-writing GOAL_POSITION "
                f"to servo(s) {ids}: {exc}"
            ) from None
        if result != COMM_SUCCESS:
            self.port.is_using = False
            ids = ", ".join(map(str, changed))
            raise BusError(
                f"sync write of GOAL_POSITION to servo(s) {ids} failed: "
                f"{self.packets.getTxRxResult(result)}"
            )
        self._last_goals.update(changed)
        self._sync_writes += 1
        self._goals_written += len(changed)
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

    def move_to_rest(self, timeout_ns: int = 2_000_000_000) -> tuple[int, ...]:
        """Send every pin to rest and wait until they report it; returns the ids at rest."""
        rest = {s.servo_id: s.rest_steps for s in self.setup.servos}
        self.write_goals(rest, force=True)
        return self._wait_at(rest, timeout_ns)

    def _wait_at(self, goals: Mapping[int, int], timeout_ns: int) -> tuple[int, ...]:
        deadline_ns = self.clock.now_ns() + timeout_ns
        pending = dict(goals)
        arrived: list[int] = []
        while pending:
            for servo_id, goal in list(pending.items()):
                try:
                    data, _ = self.read(servo_id, Register.PRESENT_POSITION, MOTION_LENGTH)
                except PortLost:
                    raise
                except BusError:
                    continue
                position = decode_position(from_bytes(data[0:2]))
                still = data[-1] == 0  # MOVING register
                if still and abs(position - goal) <= REST_TOLERANCE_STEPS:
                    arrived.append(servo_id)
                    del pending[servo_id]
            if not pending or self.clock.now_ns() >= deadline_ns:
                break
            self.clock.sleep_until_ns(self.clock.now_ns() + REST_POLL_NS)
        return tuple(sorted(arrived))

    def rest_and_release(self, timeout_ns: int = 2_000_000_000) -> SafeStopReport:
        """Pins to rest, then torque off, on every servo that still answers. Never raises.

        Ctrl-C and SIGTERM are held back until it is done, so a second one cannot leave
        servos holding torque.
        """
        with deferred_signals():
            return self._rest_and_release(timeout_ns)

    def _rest_and_release(self, timeout_ns: int) -> SafeStopReport:
        ids = self.setup.servo_ids
        # An exchange cut short by an exception leaves the SDK's busy flag and maybe half a
        # reply behind; without this, every safe-stop write would be refused as "port busy".
        self._discard_stale_input()
        try:
            at_rest = self.move_to_rest(timeout_ns)
        except PortLost:
            return SafeStopReport((), (), ids, port_lost=True)
        except BusError:
            at_rest = ()
        released = []
        for servo_id in ids:
            try:
                self.write(servo_id, Register.TORQUE_ENABLE, 0)
                released.append(servo_id)
            except PortLost:
                silent = tuple(i for i in ids if i not in released)
                return SafeStopReport(at_rest, tuple(released), silent, port_lost=True)
            except BusError:
                continue
        silent = tuple(i for i in ids if i not in released or i not in at_rest)
        return SafeStopReport(at_rest, tuple(released), silent)

    # -- bookkeeping ---------------------------------------------------------------------

    def stats(self) -> BusStats:
        return BusStats(
            bytes_written=self.port.bytes_written,
            bytes_read=self.port.bytes_read,
            sync_writes=self._sync_writes,
            goals_written=self._goals_written,
            retries=self._retries,
        )

    def close(self) -> None:
        try:
            if self.port.is_open:
                self.port.closePort()
        except (serial.SerialException, OSError):
            pass
