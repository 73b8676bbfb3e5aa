"""Options several commands share: argparse ``type=`` functions with the ranges that keep a run
bounded, refused at parse time with what was expected (argparse then exits with status 2).

A number on the command line can otherwise hang a run (``--time-scale 1e-300`` slows the
simulator to a standstill), allocate gigabytes (``--width 10**9``), or reach numpy as a value
it refuses with a traceback (a negative ``--seed``).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import stat
import sys
from collections.abc import Callable
from typing import IO

from pinarray.errors import PinArrayError

MAX_SEED = 2**63 - 1  # what a plan and numpy's generators accept
# A simulator slower than 1/100 of real time, or faster than 10 000 times, helps nobody;
# 0 means virtual time (nothing sleeps).
MIN_TIME_SCALE, MAX_TIME_SCALE = 0.01, 10_000.0


# ASCII decimal only: int() and float() also read 1_000 and other scripts' digits (１２).
_WHOLE = re.compile(r"[+-]?[0-9]+", re.ASCII)
_REAL = re.compile(r"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:e[+-]?[0-9]+)?|inf(?:inity)?|nan)",
                   re.ASCII | re.IGNORECASE)


def _whole(text: str) -> int:
    try:
        if not _WHOLE.fullmatch(text.strip()):
            raise ValueError(text)
        return int(text.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a whole number, found {_short(text)}") from None


def _real(text: str) -> float:
    try:
        if not _REAL.fullmatch(text.strip()):
            raise ValueError(text)
        return float(text) + 0.0  # -0.0 becomes 0.0, which numpy's generators accept as a scale
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, found {_short(text)}") from None


def seed(text: str) -> int:
    """A seed: a whole number from 0 to 2^63 - 1."""
    value = _whole(text)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(
            f"expected a seed from 0 to 2^63-1, found {_short(text)}"
        )
    return value


def time_scale(text: str) -> float:
    """0 (virtual time) or a speed-up from `MIN_TIME_SCALE` to `MAX_TIME_SCALE` times real time."""
    value = _real(text)
    if value != 0 and not MIN_TIME_SCALE <= value <= MAX_TIME_SCALE:  # NaN fails both
        raise argparse.ArgumentTypeError(
            f"expected 0 (virtual time) or {MIN_TIME_SCALE:g} to {MAX_TIME_SCALE:g} times real "
            f"time, found {_short(text)}"
        )
    return value


def add_speed(parser: argparse.ArgumentParser, default: float | None, help: str) -> None:
    """``--speed X``: the simulator at X times real time (0: virtual time, nothing waits).

    ``--time-scale`` is its old name, kept working: read as "scale time by 0.001" it was
    taken to mean "faster", while it meant "1000 times slower".
    """
    parser.add_argument("--speed", "--time-scale", dest="time_scale", type=time_scale,
                        default=default, metavar="X", help=help)


def baud_rate(text: str) -> int:
    """A rate the servos listen at (`pinarray.protocol.BAUD_RATES`), checked as it is read: the
    protocol's model is not loaded to build the options of the commands that take one (it is
    most of `sim-serve`'s and `servos scan`'s start-up)."""
    from pinarray.protocol import BAUD_RATES

    value = _whole(text)
    if value not in BAUD_RATES:
        raise argparse.ArgumentTypeError(
            f"expected one of {', '.join(map(str, BAUD_RATES))}, found {_short(text)}")
    return value


def count(minimum: int, maximum: int) -> Callable[[str], int]:
    """A whole number from ``minimum`` to ``maximum``."""

    def parse(text: str) -> int:
        value = _whole(text)
        if not minimum <= value <= maximum:
            raise argparse.ArgumentTypeError(
                f"expected a whole number from {minimum:,} to {maximum:,}, found {_short(text)}"
            )
        return value

    return parse


def counts(minimum: int, maximum: int, most: int) -> Callable[[str], list[int]]:
    """Comma-separated whole numbers from ``minimum`` to ``maximum``, at most ``most`` of them."""
    one = count(minimum, maximum)

    def parse(text: str) -> list[int]:
        items = text.split(",")
        if items[-1].strip() == "" and len(items) > 1:
            items.pop()  # "4,8," as a spreadsheet copies a row: the last comma ends it
        if any(not item.strip() for item in items):
            raise argparse.ArgumentTypeError(
                f"expected comma-separated numbers, found an empty one in {_short(text)}")
        values = [one(item) for item in items]
        if not 1 <= len(values) <= most:
            raise argparse.ArgumentTypeError(
                f"expected 1 to {most} comma-separated numbers, found {len(values)} in "
                f"{_short(text)}"
            )
        twice = sorted({v for v in values if values.count(v) > 1})
        if twice:
            raise argparse.ArgumentTypeError(
                f"expected each number once, found {', '.join(map(str, twice))} more than once "
                f"in {_short(text)}")
        return values

    return parse


def number(
    minimum: float, maximum: float, *, above_minimum: bool = False, infinite: bool = False
) -> Callable[[str], float]:
    """A finite number from ``minimum`` to ``maximum`` (excluding ``minimum`` when
    ``above_minimum``); ``infinite`` also lets +inf through, where it means something."""

    def parse(text: str) -> float:
        value = _real(text)
        if infinite and value == math.inf:
            return value
        low_ok = value > minimum if above_minimum else value >= minimum
        if not (low_ok and value <= maximum):  # NaN fails too
            relation = "above" if above_minimum else "from"
            raise argparse.ArgumentTypeError(
                f"expected a number {relation} {minimum:g} to {maximum:g}, found {_short(text)}"
            )
        return value

    return parse


def servo_ids(text: str) -> tuple[int, ...]:
    """The servo ids ``--ids`` names (``1-4,9``), at least one; refused naming the option.

    Read in the command, not as an argparse ``type=``, so that the refusal is one line.
    """
    from pinarray.hardware.feetech.faults import parse_ids

    try:
        return parse_ids(text)
    except PinArrayError as problem:
        raise PinArrayError(f"--ids: {problem}") from None


# -- work that may take minutes -------------------------------------------------------------

# Work estimated at this or longer says how far it is, a line on stderr per tenth.
PROGRESS_AFTER_S = 10.0


def refuse_long_work(what: str, estimate_s: float, limit_s: float, change: str) -> None:
    """Refuse, before it starts, work estimated to take more than ``limit_s``: one line with
    the estimate and ``change`` (what to change)."""
    from pinarray.units import duration_words

    if estimate_s > limit_s:
        raise PinArrayError(f"{what} would take about {duration_words(estimate_s)}; at most "
                            f"{duration_words(limit_s)}: {change}")


def progress(what: str, total: int, estimate_s: float) -> Callable[[int], None]:
    """What to call with the units of work done so far (of ``total``): a line on stderr at each
    tenth, with the time left at the pace so far, when the work is estimated to take
    `PROGRESS_AFTER_S` or longer; nothing otherwise."""
    import time

    from pinarray.units import duration_words

    if estimate_s < PROGRESS_AFTER_S or total <= 0:
        return lambda done: None
    started, said = time.monotonic(), 0  # tenths said so far

    def tell(done: int) -> None:
        nonlocal said
        tenth = 10 * done // total
        if tenth <= said:
            return
        said = tenth
        left = (time.monotonic() - started) * (total - done) / done
        print(f"{what}: {done:,} of {total:,} ({100 * done // total} %)"
              + (f", about {duration_words(left)} left" if done < total else ""),
              file=sys.stderr, flush=True)

    return tell


def _short(text: str) -> str:
    return repr(text) if len(text) <= 30 else f"{text[:30]!r}... ({len(text)} characters)"


def png_path(text: str) -> str:
    """Where a ``--png`` option writes: ``text`` if it ends in ``.png``, else ``text.png``, the
    name matplotlib gives a picture saved without an extension; commands report this name.

    A folder is refused, as `OutputFile` refuses one, rather than read as ``folder.png``
    beside it (``--out`` names the folder where a command has one).
    """
    if os.path.isdir(text):
        raise PinArrayError(f"{text}: cannot write: it is a folder, expected a file name")
    return text if text.lower().endswith(".png") else text + ".png"


def new_file(text: str) -> str:
    """A file a command will write as it goes (a log): not a folder, in a folder that exists
    (an argparse ``type=``: refused with the option's name and usage, exit status 2)."""
    problem = _unwritable(text)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return text


def check_new_file(text: str) -> None:
    """Refuse, before any work, a file a command will write that it could not: a folder, in
    a folder that does not exist or cannot be written."""
    problem = _unwritable(text)
    if problem:
        raise PinArrayError(problem)


def check_output_folder(text: str, names: tuple[str, ...]) -> None:
    """Refuse, before any work, a folder of outputs that could not be written: a file where
    the folder or one of ``names`` in it should be, or a place where it cannot be made."""
    if os.path.exists(text) and not os.path.isdir(text):
        raise PinArrayError(f"{text}: cannot write there: it is a file, expected a folder")
    made = text
    while not os.path.exists(made):  # the nearest folder that exists must take the new one
        made = os.path.dirname(os.path.abspath(made))
    if not os.path.isdir(made):
        raise PinArrayError(f"{text}: cannot write there: {made} is a file, not a folder")
    if not os.access(made, os.W_OK | os.X_OK):
        raise PinArrayError(f"{text}: cannot write there: {made}: permission denied")
    if os.path.isdir(text):
        for name in names:
            check_new_file(os.path.join(text, name))


def _unwritable(text: str) -> str | None:
    if os.path.isdir(text):
        return f"{text}: cannot write: it is a folder, expected a file name"
    folder = os.path.dirname(text) or "."
    if not os.path.isdir(folder):
        return f"{text}: cannot write: no folder {folder!r}"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"{text}: cannot write: permission denied in {folder!r}"
    return None


class OutputFile:
    """A file a command writes whole or not at all.

    A regular file is written under a temporary name beside it and renamed over it only
    when `commit` is called, so a full disk or a failed run leaves any earlier file of that
    name as it was and no half-written one. A device or FIFO (``/dev/null``, ``/dev/full``)
    cannot be renamed over and is written directly; ``-`` is standard output. Every failure
    is a `PinArrayError` naming the path.
    """

    def __init__(self, path: str, binary: bool = False) -> None:
        self.path, self.final, self.temporary = path, path, None
        if path == "-" and not binary:
            self.stream: IO = sys.stdout
            return
        try:
            mode = os.stat(path).st_mode
        except FileNotFoundError:
            mode = stat.S_IFREG
        except OSError as problem:
            raise PinArrayError(f"{path}: cannot write: {problem.strerror}") from None
        if stat.S_ISDIR(mode):
            raise PinArrayError(f"{path}: cannot write: it is a folder, expected a file name")
        target = path
        if stat.S_ISREG(mode):
            # Beside the file a symbolic link points to: the rename replaces that file.
            self.final = os.path.realpath(path)
            folder, name = os.path.split(self.final)
            target = self.temporary = os.path.join(
                folder, f".{name}.{os.getpid()}-{os.urandom(4).hex()}.part")
        try:
            # Created 0666 less the umask, as an ordinary file would be (not mkstemp's 0600).
            flags = os.O_WRONLY | (os.O_CREAT | os.O_EXCL if self.temporary else os.O_TRUNC)
            fd = os.open(target, flags, 0o666)
            self.stream = (
                os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", newline="", encoding="utf-8")
            )
        except OSError as problem:
            raise PinArrayError(f"{path}: cannot write: {problem.strerror}") from None

    def flush(self) -> None:
        """Push everything written so far to the file (a full device fails here)."""
        try:
            self.stream.flush()
        except OSError as problem:
            self.discard()
            raise PinArrayError(f"{self.path}: cannot write: {problem.strerror}") from None

    def commit(self) -> None:
        """Finish the file: flush it and put it in place."""
        try:
            if self.stream is sys.stdout:
                self.stream.flush()
                return
            self.stream.close()
            if self.temporary:
                os.replace(self.temporary, self.final)
                self.temporary = None
        except OSError as problem:
            self.discard()
            raise PinArrayError(f"{self.path}: cannot write: {problem.strerror}") from None

    def discard(self) -> None:
        """Give the file up: nothing of it is left (a device keeps what it was sent)."""
        if self.stream is not sys.stdout:
            with contextlib.suppress(OSError):  # already failing: the write's error is the one to say
                self.stream.close()
        if self.temporary:
            with contextlib.suppress(FileNotFoundError):
                os.remove(self.temporary)
            self.temporary = None


# -- scanners and EEG (batch, tui) -------------------------------------------------------------


def trigger(text: str):
    """A scanner trigger: serial:PATH[:CHAR], key[:CHAR] or emulate:TR."""
    from pinarray.protocol.imaging import SyncError, parse_trigger

    try:
        return parse_trigger(text)
    except SyncError as problem:
        raise argparse.ArgumentTypeError(str(problem)) from None


def seconds_ns(minimum_s: float, maximum_s: float) -> Callable[[str], int]:
    """Seconds from ``minimum_s`` to ``maximum_s``, as whole nanoseconds."""
    within = number(minimum_s, maximum_s)

    def parse(text: str) -> int:
        return round(within(text) * 1_000_000_000)

    return parse


def add_sync_options(parser: argparse.ArgumentParser, *, key: bool) -> None:
    """--trigger, --dummy-volumes, --tr, --lock-to-volumes, --trigger-timeout, --lsl."""
    from pinarray.imaging.lsl import DEFAULT_STREAM_NAME
    from pinarray.protocol.imaging import MAX_DUMMY_VOLUMES, MAX_LOCK_VOLUMES

    kinds = "serial:PATH[:CHAR], key[:CHAR] (in the UI) or emulate:TR" if key else \
        "serial:PATH[:CHAR] or emulate:TR"
    group = parser.add_argument_group(
        "scanner and EEG", "wait for a scanner's first counted volume and time every onset from "
        "it; send LSL markers (these override the protocol's sync: section)")
    group.add_argument("--trigger", type=trigger, metavar="SPEC",
                       help=f"volume triggers: {kinds}; CHAR defaults to 5")
    group.add_argument("--dummy-volumes", type=count(0, MAX_DUMMY_VOLUMES), metavar="N",
                       help="volumes logged but not counted before time zero (default 0)")
    group.add_argument("--tr", type=seconds_ns(0.1, 60), metavar="S",
                       help="the scanner's TR in seconds, to flag irregular and missed volumes "
                            "(default: the median interval seen)")
    group.add_argument("--lock-to-volumes", type=count(0, MAX_LOCK_VOLUMES), metavar="N",
                       help="start each trial on a counted volume numbered a multiple of N "
                            "(0 = on the protocol's timing, the default)")
    group.add_argument("--trigger-timeout", type=seconds_ns(1, 3600), metavar="S",
                       help="give up when no volume comes for S seconds before time zero "
                            "(default 300)")
    group.add_argument("--lsl", nargs="?", const=DEFAULT_STREAM_NAME, metavar="NAME",
                       help=f"send a marker per stimulus onset and offset on an LSL stream of "
                            f"type Markers named NAME (default {DEFAULT_STREAM_NAME})")


def sync_overrides(args: argparse.Namespace):
    """The scanner options given on the command line (`SyncOverrides`)."""
    from pinarray.protocol.imaging import SyncOverrides

    return SyncOverrides(args.trigger, args.dummy_volumes, args.tr, args.lock_to_volumes,
                         args.trigger_timeout)
