"""Holding Ctrl-C and SIGTERM back while something must not be cut in half.

A pin's safe stop (rest, then torque off) and a results row (beh.tsv, then events.tsv) are
each finished before a pending signal is delivered; the signal then arrives as usual.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_HELD = {signal.SIGINT, signal.SIGTERM}


@contextmanager
def deferred_signals() -> Iterator[None]:
    """Inside the block, SIGINT and SIGTERM wait; outside any main thread this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        # Python runs signal handlers in the main thread only: this thread is never interrupted.
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
