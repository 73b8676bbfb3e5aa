"""Results files: read checked and bounded, replaced atomically, named durably; the wall clock.

A file replaced with `write_atomically` is either the old or the new version after a crash at
any moment, never half of one: the new text goes to a temporary file in the same folder, is
fsync'd, and takes the old one's name with ``os.replace``; the folder is then fsync'd so the
new name is durable too.

Every results file is read through `read_results_file` (or `read_results_json`): a name can
lead anywhere (a folder, a FIFO whose open waits for a writer for ever, ``/dev/zero``, a link
to nothing), so only a regular file is opened, and no more than a bound is read. Whatever
else is found is a one-line `ResultsError` naming the file.
"""

from __future__ import annotations

import csv
import io
import json
import os
import platform
import re
import shutil
import socket
import stat
import tempfile
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any, BinaryIO

from pinarray.errors import ResultsError
from pinarray.text_files import NotText, kind_of, position_of, read_bounded

# A run's tables: a million rows, far more than any design.
MAX_RESULTS_BYTES = 256 << 20
# A manifest holds a plan of at most 20 000 trials, a few hundred bytes each; sidecars less.
MAX_JSON_BYTES = 64 << 20


def wall_now() -> datetime:
    """The local wall-clock time with its UTC offset."""
    return datetime.now().astimezone()


def iso(at: datetime, timespec: str = "seconds") -> str:
    """ISO 8601 with the UTC offset, e.g. ``2024-05-01T14:03:07+02:00``."""
    return at.isoformat(timespec=timespec)


def now_iso() -> str:
    """Local wall-clock time with its UTC offset, to the second."""
    return iso(wall_now())


def this_host() -> str:
    return socket.gethostname()


def this_machine() -> dict[str, str]:
    """Platform and host name, recorded so results can be traced to the computer that ran them."""
    return {
        "hostname": this_host(),
        "platform": platform.platform(),
        "python": platform.python_version(),
    }


def _umask() -> int:
    # Read once, at import, while nothing else can be creating files: os.umask can only be
    # read by setting it.
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _umask()


def write_atomically(path: Path, text: str) -> None:
    """Replace ``path`` with ``text`` so that a crash leaves either the old or the new file.

    The file gets the permissions any new file would (0666 less the umask), not the
    temporary file's owner-only ones, so the lab's other accounts can read the dataset.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    _replace(path, 0o666 & ~_UMASK, lambda out: out.write(text.encode("utf-8")))


def own_copy(path: Path) -> None:
    """Give the regular file at ``path`` a copy of its own if it has other names (hard links):
    a backup made with ``cp -al``, or a link put there by hand. The bytes go to a new file that
    takes the name with ``os.replace``, so a later write in place (an appended row, a torn row
    cut off) changes this file only, never the others; nothing there, or one name: nothing done."""
    try:
        status = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return
    if not stat.S_ISREG(status.st_mode) or status.st_nlink < 2:
        return

    def copy(out: BinaryIO) -> None:
        with open(path, "rb") as source:
            shutil.copyfileobj(source, out)

    _replace(path, stat.S_IMODE(status.st_mode), copy)


def _replace(path: Path, mode: int, write: Callable[[BinaryIO], object]) -> None:
    """``path`` replaced by a new file of permissions ``mode`` that ``write`` fills, fsync'd,
    renamed over it, its folder fsync'd; the new file removed if anything fails."""
    # The temporary file must be in the same folder: os.replace is atomic only within one
    # file system.
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if hasattr(os, "fchmod"):  # POSIX
            os.fchmod(handle, mode)
        with os.fdopen(handle, "wb") as out:
            write(out)
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    fsync_folder(path.parent)


