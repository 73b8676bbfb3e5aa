"""I2C as a PCA9685 board is spoken to: messages, the link that carries them, and their log.

A message is what a logic analyser decodes between a START (or repeated START) and the next:
an address, read or write, the bytes after the address byte, and whether every byte was
acknowledged. `I2cLink` is the port: Linux i2c-dev through ``smbus2`` for real boards
(`pinarray.hardware.pca9685.smbus_link`), or the simulated board
(`pinarray.hardware.pca9685.sim`). Every message a link carries is handed to its
``listener`` (the ``--i2c-log`` file, the driver's counters).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from pinarray.errors import BusError


@dataclass(frozen=True)
class I2cMessage:
    """One message on the bus.

    Attributes
    ----------
    address : int
        The 7-bit address.
    read : bool
        A read (the board's bytes follow the address) or a write.
    data : bytes
        The bytes after the address byte: written by the host, or read from the board (up to
        the first byte not acknowledged, for a write that was refused).
    acked : bool
        Every byte of the message was acknowledged (for a read: the address was).
    stop_ns : int
        Clock time, in ns, when the message ended (its STOP, or the repeated START that
        follows it).
    """

    address: int
    read: bool
    data: bytes
    acked: bool
    stop_ns: int

    def log_line(self, onset_ns: int) -> str:
        """``t_ns addr rw data_hex ack``, t_ns from ``onset_ns``."""
        return (f"{self.stop_ns - onset_ns} 0x{self.address:02x} {'r' if self.read else 'w'} "
                f"{self.data.hex()} {'ack' if self.acked else 'nack'}")


class I2cNack(BusError):
    """A board did not acknowledge its address or a byte: absent, powered off or busy."""

    def __init__(self, message: str, address: int):
        super().__init__(message)
        self.address = address


Listener = Callable[[I2cMessage], None]


class MessageLog(Protocol):
    """Where a driver's messages go as a logic analyser would show them (``--i2c-log``)."""

    def __call__(self, message: I2cMessage) -> None: ...

    def trial_onset(self, onset_ns: int) -> None:
        """A trial's onset on the player's clock: its messages are timed from it."""
        ...

    def trial_end(self) -> None:
        """What was written so far goes to disk."""
        ...

    def close(self) -> None: ...


class I2cLink(Protocol):
    """An I2C bus master: real (i2c-dev) or simulated."""

    listener: Listener | None

    @property
    def name(self) -> str:
        """The bus as the lab names it (``/dev/i2c-1``, ``sim://pca9685?...``)."""
        ...

    @property
    def descriptor(self) -> int | None:
        """The bus's file descriptor, which a player process can inherit (None: none)."""
        ...

    @property
    def bus_hz(self) -> int:
        """The SCL clock rate, bit/s."""
        ...

    def write(self, address: int, data: bytes) -> I2cMessage:
        """One write message (START, address+W, ``data``, STOP); returns it as carried.

        Raises `I2cNack` when a byte is not acknowledged (the message is heard by the
        listener first) and `pinarray.hardware.driver.PortLost` when the adapter is gone.
        """
        ...

    def write_read(self, address: int, data: bytes, count: int) -> bytes:
        """A write of ``data`` (the register pointer), a repeated START and a read of ``count``
        bytes, in one transaction (two messages)."""
        ...

    def message_ns(self, data_bytes: int) -> int:
        """How long a message with that many bytes after its address takes on the bus."""
        ...

    def close(self) -> None: ...
