"""Real PCA9685 boards through Linux i2c-dev, with ``smbus2``: the one module that imports it.

Every message is one ``I2C_RDWR`` ioctl (``SMBus.i2c_rdwr``), so a register-pointer write and
the read after it are one transaction with a repeated START, as the datasheet's Fig 22 reads.
The kernel's answer is mapped to what the driver can act on:

``ENXIO``, ``EREMOTEIO``            a byte was not acknowledged: `I2cNack` naming the address
``ETIMEDOUT``, ``EAGAIN``           the bus is stuck (SDA held low, lost arbitration): BusError
``ENODEV``, ``ENOENT``, ``EIO``     the adapter is gone (USB unplugged): `PortLost`

i2c-dev does not say which byte of a refused write was refused, so a refused write is logged
with every byte the host sent. A message's ``stop_ns`` is the clock's time when the ioctl
returned.
"""

from __future__ import annotations

import errno
import math

from smbus2 import SMBus, i2c_msg

from pinarray.clock import Clock
from pinarray.errors import BusError
from pinarray.hardware.driver import PortLost
from pinarray.hardware.pca9685.i2c import I2cMessage, I2cNack, Listener
from pinarray.units import NS_PER_S

DEFAULT_BUS_HZ = 400_000  # the usual i2c-dev default; the kernel, not us, sets it
_NACK = {errno.ENXIO, errno.EREMOTEIO}
_STUCK = {errno.ETIMEDOUT, errno.EAGAIN}
_GONE = {errno.ENODEV, errno.ENOENT, errno.EIO}


class SmbusLink:
    """An `I2cLink` over a Linux i2c-dev bus (``/dev/i2c-1``, a bus number, or an open fd)."""

    listener: Listener | None

    def __init__(self, path_or_fd: str | int, clock: Clock, bus_hz: int = DEFAULT_BUS_HZ,
                 fd: bool = False):
        """Open the bus: ``path_or_fd`` is a path or bus number, or with ``fd`` an inherited
        file descriptor (a player process's)."""
        self._clock = clock
        self._bus_hz = bus_hz
        self.listener = None
        self._name = f"fd {path_or_fd}" if fd else str(path_or_fd)
        try:
            if fd:
                self._bus = SMBus()
                self._bus.fd = int(path_or_fd)
            else:
                self._bus = SMBus(path_or_fd)
        except OSError as error:
            raise BusError(f"cannot open the I2C bus {self._name}: "
                           f"{error.strerror or error}") from None

    @property
    def name(self) -> str:
        return self._name

    @property
    def descriptor(self) -> int | None:
        fd = self._bus.fd
        return int(fd) if fd is not None else None

    @property
    def bus_hz(self) -> int:
        return self._bus_hz

    def message_ns(self, data_bytes: int) -> int:
        return math.ceil((1 + 9 * (1 + data_bytes) + 1) * NS_PER_S / self._bus_hz)

    def write(self, address: int, data: bytes) -> I2cMessage:
        try:
            self._bus.i2c_rdwr(i2c_msg.write(address, data))
        except OSError as error:
            self._failed(error, address, [I2cMessage(address, False, data, False,
                                                     self._clock.now_ns())])
        message = I2cMessage(address, False, data, True, self._clock.now_ns())
        self._hear(message)
        return message

    def write_read(self, address: int, data: bytes, count: int) -> bytes:
        read = i2c_msg.read(address, count)
        try:
            self._bus.i2c_rdwr(i2c_msg.write(address, data), read)
        except OSError as error:
            self._failed(error, address, [I2cMessage(address, False, data, False,
                                                     self._clock.now_ns())])
        stop_ns = self._clock.now_ns()
        answer = bytes(read)
        self._hear(I2cMessage(address, False, data, True, stop_ns - self.message_ns(count)))
        self._hear(I2cMessage(address, True, answer, True, stop_ns))
        return answer

    def close(self) -> None:
        try:
            self._bus.close()
        except OSError:
            pass  # closing a bus whose adapter is gone: nothing left to release

    def _failed(self, error: OSError, address: int, heard: list[I2cMessage]) -> None:
        for message in heard:
            self._hear(message)
        code = error.errno
        if code in _NACK:
            raise I2cNack(f"{self._name}: board 0x{address:02x} did not acknowledge", address)
        if code in _STUCK:
            raise BusError(f"{self._name}: bus stuck talking to board 0x{address:02x} "
                           f"({error.strerror or error})")
        if code in _GONE:
            raise PortLost(f"{self._name}: the I2C adapter is gone ({error.strerror or error})")
        raise BusError(f"{self._name}: talking to board 0x{address:02x} failed: "
                       f"{error.strerror or error}")

    def _hear(self, message: I2cMessage) -> None:
        if self.listener is not None:
            self.listener(message)
