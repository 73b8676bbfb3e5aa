"""Writing to the person at the terminal, when there still is one."""

from __future__ import annotations

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
        pass
