"""Bring-up of PCA9685 boards: which answer on a bus, and in what state. Reads only."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from pinarray.hardware.pca9685.i2c import I2cLink, I2cNack
from pinarray.hardware.pca9685.registers import (
    ALL_CALL_ADDRESS,
    COUNTS,
    FIRST_ADDRESS,
    LAST_ADDRESS,
    MODE1,
    NOMINAL_OSC_HZ,
    PRE_SCALE,
    SLEEP,
)


@dataclass(frozen=True)
class BoardFound:
    """A board that answered: its address, MODE1 and PRE_SCALE as read."""

    address: int
    mode1: int
    prescale: int

    @property
    def asleep(self) -> bool:
        return bool(self.mode1 & SLEEP)

    @property
    def nominal_rate_hz(self) -> Fraction:
        """The PWM rate its prescale gives at the nominal 25 MHz."""
        return Fraction(NOMINAL_OSC_HZ, COUNTS * (self.prescale + 1))

    def describe(self) -> str:
        state = "asleep (no pulses)" if self.asleep else "running"
        return (f"0x{self.address:02x}: PCA9685 answers, MODE1 0x{self.mode1:02x} {state}, "
                f"prescale {self.prescale} ({float(self.nominal_rate_hz):.1f} Hz at 25 MHz)")


def scan(link: I2cLink) -> tuple[BoardFound, ...]:
    """Every address 0x40-0x7f but the all-call 0x70 that acknowledges a read of MODE1."""
    found = []
    for address in range(FIRST_ADDRESS, LAST_ADDRESS + 1):
        if address == ALL_CALL_ADDRESS:
            continue
        try:
            mode1 = link.write_read(address, bytes([MODE1]), 1)[0]
            prescale = link.write_read(address, bytes([PRE_SCALE]), 1)[0]
        except I2cNack:
            continue
        found.append(BoardFound(address, mode1, prescale))
    return tuple(found)
