"""A simulated PCA9685 board: its register file, and the pulses its pins carry, per NXP's datasheet.

Section numbers are those of the datasheet, rev. 4 (16 April 2015); where it is silent or
ambiguous the reading chosen is said as "Reading:". The board is driven by messages with the
clock time (ns) of their STOP; it answers, and it remembers what it latched when, so that
`SimulatedBoard.pulses` can say afterwards, exactly, what left each pin.

Register file (7.3, Table 3)
    MODE1 0x11, MODE2 0x04, SUBADR1..3 0xE2/0xE4/0xE8, ALLCALLADR 0xE0, every LEDn_ON 0x0000,
    every LEDn_OFF_H 0x10 (full off), PRE_SCALE 0x1E at power-up and after a software reset.
    "Reserved addresses will not be acknowledged": a control byte naming 0x46..0xF9 is refused.
    Bits 7:5 of MODE2 and of every LEDn_ON_H / LEDn_OFF_H are "reserved, non-writable" and
    read 0 (Table 7). TEST_MODE (0xFF) "may cause unpredictable results"; Reading: writes to
    it are acknowledged and ignored, and it reads 0.
Auto-increment (7.3, remark under Table 3; 7.3.1 AI)
    With MODE1's AI bit set the register pointer advances after each byte read or written;
    "Auto Increment past register 69 will point to MODE1 register (register 0). Auto Increment
    also works from register 250 to register 254, then rolls over to register 0." Reading:
    past 0xFF it also goes to 0x00. With AI clear the pointer stays where the control byte put
    it, so every byte goes to (or comes from) the same register.
ALL_LED (7.3.4, Table 3 "write/read zero")
    A write to ALL_LED_ON_L..ALL_LED_OFF_H loads that byte of every channel's four registers;
    the ALL_LED registers themselves read back as 0.
LEDn ON/OFF (7.3.3, Figs 7-9)
    The 12-bit counter counts 0..4095 in each period; the output goes high when the counter
    reaches LEDn_ON and low when it reaches LEDn_OFF, so an OFF below ON makes a pulse that
    wraps into the next period (Fig 8). LEDn_OFF_H bit 4 (full off) "takes precedence" over
    everything; LEDn_ON_H bit 4 (full on) holds the output high from its ON count on.
    ON equal to OFF gives no pulse (Fig 9 example 4 shows the output off). Reading: the output
    is edge-driven, so a level carries from one period into the next.
When new ON/OFF values take effect (7.3.2 MODE2 OCH; 7.3.3 "updating the changes at the end of
    the LOW cycle"; Figs 10-11 "register(s) updated in this cycle / output(s) updated in this
    cycle")
    With OCH 0 (reset) a channel's new values are taken at the STOP of the message that wrote
    them, with OCH 1 at the ACK of the byte written; in either case the output follows from the
    next period boundary (counter 4095 -> 0). Reading: "end of the LOW cycle" is read as the
    end of the period, as Figs 10-11 draw it.
SLEEP, the oscillator and RESTART (7.3.1 Table 5 SLEEP and RESTART; 7.3.1.1 Restart mode)
    At power-up SLEEP is set: the oscillator is off and no pin carries pulses. "It takes 500 us
    max. for the oscillator to be up and running once SLEEP bit has been set to logic 0."
    Setting SLEEP "without stopping any of the PWM channels" sets RESTART "at the end of the
    PWM refresh cycle"; Reading: the pins carry pulses until that period ends, then stop. The
    datasheet's restart procedure: read MODE1, clear SLEEP, wait 500 us, write RESTART (1);
    "All PWM channels will restart and the RESTART bit will clear." "The SLEEP bit must be
    logic 0 for at least 500 us, before a logic 1 is written into the RESTART bit"; Reading:
    a RESTART written sooner is ignored (the bit stays 1, a read-back shows it). Writing 0 to
    RESTART has no effect. Also clearing RESTART (7.3.1.1): a write to any PWM register (at
    the STOP with OCH 0) restarts the outputs too. Reading: while RESTART is pending after a
    wake-up the pins stay off, and the counter starts from 0 at the moment the channels
    restart (the STOP of the message that restarts them, or 500 us after the wake-up if that
    is later). Waking with RESTART clear (nothing to restart) starts the counter 500 us after
    the STOP that cleared SLEEP.
EXTCLK (7.3.1 Table 5)
    A sticky bit: set, it is cleared only by a power cycle or a software reset. Reading: the
    clock it selects runs at the board's ``osc_hz`` (the URL names the clock, whichever it is).
PRE_SCALE (7.3.5)
    "The PRE_SCALE register can only be set when the SLEEP bit of MODE1 register is set to
    logic 1"; Table 3 note: "Writes to PRE_SCALE register are blocked when SLEEP bit is logic
    0". Reading: a blocked write is still acknowledged. "The hardware forces a minimum value
    that can be loaded into the PRE_SCALE register at '3'": smaller values load 3. The period
    is ``registers.period_ns(osc_hz, prescale)``, fixed for as long as the counter runs.
All channels full off
    The datasheet does not say that the counter stops when every channel is full off (the
    issue that asked for this simulator says it does). Reading: the counter runs whenever the
    oscillator runs; the driver must not depend on its phase across an all-off stretch anyway
    and restarts it (SLEEP, RESTART) before each trial.
Addresses (7.1)
    The board answers its own address, the LED All Call address (ALLCALLADR >> 1, 0x70 at
    reset) while MODE1's ALLCALL bit is set, and SUBADRn >> 1 while SUBn is set. Reading: an
    All Call or Sub Call read is not answered (those addresses are for writing many boards).
Software reset (7.1.4, 7.6)
    General call address 0x00 with R/W 0, then the one byte 0x06: every board resets to its
    power-up values at the STOP. Any other first byte is not acknowledged, nor any byte after
    0x06, and then nothing is reset.
Power (7.6 "power-up state")
    `lose_power` drops the outputs at once and, when power returns (`power_up`), every
    register holds its power-up value: SLEEP set, outputs full off.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from math import floor

from pinarray.hardware.pca9685 import registers as r

_RESERVED = range(r.LAST_LED_REGISTER + 1, r.ALL_LED_ON_L)
_LED_STATE_OFF = (0, 0, False, True)
# A latch key: (counter run, period index within it); a change keyed (n, 0) for a run not yet
# started applies from the start of that run.
Key = tuple[int, int]


@dataclass
class _Run:
    """One stretch of the counter running: period boundaries at ``start_ns + k * period_ns``."""

    start_ns: Fraction
    period_ns: Fraction
    end_ns: Fraction | None = None  # the counter stopped here (None: still running)


@dataclass(frozen=True)
class BoardParts:
    """Everything one board holds, as plain values: what a state file keeps (`board_file`).

    ``runs`` are the counter's stretches (start, period, end or None, exact ns); ``latched``
    holds, per channel, each latch key with the (ON count, OFF count, full on, full off) the
    channel's output follows from it.
    """

    osc_hz: int
    address: int
    powered: bool
    registers: bytes
    pointer: int
    restart_from: Fraction | None
    awake_from: Fraction | None
    runs: tuple[tuple[Fraction, Fraction, Fraction | None], ...]
    latched: tuple[tuple[tuple[Key, tuple[int, int, bool, bool]], ...], ...]


@dataclass(frozen=True)
class _ChannelState:
    """What one channel's output does in a period, as latched from its four registers."""

    on_count: int
    off_count: int
    full_on: bool
    full_off: bool

    def edges(self) -> list[tuple[int, bool]]:
        """(count, level) switches within one period, in order; OFF wins a tie with ON."""
        if self.full_off:
            return [(0, False)]
        if self.full_on:
            return [(self.on_count, True)]
        if self.on_count == self.off_count:
            return [(self.on_count, False)]
        switches = [(self.on_count, True), (self.off_count, False)]
        return sorted(switches)

    @property
    def level_at_end(self) -> bool:
        return self.edges()[-1][1]


