"""Which serial port is the array? The ports on this machine where bus servos answer.

A script, or a host program such as PsychoPy's device manager, asks before it opens an array:
each port is sent one broadcast PING, and where something answers, every servo id is pinged
in turn (as ``pinarray servos scan`` does). Nothing but PINGs and register reads is sent:
torque and goals stay as they were.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pinarray.api import arguments
from pinarray.errors import BusError
from pinarray.hardware.feetech.bringup import sweep_timeout_ns
from pinarray.hardware.feetech.scan import scan
from pinarray.hardware.feetech.transport import is_sim_url, open_bus
from pinarray.hardware.port_lock import hold_port

__all__ = ["ServoPort", "find_servo_ports"]


@dataclass(frozen=True)
class ServoPort:
    """A serial port on which Feetech STS bus servos answer.

    Attributes
    ----------
    port : str
        The serial device (``/dev/ttyUSB0``), or the ``sim://`` URL that was asked about:
        what `open_array` takes as ``port`` (or ``sim``).
    description : str
        What the system says the device is (a USB adapter's product name); empty when it
        says nothing, as for a ``sim://`` URL.
    servo_ids : tuple of int
        The ids of the servos that answered, in rising order.
    """

    port: str
    description: str
    servo_ids: tuple[int, ...]


def find_servo_ports(ports: Sequence[str] | None = None) -> tuple[ServoPort, ...]:
    """The serial ports on which bus servos answer, each with the ids that answered.

    Each port is opened at 1 Mbit/s (the servos' factory rate) and sent one broadcast PING. A
    port where nothing answers is closed at once; where something does (a whole array's
    answers collide: several servos share one return delay), every id from 0 to 252 is
    pinged in turn, waiting a few milliseconds for each. A port that cannot be opened (held
    by an array, in use, no permission, gone) or that stops answering is left out: a port an
    array holds is never sent anything. Ask only about ports no other program is using: a
    PING sent to another device is a few stray bytes to it.

    Parameters
    ----------
    ports : sequence of str or None
        Serial devices (``/dev/ttyUSB0``) or ``sim://`` URLs (``sim://?missing=3`` answers
        without servo 3); None: every serial port the system lists.

    Returns
    -------
    tuple of ServoPort
        The ports where at least one servo answered, in the order asked.
    """
    from serial.tools.list_ports import comports

    ports = arguments.port_list("find_servo_ports", ports)
    listed = {info.device: info.description for info in comports()}
    if ports is None:
        ports = sorted(listed)
    found = []
    for port in ports:
        servo_ids = _answering_ids(port)
        if servo_ids:
            description = "" if is_sim_url(port) else listed.get(port, "")
            found.append(ServoPort(port, "" if description == "n/a" else description, servo_ids))
    return tuple(found)


def _answering_ids(port: str) -> tuple[int, ...]:
    """The ids that answer on ``port``; none where it cannot be opened or asked."""
    try:
        held = hold_port(port, "pinarray.find_servo_ports")  # held while asked
    except BusError:
        return ()  # an array drives it (PortInUse), or it cannot be held: not a byte from here
    try:
        bus = open_bus(port)
    except BusError:
        held.release()
        return ()
    try:
        ping = bus.broadcast_ping()
        if not ping.servo_ids and not ping.garbled_bytes:
            return ()
        return scan(bus, timeout_ns=sweep_timeout_ns(bus)).servo_ids
    except BusError:  # the port stopped answering (an adapter pulled out while asked)
        return ()
    finally:
        bus.close()
        held.release()
