"""A trial's pulses as a PCA9685 board can place them: the period, each write's window, and
the pulses that will leave the board, predicted against the schedule. Pure: no I/O.

The board emits one pulse per channel per PWM period, starting at the channel's ON count, as
wide as its OFF count says, and takes a new ON/OFF only at a period boundary. So a trial is
planned in periods of the board's own counter, started at the trial's onset:

- **One pulse per period** (the seed's trains: a pulse every 1/30, 1/50, 1/100 s) when every
  pulse of the trial falls on one grid of slots ``S``: the rate is ``1/S``, the prescale the
  nearest the board allows, each pin's phase its ON count, and pulse ``k`` of the schedule is
  the board's pulse in period ``k``. What that costs: the board's period ``P`` is
  ``4096 * (prescale + 1) / osc_hz``, not ``S``, so pulse ``k`` drifts ``k * (P - S)`` from
  the schedule (0.38 % of the elapsed time at 100 Hz on a 25.3 MHz board), plus half a count
  of rounding in its start and width.
- **Otherwise** (trains of different rates at once, a change between pulses) the board runs at
  the protocol's ``pwm_hz`` and a change shows from the first pulse that starts at or after
  its time: up to one period late.

A change for period ``n`` is written in period ``n - 1`` (after the boundary that started it,
so it cannot reach period ``n - 1`` itself, and before ``n`` begins); changes of period 0 are
in place before the counter starts; a write begins at its first channel's OFF count (the ON
counts, each pin's phase, are written with the first registers and hold for the trial). A trial whose predicted drift exceeds the protocol's
tolerance, or that needs two changes of one pin in one period, is refused before anything is
sent, saying what to change.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from math import ceil, floor

from pinarray.errors import PinArrayError
from pinarray.hardware.delivery import Change, PreparedFrame, PreparedTrial
from pinarray.hardware.driver import Pulses, ServoSetup, Targets
from pinarray.hardware.frames import check_limits, distinct_pins
from pinarray.hardware.pca9685.registers import (
    CHANNELS,
    COUNTS,
    FULL_OFF,
    PRESCALE_MAX,
    PRESCALE_MIN,
    LedBlock,
    led_register,
    period_ns,
    prescale_for,
    tick_ns,
)
from pinarray.units import NS_PER_MS, NS_PER_S, NS_PER_US

ON_BYTES = 2  # LEDn_ON_L, LEDn_ON_H: the first half of a channel's block

# A period's write goes out this long after the boundary that opens its window, so that the
# host's clock and the board's counter, started together, cannot disagree about the period.
WINDOW_MARGIN_NS = 200_000


@dataclass(frozen=True)
class PwmSetup:
    """A PCA9685 array: each pin's channel (its ``servo_id``), rest and limits in us of width."""

    servos: tuple[ServoSetup, ...]
    address: int = 0x40
    osc_hz: int = 25_000_000
    pwm_hz: int = 50
    tolerance_ns: int = 10 * NS_PER_MS

    @property
    def servo_ids(self) -> tuple[int, ...]:
        return tuple(s.servo_id for s in self.servos)

    @property
    def position_unit(self) -> str:
        return "us"

    def rest_widths_us(self) -> dict[int, int]:
        """Channel -> rest width."""
        return {s.servo_id: s.rest_steps for s in self.servos}


@dataclass(frozen=True)
class BoardRate:
    """The board's period for a trial, and whether each scheduled pulse is one period."""

    osc_hz: int
    prescale: int
    slot_ns: Fraction | None  # the schedule's pulse spacing when one pulse per period

    @property
    def period_ns(self) -> Fraction:
        return period_ns(self.osc_hz, self.prescale)

    @property
    def tick_ns(self) -> Fraction:
        return tick_ns(self.osc_hz, self.prescale)

    def describe(self) -> str:
        rate = NS_PER_S / self.period_ns
        text = (f"prescale {self.prescale}: a period of {float(self.period_ns) / 1e6:.4f} ms "
                f"({float(rate):.3f} Hz) at osc {self.osc_hz} Hz")
        if self.slot_ns is not None:
            text += f", for a pulse every {float(self.slot_ns) / 1e6:.4f} ms"
        return text


@dataclass(frozen=True)
class Prediction:
    """One pin's pulses as they will leave the board, against the schedule."""

    pin: int
    channel: int
    on_count: int
    first_period: int
    last_period: int
    worst_deviation_ns: int  # largest |board start - scheduled start| of its scheduled pulses


