"""Writing to the person at the terminal, when there still is one."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO


def say(text: str, *, error: bool = False) -> None:
    """Print a line to stdout (or stderr), unless the terminal or pipe is gone.

    A closed terminal (SIGHUP) or a reader that went away (``| head``) must not turn a clean
    stop into a crash: the signal that came with it has already asked the run to stop.
    """
    stream = sys.stderr if error else sys.stdout
    try:
        print(text, file=stream, flush=True)
    except (OSError, StandardOutputFailed):
        discard(stream)


class StandardOutputFailed(Exception):
    """Standard output could not take a line (a full disk, an I/O error); ``args[0]`` is the
    ``OSError``. Its own kind: an ``OSError`` there would read as a results file's."""


class _Guarded:
    """A text stream whose failures to write are `StandardOutputFailed` (a reader gone stays
    ``BrokenPipeError``: it ends a command as SIGPIPE would)."""

    def __init__(self, stream: TextIO):
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as error:
            raise StandardOutputFailed(error) from error

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as error:
            raise StandardOutputFailed(error) from error

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)


@contextmanager
def guarded_stdout() -> Iterator[None]:
    """Inside the block, a line standard output cannot take raises `StandardOutputFailed`;
    what it still holds is flushed as the block ends (to a file it is written in blocks: the
    failure would otherwise come as the interpreter exits, status 120). No standard output at
    all (started with it closed: Python's ``sys.stdout`` is None) is left so: prints vanish."""
    stream = sys.stdout
    if stream is None:
        yield
        return
    guarded = _Guarded(stream)
    sys.stdout = guarded  # type: ignore[assignment]  # a text stream in all it is asked
    try:
        yield
        guarded.flush()
    finally:
        if sys.stdout is guarded:
            sys.stdout = stream


def discard(stream: TextIO) -> None:
    """What ``stream`` still holds, and whatever follows, written where nobody reads: it would
    fail again as the interpreter flushes it on its way out (exit status 120, "Exception
    ignored")."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())
    except (OSError, ValueError, AttributeError):  # AttributeError: no stream (None)
        pass
