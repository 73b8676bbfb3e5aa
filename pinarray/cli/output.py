"""Writing to the person at the terminal, when there still is one."""

from __future__ import annotations

import os
import sys


def say(text: str, *, error: bool = False) -> None:
    """Print a line to stdout (or stderr), unless the terminal or pipe is gone.

    A closed terminal (SIGHUP) or a reader that went away (``| head``) must not turn a clean
    stop into a crash: the signal that came with it has already asked the run to stop.
    """
    stream = sys.stderr if error else sys.stdout
    try:
        print(text, file=stream, flush=True)
    except OSError:
        # What the stream still holds would fail again as the interpreter flushes it on its
        # way out (exit status 120, "Exception ignored"): written where nobody reads instead.
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())
        except (OSError, ValueError):
            pass
