"""Files that survive a crash: atomic replacement, durable names, and the wall clock's reading.

A file replaced with `write_atomically` is either the old or the new version after a crash at
any moment, never half of one: the new text goes to a temporary file in the same folder, is
fsync'd, and takes the old one's name with ``os.replace``; the folder is then fsync'd so the
new name is durable too.
"""

from __future__ import annotations

import os
import platform
import socket
import tempfile
from datetime import datetime
from pathlib import Path


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
    # The temporary file must be in the same folder: os.replace is atomic only within one
    # file system.
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if hasattr(os, "fchmod"):  # POSIX
            os.fchmod(handle, 0o666 & ~_UMASK)
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            out.write(text)
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
