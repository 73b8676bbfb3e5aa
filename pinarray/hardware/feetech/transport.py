"""One place that decides between hardware and simulation: `open_bus(url)`.

``url`` is either a serial device (``/dev/ttyUSB0``, ``COM3``, or any pyserial URL such as
``spy:///dev/ttyUSB0``) or a simulated bus ``sim://?ids=1-16&...`` (grammar in
`pinarray.hardware.feetech.faults`). Both end up as a `FeetechBus` over a `Link`; only what is
under it differs: the device's file descriptor, or the in-process simulator at the level its
URL asks for (`pinarray.hardware.feetech.sim_levels`: its pyserial look-alike at the wire
level, exchanges computed whole at the packet level, the default).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from pinarray.clock import Clock, MonotonicClock, VirtualClock
from pinarray.errors import BusError
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.faults import is_sim_url, parse_sim_url
from pinarray.hardware.feetech.link import FdWire, Latency, Link, PolledWire, Wire
from pinarray.hardware.feetech.sim_levels import IN_PROCESS_DEFAULT, Fidelity

if TYPE_CHECKING:
    from pinarray.hardware.feetech.feetech import FeetechBus
    from pinarray.hardware.feetech.sim import SimBus

SYSFS_USB_SERIAL = Path("/sys/bus/usb-serial/devices")


def latency_timer_ms(device: str, sysfs: Path = SYSFS_USB_SERIAL) -> int | None:
    """The USB-serial latency timer of ``device`` in ms (Linux), or None if not applicable."""
    if not sys.platform.startswith("linux"):
        return None
    tty = Path(os.path.realpath(device)).name  # /dev/serial/by-id/... links to ttyUSB0
    path = sysfs / tty / "latency_timer"
    try:
        return int(path.read_text().strip())
    except (OSError, ValueError):
        return None


def latency_warning(device: str, sysfs: Path = SYSFS_USB_SERIAL) -> str | None:
    """A how-to-fix message when the adapter's latency timer is above 1 ms."""
    timer_ms = latency_timer_ms(device, sysfs)
    if timer_ms is None or timer_ms <= 1:
        return None
    tty = Path(os.path.realpath(device)).name
    path = sysfs / tty / "latency_timer"
    return (
        f"{device}: USB latency timer is {timer_ms} ms (above 1 ms), so every servo read "
        f"waits up to {timer_ms} ms; fix it with `echo 1 | sudo tee {path}` (lasts until "
        "unplugged), or permanently with a udev rule: ACTION==\"add\", SUBSYSTEM==\"usb-serial\", "
        "DRIVER==\"ftdi_sio\", ATTR{latency_timer}=\"1\""
    )


def open_bus(
    url: str,
    setup: BusSetup | None = None,
    clock: Clock | None = None,
    baud_rate: int = 1_000_000,
    retries: int = 3,
    sim: SimBus | None = None,
) -> FeetechBus:
    """Open a real or simulated servo bus and, given a `BusSetup`, run the handshake.

    Parameters
    ----------
    url : str
        A serial device path / pyserial URL, or ``sim://?...``.
    setup : BusSetup, optional
        Servos to expect; when given, `FeetechBus.connect` checks them and enables torque.
    clock : Clock, optional
        Defaults to a `VirtualClock` for ``sim://`` and a `MonotonicClock` for hardware.
    baud_rate : int
        Wire speed in bit/s (a ``baud=`` key in a sim URL wins).
    retries : int
        Extra attempts after a transient failure.
    sim : SimBus, optional
        For a ``sim://`` URL: the simulated servos an earlier connection to it left (they
        keep their tables, as real servos do); None: new ones, as the URL says.

    Returns
    -------
    FeetechBus
        Connected bus; ``.sim`` holds the `SimBus` for a simulated one. Call
        ``rest_and_release()`` and ``close()`` when done.
    """
    from pinarray.hardware.feetech.feetech import FeetechBus

    warnings: list[str] = []
    if is_sim_url(url):
        bus = _open_simulated(url, clock, baud_rate, retries, sim)
    else:
        clock = clock or MonotonicClock()
        wire = _open_device(url, baud_rate, clock)
        latency = Latency(timer_ms=latency_timer_ms(url))
        if (message := latency_warning(url)) is not None:
            warnings.append(message)
        bus = FeetechBus(Link(wire, clock, baud_rate, latency), clock, retries=retries)
    bus.warnings.extend(warnings)
    if setup is not None:
        try:
            bus.connect(setup)
        except BaseException:
            bus.close()
            raise
    return bus