@dataclass(frozen=True)
class PwmTrial(PreparedTrial):
    """A trial prepared for the board: frames of LED blocks, each in its period's window.

    ``frame_periods[i]`` is the period frame ``i`` sets (written in the period before it);
    ``first_blocks`` every channel's registers for period 0, written before the counter starts.
    """

    rate: BoardRate = BoardRate(25_000_000, 121, None)
    frame_periods: tuple[int, ...] = ()
    first_blocks: tuple[LedBlock, ...] = ()
    predictions: tuple[Prediction, ...] = ()
    change_lateness_ns: tuple[int, ...] = ()  # per change: its pulse's predicted lateness

    @property
    def worst_deviation_ns(self) -> int:
        return max((p.worst_deviation_ns for p in self.predictions), default=0)

    def window_end_ns(self, frame_index: int) -> int:
        """When frame ``frame_index``'s period begins (ns from onset): its write must be done."""
        return floor(self.frame_periods[frame_index] * self.rate.period_ns)

    def write_window_ns(self) -> int | None:
        """The least time any frame has from its scheduled write to its period's start."""
        return min((self.window_end_ns(i) - frame.time_ns for i, frame in enumerate(self.frames)),
                   default=None)


def width_counts(width_us: int, tick: Fraction) -> int:
    """A width in whole counts of the board's tick, nearest (halves up)."""
    return floor(Fraction(width_us * NS_PER_US) / tick + Fraction(1, 2))


def _regular_slot(pulses: Pulses) -> Fraction | None:
    """The one spacing every pulse of the trial keeps (within the schedule's 1 ns rounding), so
    that each can be one period of the board; None when the pulses keep none."""
    if len(pulses.pin) == 0:
        return None
    slot: Fraction | None = None
    for pin in distinct_pins(pulses.pin):
        starts = pulses.start_ns[pulses.pin == pin]
        if len(starts) < 2:
            continue
        mine = Fraction(int(starts[-1] - starts[0]), len(starts) - 1)
        slot = mine if slot is None else slot
        if abs(mine - slot) * (len(starts) - 1) > 2:
            return None
    if slot is None or slot <= 0:
        return None
    # Here, not at import: the player process, which plays a board's trials planned before
    # they reach it, imports no numpy (some 100 ms of processor at each of its starts).
    import numpy as np

    for pin in distinct_pins(pulses.pin):
        starts = pulses.start_ns[pulses.pin == pin].astype(np.float64)
        index = np.round((starts - starts[0]) / float(slot))
        if np.any(np.diff(index) != 1) or np.any(np.abs(starts - starts[0] - index * float(slot)) > 1.5):
            return None
    return slot


def board_rate(setup: PwmSetup, pulses: Pulses) -> BoardRate:
    """One pulse per period where the schedule allows and the board reaches the rate."""
    slot = _regular_slot(pulses)
    if slot is not None:
        rate = NS_PER_S / slot
        exact = Fraction(setup.osc_hz) / (COUNTS * rate) - 1
        if PRESCALE_MIN - Fraction(1, 2) <= exact < PRESCALE_MAX + Fraction(1, 2):
            return BoardRate(setup.osc_hz, prescale_for(setup.osc_hz, rate), slot)
    return BoardRate(setup.osc_hz, prescale_for(setup.osc_hz, Fraction(setup.pwm_hz)), None)