class SimulatedBoard:
    """One PCA9685 on a simulated bus.

    Parameters
    ----------
    osc_hz : int
        The oscillator's real frequency, Hz (nominally 25 MHz, boards are off by percents).
    address : int
        The board's own 7-bit address (0x40 + its A5..A0 pins).
    """

    def __init__(self, osc_hz: int, address: int = r.FIRST_ADDRESS):
        if osc_hz <= 0:
            raise ValueError(f"expected an oscillator frequency above 0 Hz, found {osc_hz}")
        self.osc_hz = osc_hz
        self.address = address
        self._runs: list[_Run] = []
        self._latched: list[tuple[list[Key], list[_ChannelState]]] = [
            ([], []) for _ in range(r.CHANNELS)
        ]
        self.powered = False
        self.power_up(0)

    def parts(self) -> BoardParts:
        """The board as plain values (`BoardParts`)."""
        return BoardParts(
            self.osc_hz, self.address, self.powered, bytes(self._regs), self._pointer,
            self._restart_from, self._awake_from,
            tuple((run.start_ns, run.period_ns, run.end_ns) for run in self._runs),
            tuple(tuple((key, (s.on_count, s.off_count, s.full_on, s.full_off))
                        for key, s in zip(keys, states, strict=True))
                  for keys, states in self._latched))

    @classmethod
    def from_parts(cls, parts: BoardParts) -> SimulatedBoard:
        """A board holding ``parts`` (checked by whoever read them: `board_file`)."""
        board = cls(parts.osc_hz, parts.address)
        board.powered = parts.powered
        board._regs = bytearray(parts.registers)
        board._pointer = parts.pointer
        board._restart_from, board._awake_from = parts.restart_from, parts.awake_from
        board._runs = [_Run(start, period, end) for start, period, end in parts.runs]
        board._latched = [([key for key, _ in channel],
                           [_ChannelState(*state) for _, state in channel])
                          for channel in parts.latched]
        return board

    # -- power --------------------------------------------------------------------------------

    def power_up(self, at_ns: int) -> None:
        """Power arrives: every register holds its power-up value (SLEEP set, outputs off)."""
        self.powered = True
        self._reset(Fraction(at_ns))

    def lose_power(self, at_ns: int) -> None:
        """Power goes: the pins drop at once; the board answers nothing until `power_up`."""
        self._stop_counter(Fraction(at_ns))
        self._latch_all_off()
        self.powered = False

    def _reset(self, at: Fraction) -> None:
        self._stop_counter(at)
        regs = bytearray(256)
        regs[r.MODE1] = r.MODE1_RESET
        regs[r.MODE2] = r.MODE2_RESET
        regs[r.SUBADR1:r.SUBADR3 + 1] = bytes(r.SUBADR_RESET)
        regs[r.ALLCALLADR] = r.ALLCALLADR_RESET
        for channel in range(r.CHANNELS):
            regs[r.led_register(channel) + 3] = r.FULL_BIT
        regs[r.PRE_SCALE] = r.PRESCALE_RESET
        self._regs = regs
        self._pointer = 0
        self._restart_from: Fraction | None = None  # RESTART reads 1 from then on
        self._awake_from: Fraction | None = None  # the oscillator is stable from then on
        self._latch_all_off()

    def _latch_all_off(self) -> None:
        for keys, states in self._latched:
            self._append(keys, states, (len(self._runs), 0), _ChannelState(*_LED_STATE_OFF))

    # -- addresses ------------------------------------------------------------------------------

    def answers(self, address: int, read: bool = False) -> bool:
        """Whether the board acknowledges ``address`` (its own, or All Call / Sub Call)."""
        if not self.powered:
            return False
        if address == self.address:
            return True
        if read:
            return False
        mode1 = self._regs[r.MODE1]
        calls = [(r.ALLCALL, r.ALLCALLADR), (r.SUB1, r.SUBADR1), (r.SUB2, r.SUBADR2),
                 (r.SUB3, r.SUBADR3)]
        return any(mode1 & bit and self._regs[reg] >> 1 == address for bit, reg in calls)

    # -- messages -------------------------------------------------------------------------------

    def refused_at(self, data: bytes) -> int | None:
        """The index of the first byte of a write the board would not acknowledge (None: all)."""
        if data and data[0] in _RESERVED:
            return 0
        return None

    def write(self, data: bytes, stop_ns: int, byte_ns: int = 0) -> bool:
        """A write message addressed to this board: control byte, then register bytes.

        ``byte_ns`` is one byte's time on the bus (9 bits), for the ACK times OCH 1 uses.
        Returns whether every byte was acknowledged (nothing is written when one is not).
        """
        if not self.powered or self.refused_at(data) is not None:
            return False
        if not data:
            return True  # an address-only write: a probe
        stop = Fraction(stop_ns)
        self._pointer = data[0]
        touched: dict[int, Fraction] = {}
        payload = data[1:]
        for index, value in enumerate(payload):
            ack = stop - byte_ns * (len(payload) - 1 - index)
            self._write_register(self._pointer, value, stop, ack, touched)
            self._advance()
        for channel, at in sorted(touched.items()):
            self._latch(channel, at)
        return True

    def read(self, count: int, stop_ns: int) -> bytes:
        """``count`` bytes from the register pointer (auto-incrementing when AI is set)."""
        now = Fraction(stop_ns)
        out = bytearray()
        for _ in range(count):
            out.append(self._read_register(self._pointer, now))
            self._advance()
        return bytes(out)

    def general_call(self, data: bytes, stop_ns: int) -> int | None:
        """A general call (address 0x00): the software reset when ``data`` is exactly 0x06.

        Returns the index of the first byte not acknowledged (None: all were).
        """
        if not self.powered:
            return 0  # Reading: an unpowered board holds nothing; the caller sees the NACK
        if not data:
            return None
        if data[0] != r.SWRST_BYTE:
            return 0
        if len(data) > 1:
            return 1
        self._reset(Fraction(stop_ns))
        return None

    def _advance(self) -> None:
        if not self._regs[r.MODE1] & r.AI:
            return
        if self._pointer == r.LAST_LED_REGISTER or self._pointer >= r.PRE_SCALE:
            self._pointer = r.MODE1
        else:
            self._pointer += 1

    def _read_register(self, register: int, now: Fraction) -> int:
        if register == r.MODE1:
            restart = self._restart_from is not None and now >= self._restart_from
            return (self._regs[r.MODE1] & ~r.RESTART) | (r.RESTART if restart else 0)
        if r.ALL_LED_ON_L <= register <= r.ALL_LED_OFF_H or register == r.TEST_MODE:
            return 0
        return self._regs[register]

    def _write_register(self, register: int, value: int, stop: Fraction, ack: Fraction,
                        touched: dict[int, Fraction]) -> None:
        regs = self._regs
        if register == r.MODE1:
            self._write_mode1(value, stop)
        elif register == r.MODE2:
            regs[r.MODE2] = value & r.MODE2_WRITABLE
        elif register <= r.ALLCALLADR:
            regs[register] = value
        elif register <= r.LAST_LED_REGISTER:
            channel, byte = divmod(register - r.LED0_ON_L, r.LED_STRIDE)
            regs[register] = value & (r.LED_HIGH_WRITABLE if byte % 2 else 0xFF)
            touched[channel] = ack if regs[r.MODE2] & r.OCH else stop
        elif register <= r.ALL_LED_OFF_H:
            byte = register - r.ALL_LED_ON_L
            for channel in range(r.CHANNELS):
                regs[r.led_register(channel) + byte] = value & (
                    r.LED_HIGH_WRITABLE if byte % 2 else 0xFF)
                touched[channel] = ack if regs[r.MODE2] & r.OCH else stop
        elif register == r.PRE_SCALE:
            if regs[r.MODE1] & r.SLEEP:
                regs[r.PRE_SCALE] = max(r.PRESCALE_MIN, value)
        # TEST_MODE: acknowledged, ignored

    def _write_mode1(self, value: int, at: Fraction) -> None:
        old = self._regs[r.MODE1]
        sticky = old & r.EXTCLK
        self._regs[r.MODE1] = (value & ~r.RESTART) | sticky
        was_asleep, asleep = bool(old & r.SLEEP), bool(value & r.SLEEP)
        if asleep and not was_asleep:
            self._go_to_sleep(at)
        elif was_asleep and not asleep:
            self._wake(at)
        elif (value & r.RESTART and not asleep and self._restart_pending(at)
              and self._awake_from is not None and at >= self._awake_from):
            self._restart(at)

    def _restart_pending(self, at: Fraction) -> bool:
        return self._restart_from is not None and at >= self._restart_from

    def _go_to_sleep(self, at: Fraction) -> None:
        self._awake_from = None
        run = self._running(at)
        if run is None:
            self._stop_counter(at)  # a counter not yet started never starts
            return
        end = self._boundary_after(run, at)
        run.end_ns = end
        active = any(not self._regs[r.led_register(channel) + 3] & r.FULL_BIT
                     for channel in range(r.CHANNELS))
        if active and self._restart_from is None:
            self._restart_from = end

    def _wake(self, at: Fraction) -> None:
        self._stop_counter(at)
        self._awake_from = at + r.OSCILLATOR_START_NS
        if self._restart_from is None:
            self._start_counter(self._awake_from)

    def _restart(self, at: Fraction) -> None:
        """The channels restart: RESTART clears and the counter starts from 0."""
        self._restart_from = None
        assert self._awake_from is not None
        self._start_counter(max(at, self._awake_from))

    def _start_counter(self, at: Fraction) -> None:
        period = r.period_ns(self.osc_hz, self._regs[r.PRE_SCALE])
        self._runs.append(_Run(at, period))

    def _stop_counter(self, at: Fraction) -> None:
        if self._runs and (self._runs[-1].end_ns is None or self._runs[-1].end_ns > at):
            run = self._runs[-1]
            run.end_ns = max(run.start_ns, at)

    def _running(self, at: Fraction) -> _Run | None:
        if not self._runs:
            return None
        run = self._runs[-1]
        if run.end_ns is not None and run.end_ns <= at:
            return None
        return run

    @staticmethod
    def _boundary_after(run: _Run, at: Fraction) -> Fraction:
        return run.start_ns + run.period_ns * _period_after(run, at)

    def _latch(self, channel: int, at: Fraction) -> None:
        """Channel ``channel``'s registers as written at ``at`` drive its pin from the next
        period boundary."""
        if self._restart_pending(at):  # 7.3.1.1: a PWM register write clears RESTART too
            if self._awake_from is None:
                self._restart_from = None  # asleep: the counter starts when it wakes
            else:
                self._restart(at)
        base = r.led_register(channel)
        on_low, on_high, off_low, off_high = self._regs[base:base + r.LED_STRIDE]
        state = _ChannelState((on_high & 0x0F) << 8 | on_low, (off_high & 0x0F) << 8 | off_low,
                              bool(on_high & r.FULL_BIT), bool(off_high & r.FULL_BIT))
        run = self._running(at)
        key: Key = (len(self._runs), 0)
        if run is not None:
            period = _period_after(run, at)
            if run.end_ns is None or run.start_ns + run.period_ns * period < run.end_ns:
                key = (len(self._runs) - 1, period)
        keys, states = self._latched[channel]
        self._append(keys, states, key, state)

    @staticmethod
    def _append(keys: list[Key], states: list[_ChannelState], key: Key,
                state: _ChannelState) -> None:
        if keys and keys[-1] >= key:
            # a later write in the same period replaces what an earlier one latched
            del states[bisect.bisect_left(keys, key):]
            del keys[bisect.bisect_left(keys, key):]
        keys.append(key)
        states.append(state)

    def _state_at(self, channel: int, key: Key) -> _ChannelState:
        keys, states = self._latched[channel]
        index = bisect.bisect_right(keys, key) - 1
        return states[index] if index >= 0 else _ChannelState(*_LED_STATE_OFF)

    # -- the outputs ------------------------------------------------------------------------------

    def period_ns(self) -> Fraction:
        """The period the PRE_SCALE register now gives, exact ns."""
        return r.period_ns(self.osc_hz, self._regs[r.PRE_SCALE])

    def counter_runs(self) -> list[tuple[Fraction, Fraction, Fraction | None]]:
        """Each stretch the counter ran: (start ns, period ns, end ns or None), exact."""
        return [(run.start_ns, run.period_ns, run.end_ns) for run in self._runs]

    def pulses(self, channel: int, from_ns: int, to_ns: int) -> list[tuple[int, int]]:
        """The pulses channel ``channel``'s pin carried that rose in ``[from_ns, to_ns)``.

        Each is ``(start_ns, width_ns)``, its edges the exact times floored to the ns (so no
        error accumulates however long the board ran). A pulse is followed to its falling
        edge even past ``to_ns``, but not past the end of its counter run (sleep, reset, power
        loss) nor more than one period past ``to_ns`` (a pin held high for good).
        """
        r.led_register(channel)
        found: list[tuple[int, int]] = []
        for index, run in enumerate(self._runs):
            found.extend(self._run_pulses(channel, index, run, Fraction(from_ns), Fraction(to_ns)))
        return found

    def _run_pulses(self, channel: int, index: int, run: _Run, start: Fraction,
                    stop: Fraction) -> Iterator[tuple[int, int]]:
        end = run.end_ns
        if stop <= run.start_ns or (end is not None and end <= start):
            return
        period = run.period_ns
        tick = period / r.COUNTS
        first = max(0, floor((start - run.start_ns) / period))
        level = first > 0 and self._state_at(channel, (index, first - 1)).level_at_end
        rose: Fraction | None = run.start_ns + first * period if level else None
        k = first
        while True:
            boundary = run.start_ns + k * period
            if end is not None and boundary >= end:
                break
            if boundary >= stop and (rose is None or boundary >= stop + period):
                break
            for count, high in self._state_at(channel, (index, k)).edges():
                at = boundary + count * tick
                if end is not None and at >= end:
                    break
                if high and rose is None:
                    rose = at
                elif not high and rose is not None:
                    if start <= rose < stop:
                        yield floor(rose), floor(at) - floor(rose)
                    rose = None
            k += 1
        if rose is not None and start <= rose < stop:
            cut = run.start_ns + k * period if end is None else min(end, run.start_ns + k * period)
            yield floor(rose), floor(cut) - floor(rose)


def _period_after(run: _Run, at: Fraction) -> int:
    """Index of the first period boundary of ``run`` strictly after ``at`` (0: its start)."""
    if at <= run.start_ns:
        return 0
    return floor((at - run.start_ns) / run.period_ns) + 1