def fsync_folder(folder: Path) -> None:
    """Make a new or renamed file's name durable by syncing its folder entry (POSIX)."""
    # Windows cannot open folders; there the rename is already as durable as it gets.
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def results_file(path: Path, what: str = "results") -> bool:
    """Whether a regular file is at ``path`` (through a link); False when nothing is there;
    a `ResultsError` for anything else, looked at without opening it (opening a FIFO waits
    for a writer, reading ``/dev/zero`` never ends) and for a link that leads nowhere."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if os.path.islink(path):
            raise ResultsError(f"{path}: expected a {what} file, found a link to "
                               f"{os.readlink(path)}, which does not exist") from None
        return False
    except OSError as problem:  # a loop of links, a folder on the way that is not one
        raise ResultsError(f"{path}: cannot read the {what}: {problem.strerror}") from None
    if not stat.S_ISREG(mode):
        raise ResultsError(f"{path}: expected a {what} file, found {kind_of(mode)}")
    return True


def read_results_file(path: Path, what: str = "results",
                      limit_bytes: int = MAX_RESULTS_BYTES) -> bytes:
    """The bytes of the results file at ``path``: a regular file of at most ``limit_bytes``;
    a one-line `ResultsError` naming it for anything else (nothing there included)."""
    if not results_file(path, what):
        raise ResultsError(f"{path}: no such {what} file")
    try:
        return read_bounded(path, limit_bytes, what)
    except NotText as problem:
        raise ResultsError(f"{path}: {problem.message}") from None


def read_results_text(path: Path, what: str = "results",
                      limit_bytes: int = MAX_RESULTS_BYTES) -> str:
    """The text of the results file at ``path`` (`read_results_file`): UTF-8, with or without
    the byte-order mark a spreadsheet may save; a `ResultsError` at the first byte that is not."""
    data = read_results_file(path, what, limit_bytes)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as problem:
        line, col = position_of(data, problem.start)
        raise ResultsError(f"{path}:{line}:{col}: expected UTF-8 text, found byte "
                           f"0x{data[problem.start]:02x}") from None


def read_results_json(path: Path, what: str) -> Any:
    """The JSON value of the results file at ``path`` (`read_results_text`); a `ResultsError`
    at the line and column of what is not JSON."""
    text = read_results_text(path, what, MAX_JSON_BYTES)
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise ResultsError(f"{path}:{error.lineno}:{error.colno}: {error.msg}") from None
    except RecursionError:
        raise ResultsError(f"{path}: expected a {what}, found JSON nested deeper than any "
                           "pinarray writes") from None


def read_tsv(path: Path, text: str) -> list[list[str]]:
    """The rows of ``text``, the tab-separated table in the results file at ``path``; a
    one-line `ResultsError` at the row that is not one: a carriage return inside it, or a cell
    longer than Python's csv module reads (`csv.field_size_limit`, no cell pinarray writes)."""
    reader = csv.reader(io.StringIO(text), delimiter="\t")
    rows: list[list[str]] = []
    start = 1  # the line the next row begins on
    try:
        for cells in reader:
            rows.append(cells)
            start = reader.line_num + 1
    except csv.Error as problem:
        raise ResultsError(_not_a_table(path, text, start, problem)) from None
    return rows


def _not_a_table(path: Path, text: str, start: int, problem: csv.Error) -> str:
    """Where and why ``text`` cannot be read as tab-separated rows (``start``: the line the
    row that failed begins on)."""
    lone = re.search(r"\r(?!\n)", text)
    if lone is not None:
        line = text.count("\n", 0, lone.start()) + 1
        col = lone.start() - (text.rfind("\n", 0, lone.start()) + 1) + 1
        return (f"{path}:{line}:{col}: expected a tab-separated results table, found a "
                "carriage return inside a row")
    limit = csv.field_size_limit()
    if "field limit" in str(problem):
        row = text.split("\n", start)[start - 1] if start <= text.count("\n") + 1 else ""
        col, longest = 1, ""
        for cell in row.split("\t"):
            if len(cell) > limit:
                longest = cell
                break
            col += len(cell) + 1
        where = f"{path}:{start}:{col}" if longest else f"{path}:{start}"
        found = f"one of {len(longest):,}" if longest else "a longer one"
        return f"{where}: expected cells of at most {limit:,} characters, found {found}"
    return f"{path}:{start}: expected a tab-separated results table, found {problem}"
