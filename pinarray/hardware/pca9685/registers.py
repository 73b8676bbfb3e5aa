"""The PCA9685's registers and the arithmetic of its PWM counter, from NXP's datasheet (rev. 4).

Pure values: no I/O. A 12-bit counter counts oscillator ticks ``0..4095`` in every period;
channel ``n`` goes high when the counter equals its ON count and low when it equals its OFF
count (`LedBlock`). One prescaler sets the period for all channels::

    prescale = round(osc_hz / (4096 * rate_hz)) - 1        (3 <= prescale <= 255)
    period   = 4096 * (prescale + 1) / osc_hz seconds

so the nominal 25 MHz oscillator gives 24 Hz to 1526 Hz. PRE_SCALE can be written only while
MODE1's SLEEP bit is set.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from pinarray.units import NS_PER_S

MODE1 = 0x00
MODE2 = 0x01
SUBADR1, SUBADR2, SUBADR3 = 0x02, 0x03, 0x04
ALLCALLADR = 0x05
LED0_ON_L = 0x06
LED_STRIDE = 4  # ON_L, ON_H, OFF_L, OFF_H
CHANNELS = 16
LAST_LED_REGISTER = LED0_ON_L + LED_STRIDE * CHANNELS - 1  # LED15_OFF_H, 0x45
ALL_LED_ON_L = 0xFA
ALL_LED_OFF_H = 0xFD
PRE_SCALE = 0xFE
TEST_MODE = 0xFF

# MODE1 bits
RESTART = 0x80
EXTCLK = 0x40
AI = 0x20  # register auto-increment
SLEEP = 0x10
SUB1, SUB2, SUB3 = 0x08, 0x04, 0x02  # answer SUBADR1..3
ALLCALL = 0x01
MODE1_RESET = SLEEP | ALLCALL  # 0x11 at power-up
# MODE2 bits
OCH = 0x08  # 0: outputs change on STOP, 1: on ACK
OUTDRV = 0x04  # totem-pole outputs (the reset value)
MODE2_RESET = OUTDRV
MODE2_WRITABLE = 0x1F  # bits 7:5 are reserved and read 0
# SUBADR1..3 and ALLCALLADR at power-up, 8-bit form (7-bit address << 1): 0x71, 0x72, 0x74, 0x70
SUBADR_RESET = (0xE2, 0xE4, 0xE8)
ALLCALLADR_RESET = 0xE0
LED_HIGH_WRITABLE = 0x1F  # LEDn_ON_H / LEDn_OFF_H bits 7:5 are reserved and read 0
# The software reset: general call address 0x00, then this one data byte.
SWRST_ADDRESS = 0x00
SWRST_BYTE = 0x06

FULL_BIT = 0x10  # bit 4 of LEDn_ON_H (full on) and of LEDn_OFF_H (full off, which wins)
COUNTS = 4096
PRESCALE_MIN, PRESCALE_MAX = 3, 255
PRESCALE_RESET = 0x1E  # 200 Hz at 25 MHz
NOMINAL_OSC_HZ = 25_000_000
# After SLEEP is cleared the oscillator needs this long before RESTART may be written.
OSCILLATOR_START_NS = 500_000
# The general call address every board answers (ALLCALL), left alone by a scan.
ALL_CALL_ADDRESS = 0x70
FIRST_ADDRESS, LAST_ADDRESS = 0x40, 0x7F  # the board's A5..A0 pins choose 0x40 + n


def led_register(channel: int) -> int:
    """LEDn_ON_L, the first of channel ``channel``'s four registers."""
    if not 0 <= channel < CHANNELS:
        raise ValueError(f"expected a channel from 0 to {CHANNELS - 1}, found {channel}")
    return LED0_ON_L + LED_STRIDE * channel


def prescale_for(osc_hz: int, rate_hz: Fraction) -> int:
    """The datasheet's prescale for ``rate_hz`` (rounded to nearest, halves up), clamped."""
    exact = Fraction(osc_hz) / (COUNTS * rate_hz)
    return min(PRESCALE_MAX, max(PRESCALE_MIN, int(exact + Fraction(1, 2)) - 1))


def period_ns(osc_hz: int, prescale: int) -> Fraction:
    """The PWM period in exact nanoseconds for a board whose oscillator runs at ``osc_hz``."""
    return Fraction(COUNTS * (prescale + 1) * NS_PER_S, osc_hz)


def tick_ns(osc_hz: int, prescale: int) -> Fraction:
    """One count of the PWM counter, in exact nanoseconds."""
    return Fraction((prescale + 1) * NS_PER_S, osc_hz)


@dataclass(frozen=True)
class LedBlock:
    """One channel's ON and OFF counts as its four registers hold them.

    ``full_off`` (no pulse at all: a hobby servo goes limp) wins over everything else.
    """

    on_count: int
    off_count: int
    full_off: bool = False

    def encode(self) -> bytes:
        """LEDn_ON_L, LEDn_ON_H, LEDn_OFF_L, LEDn_OFF_H."""
        off_high = (self.off_count >> 8) | (FULL_BIT if self.full_off else 0)
        return bytes((self.on_count & 0xFF, self.on_count >> 8, self.off_count & 0xFF, off_high))

    @classmethod
    def decode(cls, raw: bytes) -> LedBlock:
        """From the four registers (full ON is not used by pinarray and reads as a pulse)."""
        on_low, on_high, off_low, off_high = raw
        return cls((on_high & 0x0F) << 8 | on_low, (off_high & 0x0F) << 8 | off_low,
                   bool(off_high & FULL_BIT))

    @classmethod
    def pulse(cls, on_count: int, width_counts: int) -> LedBlock:
        """A pulse ``width_counts`` long that starts at ``on_count`` (wrapping past 4095)."""
        if not 0 <= on_count < COUNTS or not 0 < width_counts < COUNTS:
            raise ValueError(f"expected a pulse within one period, found ON {on_count}, "
                             f"width {width_counts} counts")
        return cls(on_count, (on_count + width_counts) % COUNTS)


FULL_OFF = LedBlock(0, 0, full_off=True)
