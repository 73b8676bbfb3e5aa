"""One owner per port: an array holds its serial device (or I2C bus) so that no other opener,
in this process or another, drives the same servos.

The lock is the kernel's (``flock``, as pyserial's ``exclusive=True`` takes it) on a descriptor
of the device kept open for as long as the array is: it is gone the moment its holder's
descriptors close, however the holder ends (killed outright included), so a lock is never
left behind. The player process inherits the descriptor, so the port stays held until the
last process that drives it (the one resting the pins) has ended. A refusal names the holder:
an array of this process by what it was opened for, another process by its id and command
line (read from ``/proc``).

A port that is not a file (a pyserial URL such as ``rfc2217://``, a ``sim://`` URL) is not
locked: nothing else can open the same thing by its path.
"""

from __future__ import annotations

import fcntl
import os
import threading
from dataclasses import dataclass
from pathlib import Path

from pinarray.errors import BusError

__all__ = ["PortInUse", "PortLock", "hold_port"]

PROC = Path("/proc")


class PortInUse(BusError):
    """The port is held by another array (of this script, or of another process): the
    message names the holder."""


@dataclass(frozen=True)
class _Holding:
    """One port held by this process: the lock's descriptor and who holds it, in words."""

    fd: int
    holder: str


_held: dict[str, _Holding] = {}  # the port's real path -> this process's holding
_held_lock = threading.Lock()


class PortLock:
    """A port held by this process until `release` (or until the process ends).

    ``fd`` is the descriptor the lock lives on (-1 for a port that is not a file): a player
    process given it keeps the port held while it drives the servos.
    """

    def __init__(self, key: str, fd: int) -> None:
        self._key = key
        self.fd = fd

    def release(self) -> None:
        """Let other openers have the port (safe to call more than once)."""
        with _held_lock:
            holding = _held.get(self._key)
            if holding is not None and holding.fd == self.fd:
                del _held[self._key]
        if self.fd >= 0:
            try:
                os.close(self.fd)
            except OSError:
                pass
            self.fd = -1


def _key(port: str) -> str | None:
    """The port's real path, the same whichever link names it (``/dev/serial/by-id/...``);
    None for what is not a file."""
    if "://" in port:
        return None
    path = os.path.realpath(port)
    return path if os.path.exists(path) else None


def hold_port(port: str, holder: str) -> PortLock:
    """Hold ``port`` for ``holder`` (who holds it, in words: "an array for protocol 'x'").

    Raises
    ------
    PortInUse
        Another array holds it, in this process or another; the message names the holder.
    """
    key = _key(port)
    if key is None:
        return PortLock("", -1)
    with _held_lock:
        holding = _held.get(key)
        if holding is not None:
            raise PortInUse(f"{port} is in use by {holding.holder} in this process: close it "
                            "first (one owner per port)")
        try:
            fd = os.open(key, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError:
            # Not ours to open (no permission, gone): the opener says why in its own words.
            return PortLock("", -1)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise PortInUse(f"{port} is in use by {_other_holders(key)}: one owner per port; "
                            "close it there first") from None
        _held[key] = _Holding(fd, holder)
        return PortLock(key, fd)


def _other_holders(key: str) -> str:
    """The processes with ``key`` open, by id and command line, as far as /proc shows them."""
    found = []
    me = os.getpid()
    try:
        pids = [int(entry.name) for entry in PROC.iterdir() if entry.name.isdigit()]
    except OSError:
        pids = []
    for pid in sorted(pids):
        if pid == me:
            continue
        try:
            links = [os.readlink(fd) for fd in (PROC / str(pid) / "fd").iterdir()]
        except OSError:
            continue  # gone, or another user's
        if key in links:
            found.append(f"process {pid} ({_command(pid)})")
    if not found:
        return "another process (not one this user can name)"
    return " and ".join(found)


def _command(pid: int) -> str:
    try:
        raw = (PROC / str(pid) / "cmdline").read_bytes()
    except OSError:
        return "?"
    words = [word.decode(errors="replace") for word in raw.split(b"\0") if word]
    text = " ".join(words) or "?"
    return text if len(text) <= 120 else text[:117] + "..."
