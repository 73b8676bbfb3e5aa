"""One owner per port: an array holds its serial device (or I2C bus) so that no other opener,
in this process or another, drives the same servos.

The lock is the kernel's (``flock``, as pyserial's ``exclusive=True`` takes it) on a descriptor
of the device kept open for as long as the array is: it is gone the moment its holder's
descriptors close, however the holder ends (killed outright included), so a lock is never
left behind. The player process inherits the descriptor, so the port stays held until the
last process that drives it (the one resting the pins) has ended. A refusal names the holder:
an array of this process by what it was opened for, another process by its id and command
line (read from ``/proc``).

A pyserial URL that wraps a device of this machine (``spy:///dev/ttyUSB0?file=log``,
``alt:///dev/ttyUSB0?class=...``) holds that device; ``hwgrep://``, which picks a device by a
pattern only as it opens it, is refused (name the device). A port that is not a file (a
network URL such as ``rfc2217://``, a ``sim://`` URL) is not locked: nothing else can open the
same thing by its path.

A forked copy of the holder (a lab's ``multiprocessing`` workers) lets go of the lock at once:
the port is held by the process that opened the array and its player process, not by copies
that outlive them.
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
# pyserial URL handlers that open a device of this machine given by its path.
WRAPPING_URLS = ("spy://", "alt://")


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
    """The real path of the device ``port`` opens, the same whichever link or pyserial URL
    names it (``/dev/serial/by-id/...``, ``spy:///dev/ttyUSB0``); None for what is not a
    file."""
    for scheme in WRAPPING_URLS:
        if port.startswith(scheme):
            port = port[len(scheme):].split("?", 1)[0]
            break
    else:
        if port.startswith("hwgrep://"):
            raise BusError(f"{port}: hwgrep:// picks a serial port by a pattern as it opens it, "
                           "so it cannot be held for one owner first: give the device itself "
                           "(pinarray.find_servo_ports lists those where servos answer)")
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
            raise PortInUse(f"{port} is in use by {_lock_holders(key)}: one owner per port; "
                            "close it there first") from None
        _held[key] = _Holding(fd, holder)
        return PortLock(key, fd)


def _lock_holders(key: str) -> str:
    """Who holds the lock on ``key``, in words, as far as /proc shows it: the processes with a
    descriptor of it that carries the lock (not every program that merely has the device
    open), a player process named as its script's."""
    me = os.getpid()
    try:
        pids = sorted(int(entry.name) for entry in PROC.iterdir() if entry.name.isdigit())
    except OSError:
        pids = []
    holders = [pid for pid in pids if pid != me and _holds_lock(pid, key)]
    players = {pid: _parent(pid) for pid in holders if _is_player(pid)}
    named = []
    for pid in holders:
        if pid in players:
            if players[pid] not in holders:  # its script has ended: it is resting the pins
                named.append(f"the player process {pid} of a script that has ended (it is "
                             "putting the pins to rest; the port is free once it has)")
            continue
        its_players = [player for player, parent in players.items() if parent == pid]
        player = f" and its player process {its_players[0]}" if its_players else ""
        named.append(f"process {pid} ({_command(pid)}){player}")
    if not named:
        return "another process (not one this user can name)"
    return " and ".join(named)


def _holds_lock(pid: int, key: str) -> bool:
    """Whether process ``pid`` has a descriptor of ``key`` that carries a lock (its fdinfo
    lists it)."""
    fds = PROC / str(pid) / "fd"
    try:
        entries = list(fds.iterdir())
    except OSError:
        return False  # gone, or another user's
    for entry in entries:
        try:
            if os.readlink(entry) != key:
                continue
            info = (PROC / str(pid) / "fdinfo" / entry.name).read_text()
        except OSError:
            continue
        if any(line.startswith("lock:") for line in info.splitlines()):
            return True
    return False


def _is_player(pid: int) -> bool:
    return "pinarray.player.child" in _command(pid)


def _parent(pid: int) -> int | None:
    try:
        stat = (PROC / str(pid) / "stat").read_bytes()
    except OSError:
        return None
    return int(stat[stat.rfind(b")") + 2:].split()[1])


def _command(pid: int) -> str:
    try:
        raw = (PROC / str(pid) / "cmdline").read_bytes()
    except OSError:
        return "?"
    words = [word.decode(errors="replace") for word in raw.split(b"\0") if word]
    text = " ".join(words) or "?"
    return text if len(text) <= 120 else text[:117] + "..."


def blank_descriptors(*fds: int) -> None:
    """Point each descriptor at ``/dev/null`` (negative ones are skipped): what it held is let
    go (a lock, a port, a channel), and the number stays taken, so that a later close by its
    old owner closes nothing of anyone else's."""
    devnull = os.open(os.devnull, os.O_RDWR | os.O_CLOEXEC)
    try:
        for fd in fds:
            if fd >= 0:
                try:
                    os.dup2(devnull, fd, inheritable=False)
                except OSError:
                    pass  # closed already
    finally:
        os.close(devnull)


def _let_go_in_forked_child() -> None:
    """A forked copy of this process holds no port (the original and its player do)."""
    global _held_lock
    _held_lock = threading.Lock()  # another thread may have held it as the process forked
    holdings = list(_held.values())
    _held.clear()
    blank_descriptors(*(holding.fd for holding in holdings))


os.register_at_fork(after_in_child=_let_go_in_forked_child)
