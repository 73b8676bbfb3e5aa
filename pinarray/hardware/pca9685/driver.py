"""Hobby PWM servos on a PCA9685 board, as an `ArrayDriver`.

- **connect**: `check_servos` reads MODE1 at the board's address (a missing or silent board
  is named); `hold` sets MODE2 (outputs change on STOP), then every pin's rest width at the
  protocol's ``pwm_hz``, and starts the counter: pulses flow, the servos hold rest.
- **a trial**: `prepare` plans it in periods of the board (`pinarray.hardware.pca9685.timing`);
  `begin` puts the board to SLEEP, writes the prescale and every channel's first registers,
  wakes it and, 500 us later, writes RESTART timed to end at onset, so the counter's period 0
  begins at onset; each frame is one auto-increment write of the changed channels' LED blocks
  in the period before the one it sets.
- **verified delivery**: every message is acknowledged or raises; after each frame the
  `PwmVerifier` reads the written block back in the slack, heals (writes again) a block the
  board does not hold while its period has not begun, and finds a board that lost power
  (MODE1 back to its reset value: SLEEP set, outputs off). A write that ended after its
  period began is not delivered: that period's pulse went out with the old width.
- **safe stop**: every channel to its rest width, held while the servos travel there, then
  every channel full off (ALL_LED_OFF): hobby servos go limp without pulses.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from math import ceil
from typing import TYPE_CHECKING

from pinarray.clock import Clock
from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.delivery import DeliveryLedger, PreparedFrame, PreparedTrial
from pinarray.hardware.driver import (
    BusStats,
    PortLost,
    Pulses,
    SafeStopReport,
    Targets,
    Telemetry,
)
from pinarray.hardware.motion import PinTrace
from pinarray.hardware.pca9685.i2c import I2cLink, I2cMessage, I2cNack, MessageLog
from pinarray.hardware.pca9685.registers import (
    AI,
    ALL_LED_ON_L,
    ALLCALL,
    CHANNELS,
    COUNTS,
    FULL_BIT,
    FULL_OFF,
    LED0_ON_L,
    LED_STRIDE,
    MODE1,
    MODE2,
    OSCILLATOR_START_NS,
    OUTDRV,
    PRE_SCALE,
    RESTART,
    SLEEP,
    LedBlock,
    led_register,
    period_ns,
    prescale_for,
)
from pinarray.hardware.pca9685.timing import PwmSetup, PwmTrial, plan_trial, width_counts
from pinarray.units import NS_PER_MS, NS_PER_S

if TYPE_CHECKING:
    from pinarray.hardware.driver import Handover

AWAKE = AI | ALLCALL  # MODE1 while running: auto-increment on, all-call answered
# After the last rest write, the servos get this long beyond their travel time to get there.
REST_SETTLE_NS = 100 * NS_PER_MS


@dataclass
class _Counters:
    bytes_written: int = 0
    bytes_read: int = 0
    frames: int = 0
    goals: int = 0
    retries: int = 0
    nacks: int = 0
    power_losses: int = 0


class Pca9685Array:
    """A PCA9685 board of hobby servos, real (i2c-dev) or simulated."""

    def __init__(self, link: I2cLink, setup: PwmSetup, clock: Clock,
                 speed_us_per_s: int = 6667, log: MessageLog | None = None,
                 log_path: str | None = None):
        self.link = link
        self.log_path = log_path
        self.setup: PwmSetup = setup
        self.clock = clock
        self.speed_us_per_s = speed_us_per_s
        self.counters = _Counters()
        self.log = log
        link.listener = self._heard
        self.widths_us: dict[int, int] = setup.rest_widths_us()  # channel -> width written
        self.prescale = prescale_for(setup.osc_hz, Fraction(setup.pwm_hz))
        self.on_counts: dict[int, int] = {}
        self.counter_started_ns: int | None = None  # when period 0 of this trial began
        self.last_stop_ns = 0
        self.warnings: list[str] = []
        if setup.osc_hz == 25_000_000:
            self.warnings.append(
                f"board 0x{setup.address:02x}: osc_hz is the nominal 25 MHz; boards are off by "
                "up to several percent: measure it (docs/rig/pwm.md: measuring a board's oscillator) "
                "or pulses drift from the schedule")

    # -- the wire ----------------------------------------------------------------------
    def _heard(self, message: I2cMessage) -> None:
        if message.read:
            self.counters.bytes_read += len(message.data)
        else:
            self.counters.bytes_written += len(message.data) + 1
        if not message.acked:
            self.counters.nacks += 1
        self.last_stop_ns = message.stop_ns
        if self.log is not None:
            self.log(message)

    def _write(self, data: bytes) -> I2cMessage:
        return self.link.write(self.setup.address, data)

    def _read(self, register: int, count: int) -> bytes:
        return self.link.write_read(self.setup.address, bytes([register]), count)

    # -- ArrayDriver ---------------------------------------------------------------------
    @property
    def port_name(self) -> str:
        return self.link.name

    @property
    def descriptor(self) -> int | None:
        return self.link.descriptor

    @property
    def latency_timer_ms(self) -> None:
        return None

    def check_servos(self) -> None:
        """The board answers at its address (hobby servos cannot be asked anything)."""
        try:
            self._read(MODE1, 1)
        except I2cNack:
            raise BusError(f"{self.port_name}: no PCA9685 board answers at address "
                           f"0x{self.setup.address:02x}: check its power, its address jumpers "
                           "(A0-A5) and SDA/SCL") from None

    def hold(self) -> None:
        """Rest widths at the protocol's rate, counter started: the servos hold rest."""
        self.prescale = prescale_for(self.setup.osc_hz, Fraction(self.setup.pwm_hz))
        self.on_counts = {}
        self._start(self.prescale, self._blocks(self.widths_from_rest()), None)

    def reconnect(self) -> None:
        self.check_servos()
        self.hold()

    def widths_from_rest(self) -> dict[int, int]:
        self.widths_us = self.setup.rest_widths_us()
        return dict(self.widths_us)

    def _blocks(self, widths_us: Mapping[int, int]) -> tuple[LedBlock, ...]:
        return tuple(self._pulse(ch, widths_us[ch]) if ch in widths_us else FULL_OFF
                     for ch in range(CHANNELS))

    def _pulse(self, channel: int, width_us: int) -> LedBlock:
        """The channel's block for a ``width_us`` pulse at the current rate; a width the
        board's period cannot hold is refused, naming both."""
        period = period_ns(self.setup.osc_hz, self.prescale)
        counts = width_counts(width_us, period / COUNTS)
        if not 0 < counts < COUNTS:
            raise PinArrayError(
                f"channel {channel}: a {width_us} us pulse does not fit the board's period of "
                f"{float(period) / 1e6:.3f} ms (prescale {self.prescale}); lower board: pwm_hz")
        return LedBlock.pulse(self.on_counts.get(channel, 0), counts)

    def _start(self, prescale: int, blocks: tuple[LedBlock, ...], at_ns: int | None) -> None:
        """SLEEP, prescale, every channel's registers, wake, then RESTART (at ``at_ns``)."""
        self._write(bytes([MODE1, AWAKE | SLEEP]))
        self._write(bytes([MODE2, OUTDRV]))
        self._write(bytes([PRE_SCALE, prescale]))
        self._write(bytes([LED0_ON_L]) + b"".join(b.encode() for b in blocks))
        self._write(bytes([MODE1, AWAKE]))
        woke_ns = self.clock.now_ns()
        restart = bytes([MODE1, AWAKE | RESTART])
        start_ns = woke_ns + OSCILLATOR_START_NS
        if at_ns is not None:
            start_ns = max(start_ns, at_ns - self.link.message_ns(len(restart)))
        self.clock.sleep_until_ns(start_ns)
        message = self._write(restart)
        self.counter_started_ns = message.stop_ns

    def goal_packet(self, goals_steps: Mapping[int, int]) -> bytes:
        """The LED blocks of the channels ``goals_steps`` changes, at the current rate."""
        by_channel = {s.servo_id: s for s in self.setup.servos}
        for channel, width in goals_steps.items():
            servo = by_channel[channel]
            if not servo.min_steps <= width <= servo.max_steps:
                raise PinArrayError(
                    f"refusing: pin {servo.pin} (channel {channel}) to {width} us is outside "
                    f"its calibrated limits {servo.min_steps}..{servo.max_steps}")
        low, high = min(goals_steps), max(goals_steps)
        widths = {**self.widths_us, **goals_steps}
        return bytes([led_register(low)]) + b"".join(
            (self._pulse(ch, widths[ch]) if ch in widths else FULL_OFF).encode()
            for ch in range(low, high + 1))

    def prepare(self, targets: Targets, pulses: Pulses) -> PreparedTrial:
        return plan_trial(self.setup, targets, pulses)

    def begin(self, trial: PreparedTrial, onset_ns: int) -> None:
        """The trial's prescale and first registers, the counter started at onset."""
        if not isinstance(trial, PwmTrial):
            raise PinArrayError("a PCA9685 board plays trials prepared for it (prepare)")
        self.prescale = trial.rate.prescale
        self.on_counts = {p.channel: p.on_count for p in trial.predictions}
        if self.log is not None:
            self.log.trial_end()  # the last trial's lines on disk
            self.log.trial_onset(onset_ns)
        self._start(trial.rate.prescale, trial.first_blocks, onset_ns)
        for change in trial.changes[:trial.frames[0].first_change if trial.frames else None]:
            self.widths_us[change.servo_id] = change.goal_steps

    def send_goals(self, packet: bytes,
                   goals_steps: Mapping[int, int] | tuple[tuple[int, int], ...]) -> None:
        try:
            self._write(packet)
        except PortLost:
            raise
        except I2cNack:
            # Counted as it was heard; the verifier reads the block back in the slack and
            # writes it again while its period has not begun, else names the change not
            # delivered (as a lost sync write on the bus).
            pass
        goals = dict(goals_steps)
        self.widths_us.update(goals)
        self.counters.frames += 1
        self.counters.goals += len(goals)

    def verifier(self, clock: Clock, trial: PreparedTrial, onset_ns: int,
                 ledger: DeliveryLedger) -> PwmVerifier:
        if not isinstance(trial, PwmTrial):
            raise PinArrayError("a PCA9685 board plays trials prepared for it (prepare)")
        return PwmVerifier(self, clock, trial, onset_ns, ledger)

    def heal_time_ns(self, changes_per_frame: int) -> int:
        block = LED_STRIDE * changes_per_frame
        return (self.link.message_ns(1) + self.link.message_ns(block)
                + self.link.message_ns(block + 1))

    def move_to_rest(self, timeout_ns: int = 0) -> tuple[int, ...]:
        """Every channel's rest width written (at the current rate); those read back there."""
        rest = self.setup.rest_widths_us()
        packet = self.goal_packet(rest)
        self._write(packet)
        self.widths_us.update(rest)
        held = self._read(packet[0], len(packet) - 1)
        low = (packet[0] - LED0_ON_L) // LED_STRIDE
        return tuple(
            ch for ch in rest
            if held[(ch - low) * LED_STRIDE:(ch - low + 1) * LED_STRIDE]
            == packet[1 + (ch - low) * LED_STRIDE:1 + (ch - low + 1) * LED_STRIDE])

    def asleep(self) -> bool:
        """Whether the board is asleep: as it powers up, so after a loss of power."""
        return bool(self._read(MODE1, 1)[0] & SLEEP)

    def holds(self, goals_us: Mapping[int, int]) -> bool:
        """Whether the board runs at the rate it was given and its registers hold these
        widths (read back): a board that lost power reads asleep, at its reset prescale."""
        if self.asleep() or self._read(PRE_SCALE, 1)[0] != self.prescale:
            return False
        packet = self.goal_packet(goals_us)
        return self._read(packet[0], len(packet) - 1) == packet[1:]

    def assume_goals(self, goals_steps: Mapping[int, int]) -> None:
        self.widths_us.update(goals_steps)

    def read_telemetry(self, servo_ids: tuple[int, ...]) -> tuple[Telemetry, ...]:
        return ()  # hobby servos report nothing

    def travel_ns(self) -> int:
        """How long the servos may take to reach rest from where they were sent."""
        rest = self.setup.rest_widths_us()
        farthest = max((abs(self.widths_us.get(ch, w) - w) for ch, w in rest.items()),
                       default=0)
        farthest = max(farthest, max((s.max_steps - s.min_steps for s in self.setup.servos),
                                     default=0))
        return ceil(farthest * NS_PER_S / max(1, self.speed_us_per_s)) + REST_SETTLE_NS

    def rest_and_release(self) -> SafeStopReport:
        """Rest widths, held while the servos travel there; then no pulses at all."""
        channels = self.setup.servo_ids
        try:
            at_rest = self._rest_awake()
            # The rest widths leave the board from the next period boundary on: the servos get
            # them for their travel time counted from there.
            period = ceil(period_ns(self.setup.osc_hz, self.prescale))
            self.clock.sleep_until_ns(self.clock.now_ns() + period + self.travel_ns())
            self._write(bytes([ALL_LED_ON_L, 0, 0, 0, FULL_BIT]))  # every channel full off
            return SafeStopReport(at_rest, channels, ())
        except PortLost:
            return SafeStopReport((), (), channels, port_lost=True)
        except PinArrayError:  # the bus, or rest widths the board's period cannot hold
            try:
                self._write(bytes([ALL_LED_ON_L, 0, 0, 0, FULL_BIT]))
                return SafeStopReport((), channels, ())
            except (BusError, OSError):
                return SafeStopReport((), (), channels)

    def _rest_awake(self) -> tuple[int, ...]:
        """Rest widths; a board found asleep (power lost) is restarted at the protocol's rate."""
        mode = self._read(MODE1, 1)[0]
        if mode & SLEEP:
            self.counters.power_losses += 1
            self.hold()
            return self.setup.servo_ids
        # Widths in counts of the rate the board runs at: a player process may have left it
        # at a trial's rate that this process never set.
        self.prescale = self._read(PRE_SCALE, 1)[0]
        return self.move_to_rest()

    def handover(self) -> Handover:
        return Pca9685Handover(self.port_name, self.setup, self.speed_us_per_s, self.log_path)

    def stats(self) -> BusStats:
        c = self.counters
        return BusStats(c.bytes_written, c.bytes_read, c.frames, c.goals, c.retries)

    def close(self) -> None:
        try:
            self.link.close()
        finally:
            if self.log is not None:
                self.log.close()