def plan_trial(setup: PwmSetup, targets: Targets, pulses: Pulses) -> PwmTrial:
    """Frames, first registers and predicted pulses of one trial; refuses what the board
    cannot place within the tolerance."""
    check_limits(targets, setup)
    rate = board_rate(setup, pulses)
    period, tick = rate.period_ns, rate.tick_ns
    channel_of_pin = {s.pin: s.servo_id for s in setup.servos}
    widths = {s.servo_id: s.rest_steps for s in setup.servos}  # channel -> width (us)
    on_of_channel: dict[int, int] = {}
    predictions: list[Prediction] = []
    phase_of_pin: dict[int, Fraction] = {}
    if rate.slot_ns is not None:
        slot = rate.slot_ns
        for pin in distinct_pins(pulses.pin):
            starts = pulses.start_ns[pulses.pin == pin]
            first, last = int(starts[0]), int(starts[-1])
            first_slot = max(0, floor(Fraction(first) / slot + Fraction(1, 10 ** 6)))
            phase = Fraction(first) - first_slot * slot
            on = floor(phase / tick + Fraction(1, 2))
            if on >= COUNTS:
                on -= COUNTS
                first_slot += 1
            phase_of_pin[pin] = Fraction(first) - first_slot * slot
            channel = channel_of_pin[pin]
            on_of_channel[channel] = on
            last_slot = first_slot + len(starts) - 1
            deviations = [abs(n * period + on * tick - start)
                          for n, start in ((first_slot, first), (last_slot, last))]
            predictions.append(Prediction(pin, channel, on, first_slot, last_slot,
                                          ceil(max(deviations))))
    by_period: dict[int, dict[int, int]] = {}  # period -> channel -> width (us)
    due: dict[int, list[tuple[Change, int]]] = {}  # period -> (change, predicted lateness)
    changes: list[tuple[int, Change]] = []  # (period, change)
    deviation: list[int] = []
    for t, pin, width in zip(targets.time_ns.tolist(), targets.pin.tolist(),
                             targets.position_steps.tolist(), strict=True):
        channel = channel_of_pin[pin]
        on = on_of_channel.get(channel, 0)
        if rate.slot_ns is not None and pin in phase_of_pin:
            n = round((Fraction(t) - phase_of_pin[pin]) / rate.slot_ns)
        else:
            n = max(0, ceil((Fraction(t) - on * tick) / period))
        in_period = by_period.setdefault(n, {})
        if channel in in_period:
            raise PinArrayError(
                f"pin {pin}: two width changes fall in one PWM period ({float(period) / 1e6:.3f} "
                f"ms, {rate.describe()}) at {t / 1e9:.4f} s: the board would never show the "
                "first; lengthen the pulse or raise the board's pwm_hz")
        in_period[channel] = width
        change, late_ns = Change(channel, pin, width, t), ceil(n * period + on * tick - t)
        changes.append((n, change))
        deviation.append(late_ns)
        due.setdefault(n, []).append((change, late_ns))
    if rate.slot_ns is None:
        for pin in sorted({c.pin for _, c in changes}):
            mine_dev = [d for (_, c), d in zip(changes, deviation, strict=True) if c.pin == pin]
            channel = channel_of_pin[pin]
            periods = [n for n, c in changes if c.pin == pin]
            predictions.append(Prediction(pin, channel, on_of_channel.get(channel, 0),
                                          min(periods), max(periods), max(mine_dev)))
    worst = max(predictions, key=lambda p: p.worst_deviation_ns, default=None)
    if worst is not None and worst.worst_deviation_ns > setup.tolerance_ns:
        raise PinArrayError(_too_far(worst, rate, setup, targets.end_ns))

    def block(channel: int, width_us: int) -> LedBlock:
        counts = width_counts(width_us, tick)
        if not 0 < counts < COUNTS:
            raise PinArrayError(f"channel {channel}: a {width_us} us pulse does not fit the "
                                f"board's period ({rate.describe()})")
        return LedBlock.pulse(on_of_channel.get(channel, 0), counts)

    at_start = dict(widths)
    at_start.update(by_period.pop(0, {}))
    first_blocks = tuple(block(ch, at_start[ch]) if ch in at_start else FULL_OFF
                         for ch in range(CHANNELS))
    current = dict(at_start)
    frames: list[PreparedFrame] = []
    ordered: list[Change] = [c for c, _ in due.get(0, [])]
    frame_periods: list[int] = []
    lateness: list[int] = [d for _, d in due.get(0, [])]
    for n in sorted(by_period):
        current.update(by_period[n])
        low, high = min(by_period[n]), max(by_period[n])
        # From the first changed channel's OFF_L: its ON count (the pin's phase) is on the
        # board since `begin` and stays for the trial, so a one-channel frame is 4 bytes.
        data = bytes([led_register(low) + ON_BYTES]) + b"".join(
            (block(ch, current[ch]) if ch in current else FULL_OFF).encode()
            for ch in range(low, high + 1))[ON_BYTES:]
        goals = tuple(sorted(by_period[n].items()))
        in_order = sorted(due[n], key=lambda cd: cd[0].servo_id)
        frames.append(PreparedFrame(ceil((n - 1) * period) + WINDOW_MARGIN_NS, data, goals,
                                    len(ordered)))
        frame_periods.append(n)
        ordered.extend(c for c, _ in in_order)
        lateness.extend(d for _, d in in_order)
    return PwmTrial(tuple(frames), tuple(ordered), targets.end_ns,
                    {s.servo_id: s.pin for s in setup.servos}, rate, tuple(frame_periods),
                    first_blocks, tuple(predictions), tuple(lateness))


def _too_far(worst: Prediction, rate: BoardRate, setup: PwmSetup, end_ns: int) -> str:
    text = (f"refusing to play: pin {worst.pin}'s pulses would leave the board up to "
            f"{worst.worst_deviation_ns / 1e6:.1f} ms from the schedule ({rate.describe()}); "
            f"the tolerance is {setup.tolerance_ns / 1e6:g} ms: ")
    if rate.slot_ns is not None:
        drift = abs(rate.period_ns - rate.slot_ns) / rate.slot_ns
        if drift:
            tenths = floor(setup.tolerance_ns / drift / (NS_PER_S // 10))  # at most: down
            text += (f"the period is {float(drift) * 100:.2f} % off the schedule's, so "
                     f"stimuli of at most {tenths / 10:.1f} s fit; ")
    return text + ("shorten the stimulus, measure the board's osc_hz (docs/rig/pwm.md: "
                   "measuring a board's oscillator), clock it from EXTCLK, or raise "
                   "device: delivery_tolerance_ms")
