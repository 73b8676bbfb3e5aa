"""The socket between a parent and its player process: pickled messages, each after its length.

``multiprocessing.connection.Connection`` carried them before; importing it loads the whole
``multiprocessing`` package (and ``tempfile``, ``random``, ``subprocess`` with it): some 40 ms
of processor at every start of a player process, one per array opened, for a few lines of
framing. Both ends are this module, so the framing is ours: an 8-byte big-endian length, then
the message's pickle.

Errors are a closed connection's: `EOFError` when the other end has closed (at a message's
start or within it), `OSError` when this end is closed or the socket fails.

Either end may set its descriptor not to block: a write that the other end takes nothing of,
or a read whose message stops coming part way, then calls its ``while_blocked`` every
`BLOCKED_LOOK_S` (the parent looks there at a child that may be frozen: a message bigger than
the socket's buffer would otherwise wait on it for ever, either way).
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import struct
from collections.abc import Callable

_LENGTH = struct.Struct("!Q")
BLOCKED_LOOK_S = 0.05  # how often a blocked write looks at why (``while_blocked``)
_PIPE = {signal.SIGPIPE}


class Channel:
    """Pickled messages over the stream socket (or pipe) descriptor ``fd``, owned from here:
    `close` (or the channel being collected) closes it."""

    def __init__(self, fd: int):
        self._fd = fd
        # From the start of a message's send (receipt) to its end: one an exception cut short
        # (KeyboardInterrupt) leaves that way of the stream mid-message, of no more use.
        self._sending = self._receiving = False

    @property
    def midway(self) -> bool:
        """Whether a message's send or receipt began and did not end (see ``__init__``)."""
        return self._sending or self._receiving

    @property
    def closed(self) -> bool:
        return self._fd < 0

    def fileno(self) -> int:
        if self._fd < 0:
            raise OSError("the channel is closed")
        return self._fd

    def send(self, message: object, while_blocked: Callable[[], None] | None = None) -> None:
        """``message`` whole: its length and its pickle, written until every byte is.

        On a descriptor that does not block, ``while_blocked`` is called each `BLOCKED_LOOK_S`
        the other end takes nothing; what it raises ends the send (the message cut short: the
        channel is then of no more use)."""
        body = pickle.dumps(message, pickle.HIGHEST_PROTOCOL)
        data = memoryview(_LENGTH.pack(len(body)) + body)
        fd = self.fileno()
        self._sending = True
        while data:
            try:
                data = data[_write(fd, data):]
            except BlockingIOError:
                if not _polled([fd], select.POLLOUT, BLOCKED_LOOK_S) and while_blocked is not None:
                    while_blocked()
        self._sending = False

    def recv(self, while_blocked: Callable[[], None] | None = None) -> object:
        """The next message, once it has come whole.

        On a descriptor that does not block, ``while_blocked`` is called each `BLOCKED_LOOK_S`
        nothing more of it comes; what it raises ends the read (the channel is then of no more
        use)."""
        self._receiving = True
        (length,) = _LENGTH.unpack(self._read(_LENGTH.size, while_blocked))
        body = self._read(length, while_blocked)
        self._receiving = False
        return pickle.loads(body)

    def _read(self, count: int, while_blocked: Callable[[], None] | None) -> bytes:
        fd = self.fileno()
        chunks = []
        while count:
            try:
                chunk = os.read(fd, count)
            except BlockingIOError:  # the rest of the message is on its way, or stuck
                if not _polled([fd], select.POLLIN, BLOCKED_LOOK_S) and while_blocked is not None:
                    while_blocked()
                continue
            if not chunk:
                raise EOFError("the other end of the channel closed")
            chunks.append(chunk)
            count -= len(chunk)
        return b"".join(chunks)

    def hung_up(self) -> bool:
        """Whether the other end has gone (the socket hung up or failed), as poll shows it now."""
        poller = select.poll()
        poller.register(self.fileno(), select.POLLIN)
        gone = select.POLLHUP | select.POLLERR | select.POLLNVAL
        return any(events & gone for _, events in poller.poll(0))

    def close(self) -> None:
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            os.close(fd)

    def __del__(self) -> None:
        self.close()


def _write(fd: int, data: memoryview) -> int:
    """`os.write`, but an end that has gone is `BrokenPipeError` only, never SIGPIPE as well:
    a host program may have set SIGPIPE back to its default, which ends the process there,
    before anything could make the pins safe (and the player process takes it for a stop)."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _PIPE)
    try:
        return os.write(fd, data)
    except BrokenPipeError:
        if signal.SIGPIPE not in blocked and signal.SIGPIPE in signal.sigpending():
            signal.sigwait(_PIPE)  # this write's own: taken now, never delivered
        raise
    finally:
        if signal.SIGPIPE not in blocked:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def readable(fds: list[int], timeout_s: float | None) -> list[int]:
    """Those of ``fds`` that can be read without blocking (or have hung up or failed), waiting
    up to ``timeout_s`` for one (None: no limit). Through poll, not select: a host program's
    descriptors may number past select's 1024."""
    return _polled(fds, select.POLLIN, timeout_s)


def _polled(fds: list[int], event: int, timeout_s: float | None) -> list[int]:
    poller = select.poll()
    for fd in fds:
        poller.register(fd, event)
    timeout_ms = None if timeout_s is None else max(0, int(timeout_s * 1000 + 0.999))
    return [fd for fd, _ in poller.poll(timeout_ms)]
