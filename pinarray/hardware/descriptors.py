"""Waits on a descriptor that hold for any descriptor number.

select has microseconds in its timeout, which a player's reads need (poll rounds its wait up to
whole milliseconds, and a read must not overrun the next frame's deadline by that), but watches
only descriptors below ``FD_SETSIZE``. A host program holding more than 1024 open files (a
lab's script with many of them open) hands the port and the player's channel higher numbers:
those are polled, their waits rounded up to the next millisecond, rather than refused.
"""

from __future__ import annotations

import os
import select

from pinarray.units import NS_PER_MS

SELECT_LIMIT = 1024  # FD_SETSIZE: select watches only descriptors below it


def readable(fd: int, timeout_ns: int) -> bool:
    """Whether ``fd`` has something to read (or has failed), waiting up to ``timeout_ns``."""
    return _ready(fd, timeout_ns, select.POLLIN)


def writable(fd: int, timeout_ns: int) -> bool:
    """Whether ``fd`` takes data (or has failed), waiting up to ``timeout_ns``."""
    return _ready(fd, timeout_ns, select.POLLOUT)


def _ready(fd: int, timeout_ns: int, event: int) -> bool:
    timeout_ns = max(0, timeout_ns)
    if fd < SELECT_LIMIT:
        watched = [fd]
        reading, writing, _ = select.select(watched if event == select.POLLIN else [],
                                            watched if event == select.POLLOUT else [], [],
                                            timeout_ns / 1e9)
        return bool(reading or writing)
    poller = select.poll()
    poller.register(fd, event)
    return bool(poller.poll(-(-timeout_ns // NS_PER_MS)))


def below_select_limit(fd: int) -> int:
    """``fd``, or a copy of it select can watch if it cannot: a parent holding more than 1024
    descriptors passes its own numbers to a child (``pass_fds`` keeps them), and the child,
    which holds a few, has low ones free. The original is closed; the copy shares its open
    file (and a port's ``flock``)."""
    if fd < SELECT_LIMIT:
        return fd
    low = os.dup(fd)
    os.close(fd)
    return low