@dataclass(frozen=True)
class Pca9685Handover:
    """A connected board as the player process takes it over through the bus's descriptor."""

    port_name: str
    setup: PwmSetup
    speed_us_per_s: int
    log_path: str | None

    def attach(self, fd: int, clock: Clock) -> Pca9685Array:
        from pinarray.hardware.pca9685.i2c_log import I2cLog
        from pinarray.hardware.pca9685.sim import SimI2cLink, is_pca9685_url
        from pinarray.hardware.pca9685.smbus_link import SmbusLink

        link: I2cLink
        if is_pca9685_url(self.port_name):
            link = SimI2cLink(self.port_name, clock)  # boards kept in a file: opened again
        else:
            link = SmbusLink(fd, clock, fd=True)
        log = I2cLog(self.log_path, append=True) if self.log_path is not None else None
        board = Pca9685Array(link, self.setup, clock, self.speed_us_per_s, log, self.log_path)
        board.warnings.clear()
        return board


@dataclass
class PwmVerifier:
    """Reads each written block back in the slack; heals it while its period has not begun."""

    board: Pca9685Array
    clock: Clock
    trial: PwmTrial
    onset_ns: int
    ledger: DeliveryLedger
    pending_frames: list[int] = field(default_factory=list)
    frames_sent: int = 0
    written_stop_ns: dict[int, int] = field(default_factory=dict)
    healed: set[int] = field(default_factory=set)
    lateness_ns: dict[int, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.lateness_ns = dict(enumerate(self.trial.change_lateness_ns))
        first = self.trial.frames[0].first_change if self.trial.frames else len(self.trial.changes)
        self._initial = list(range(first))  # period-0 changes: written before the counter

    @property
    def pending(self) -> dict[int, int]:
        out: dict[int, int] = {}
        for frame_index in self.pending_frames:
            frame = self.trial.frames[frame_index]
            for offset, (channel, _w) in enumerate(frame.goals):
                out[channel] = frame.first_change + offset
        return out

    def _counter_shift_ns(self) -> int:
        started = self.board.counter_started_ns
        return 0 if started is None else started - self.onset_ns

    def _confirm_initial(self) -> None:
        """The period-0 changes were read back with the registers written before the counter
        started (`Pca9685Array.begin`); they count from when it did."""
        shift = self._counter_shift_ns()
        for index in self._initial:
            self.ledger.confirm(index, self.lateness_ns[index] + shift, healed=False)
        self._initial = []

    def sent(self, frame: PreparedFrame, sent_ns: int) -> None:
        if self._initial:
            self._confirm_initial()
        index = self.frames_sent
        self.frames_sent += 1
        self.written_stop_ns[index] = self.board.last_stop_ns - self.onset_ns
        self.pending_frames.append(index)

    def work_until(self, limit_ns: int) -> None:
        if self._initial and self.board.counter_started_ns is not None:
            self._confirm_initial()
        board, clock = self.board, self.clock
        while self.pending_frames:
            frame_index = self.pending_frames[0]
            frame = self.trial.frames[frame_index]
            length = len(frame.packet) - 1
            cost = board.link.message_ns(1) + board.link.message_ns(length)
            if clock.now_ns() + cost > limit_ns:
                return
            window_end = self.onset_ns + self._counter_shift_ns() \
                + self.trial.window_end_ns(frame_index)
            try:
                held = board._read(frame.packet[0], length)
            except PortLost:
                raise
            except BusError as error:
                self._lose(frame_index, f"the board did not answer its read-back ({error})")
                continue
            if held == frame.packet[1:]:
                self._settle(frame_index)
                continue
            if board._read(MODE1, 1)[0] & SLEEP:
                board.counters.power_losses += 1
                self._lose(frame_index, f"board 0x{board.setup.address:02x} lost power: its "
                                        "registers are back to their reset values (SLEEP set, "
                                        "outputs off)")
                continue
            rewrite_ns = board.link.message_ns(len(frame.packet))
            if clock.now_ns() + rewrite_ns <= min(limit_ns, window_end):
                board._write(frame.packet)
                board.counters.retries += 1
                self.written_stop_ns[frame_index] = board.last_stop_ns - self.onset_ns
                self.healed.add(frame_index)
                continue  # read back again
            self._lose(frame_index, "the board did not hold its registers and its period "
                                    "began before they could be written again")

    def sample_until(self, limit_ns: int) -> None:
        """Hobby PWM servos report no position: nothing to sample (their trials' strokes are
        not measured)."""

    def trace(self) -> tuple[PinTrace, ...]:
        return ()

    def _settle(self, frame_index: int) -> None:
        self.pending_frames.pop(0)
        frame = self.trial.frames[frame_index]
        window_end = self._counter_shift_ns() + self.trial.window_end_ns(frame_index)
        stop = self.written_stop_ns.get(frame_index, 0)
        for offset in range(len(frame.goals)):
            index = frame.first_change + offset
            if stop > window_end:
                self.ledger.lose(index, f"written {(stop - window_end) / 1e6:.3f} ms after its "
                                        "PWM period began: that period's pulse went out with "
                                        "the old width")
            else:
                self.ledger.confirm(index, self.lateness_ns[index] + self._counter_shift_ns(),
                                    healed=frame_index in self.healed)

    def _lose(self, frame_index: int, why: str) -> None:
        self.pending_frames.remove(frame_index)
        frame = self.trial.frames[frame_index]
        for offset in range(len(frame.goals)):
            self.ledger.lose(frame.first_change + offset, why)