def _open_simulated(url: str, clock: Clock | None, baud_rate: int, retries: int,
                    sim: SimBus | None) -> FeetechBus:
    """The in-process simulator for a ``sim://`` URL, at the level it asks for (the packet
    level unless it says: `pinarray.hardware.feetech.sim_levels`)."""
    from pinarray.hardware.feetech.feetech import FeetechBus
    from pinarray.hardware.feetech.sim import SimBus, SimSerial

    config = parse_sim_url(url)
    clock = clock or VirtualClock()
    baud_rate = config.baud_rate or baud_rate
    if sim is None:
        sim = SimBus(config, clock)
    else:
        sim.reopen(clock)
    port = SimSerial(sim, clock, baud_rate, port=url)
    latency = Latency(timer_ms=0, learns=False)  # no adapter: nothing to learn
    level = config.fidelity or IN_PROCESS_DEFAULT
    if level is Fidelity.WIRE:
        bus = FeetechBus(Link(PolledWire(port, clock, url), clock, baud_rate, latency), clock,
                         retries=retries)
    else:
        from pinarray.hardware.feetech.sim_packet import PacketLink

        link = PacketLink(port, clock, baud_rate, latency, url)
        if level is Fidelity.MOTION:
            from pinarray.hardware.feetech.sim_samples import MotionLevelBus

            bus = MotionLevelBus(link, clock, sim, retries=retries)
        else:
            bus = FeetechBus(link, clock, retries=retries)
    bus.sim = sim
    return bus


def fidelity_of(bus: FeetechBus) -> Fidelity | None:
    """The level a bus is simulated at (None: real servos, or a pseudo-terminal's)."""
    if bus.sim is None:
        return None
    from pinarray.hardware.feetech.sim_packet import PacketLink
    from pinarray.hardware.feetech.sim_samples import MotionLevelBus

    if isinstance(bus, MotionLevelBus):
        return Fidelity.MOTION
    return Fidelity.PACKET if isinstance(bus.link, PacketLink) else Fidelity.WIRE


def _why_not_opened(exc: Exception) -> str:
    """Why a port did not open, once: pyserial's words repeat the errno and the path
    ("[Errno 2] could not open port X: [Errno 2] No such file or directory: 'X'")."""
    import errno
    import os

    number = getattr(exc, "errno", None)
    if number == errno.ENOENT:
        return "no such device (is the adapter plugged in?)"
    if number == errno.EACCES:
        return ("permission denied (add your user to the group that owns the port, e.g. "
                "dialout: sudo usermod -aG dialout $USER, then log in again)")
    return os.strerror(number) if isinstance(number, int) else str(exc)


def _open_device(url: str, baud_rate: int, clock: Clock) -> Wire:
    """A wire over a serial device: its file descriptor when it has one, else polled."""
    import serial

    try:
        port = serial.serial_for_url(url, baudrate=baud_rate, timeout=0)
    except (OSError, ValueError) as exc:  # serial.SerialException is an OSError
        raise BusError(f"cannot open servo port {url}: {_why_not_opened(exc)}") from None
    try:
        fd = port.fileno()
    except (AttributeError, OSError, ValueError):
        return PolledWire(port, clock, url)  # a pyserial URL handler with no descriptor
    try:
        port.reset_input_buffer()
    except OSError:
        pass
    return FdWire(fd, clock, url, on_close=port.close)
