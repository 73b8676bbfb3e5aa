"""One writer per run: a lock file that names its holder (pid and host) while a run is open.

The claim itself is the operating system's: an exclusive ``flock`` on the lock file, which the
kernel drops the moment its process ends, however it ends (SIGKILL, power cut of the process,
a crash). The file's text only says who holds it, so a refusal can name the other process,
and a lock left behind by a process that died is recognised as *stale*: its file is still
there but nobody holds it. A stale lock written on this computer is taken over, and the caller
told whose it was; one written on another computer (a results folder on a network drive) is
refused, since this computer cannot see that process: the message says which file to delete
if it is known to have ended.

POSIX only (``fcntl``); elsewhere the file names its holder but nothing enforces it.
"""

from __future__ import annotations

import errno
import json
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from pinarray.errors import ResultsError
from pinarray.journal.files import now_iso, this_host
from pinarray.text_files import kind_of

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]


class RunLocked(ResultsError):
    """The run is open in another process (or locked by one this computer cannot see)."""


@dataclass(frozen=True)
class LockHolder:
    """Who wrote a lock file: process id, computer, since when, and what it was doing."""

    pid: int
    host: str
    since: str
    command: str = ""

    @property
    def here(self) -> bool:
        """Whether the holder ran on this computer."""
        return self.host == this_host()

    def describe(self) -> str:
        """E.g. ``pid 4242 on host lab-pc (this computer), since 2024-05-01T14:03:07+02:00``."""
        here = " (this computer)" if self.here else ""
        return f"pid {self.pid} on host {self.host}{here}, since {self.since}"

    def to_json(self) -> str:
        return json.dumps({"pid": self.pid, "host": self.host, "since": self.since,
                           "command": self.command}) + "\n"

    @classmethod
    def from_text(cls, text: str) -> LockHolder | None:
        try:
            data = json.loads(text)
            return cls(int(data["pid"]), str(data["host"]), str(data["since"]),
                       str(data.get("command", "")))
        except (ValueError, KeyError, TypeError):
            return None  # empty (its holder had not written it yet) or not ours


def _read_holder(fd: int) -> LockHolder | None:
    os.lseek(fd, 0, os.SEEK_SET)
    return LockHolder.from_text(os.read(fd, 4096).decode("utf-8", errors="replace"))


def _try_flock(fd: int) -> bool:
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


RUN_LOCK = "the run's lock file"


def _unusable(path: Path, problem: OSError | str, what: str = RUN_LOCK) -> ResultsError:
    """A lock file that cannot be used (a folder, a link, read-only), in one line."""
    why = problem if isinstance(problem, str) else problem.strerror or str(problem)
    return ResultsError(f"{path}: cannot use {what}: {why}")


def _open(path: Path, flags: int, what: str = RUN_LOCK) -> int:
    """The lock file, opened; `ResultsError` for anything but a regular file that opens.

    O_NONBLOCK: a FIFO or a device in its place must not make the open wait. O_NOFOLLOW: a
    link in its place is not followed (a dangling one would have the lock created where it
    points, outside the results folder). A hard link is refused too: the file has another name,
    whose contents the lock's record would replace. What is left, a regular file with no
    other name, is the lock file whatever it holds: its text is not required to be a record
    of ours, since a power cut between emptying it and writing the record leaves it empty or
    torn, and that must not stop the run's resume; rewriting it changes no other file.
    """
    try:
        fd = os.open(path, flags | os.O_NONBLOCK | os.O_NOCTTY | os.O_NOFOLLOW, 0o644)
    except FileNotFoundError:
        raise  # no lock (its folder gone): the caller's to say what that means
    except OSError as problem:
        if problem.errno == errno.ELOOP and path.is_symlink():
            raise _unusable(path, "expected a regular file, found a symbolic link to "
                                  f"{os.readlink(path)}", what) from None
        raise _unusable(path, problem, what) from None
    status = os.fstat(fd)
    if not stat.S_ISREG(status.st_mode):
        os.close(fd)
        raise _unusable(path, f"expected a regular file, found {kind_of(status.st_mode)}", what)
    if status.st_nlink > 1:
        # A hard link: the same file under another name too (a run's beh.tsv, participants.tsv,
        # a file outside the results). The lock's record written into it would replace that.
        os.close(fd)
        raise _unusable(path, f"expected a file of its own, found a hard link (one file with "
                              f"{status.st_nlink} names: writing it would change the others)",
                        what)
    return fd


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        return False


class RunLock:
    """An exclusive claim on one run, held from `acquire` until `release` (or the process ends).

    Attributes
    ----------
    path : Path
        The lock file.
    stale : LockHolder or None
        The holder named in a lock file left behind by a process that ended without
        releasing it (killed, crashed), taken over by this one; None if the lock was free.
    """

    def __init__(self, path: Path, fd: int, stale: LockHolder | None):
        self.path = path
        self._fd: int | None = fd
        self.stale = stale

    @classmethod
    def acquire(cls, path: Path, what: str, command: str = "") -> RunLock:
        """Claim ``path`` for this process, or raise `RunLocked` naming its holder.

        Parameters
        ----------
        path : Path
            The lock file (created, with its folder, if missing).
        what : str
            What the lock protects, for the message (e.g. ``sub-01 ses-1 ... run-2``).
        command : str
            What this process is doing, written for the next one to read.
        """
        path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = _open(path, os.O_RDWR | os.O_CREAT)
            try:
                if not _try_flock(fd):
                    raise RunLocked(locked_message(what, _read_holder(fd)))
                if _same_file(fd, path):
                    return cls._claimed(path, fd, what, command)
            except OSError as problem:
                os.close(fd)
                raise _unusable(path, problem) from None
            except BaseException:
                os.close(fd)
                raise
            os.close(fd)  # its holder released (and removed) it while we waited: try afresh

    @classmethod
    def _claimed(cls, path: Path, fd: int, what: str, command: str) -> RunLock:
        """The lock on ``fd`` is ours: refuse another computer's, else name this process."""
        previous = _read_holder(fd)
        if previous is not None and previous.host != this_host():
            raise RunLocked(
                f"{what} is locked by {previous.describe()}, which this computer cannot see; "
                f"if that process has ended, delete {path} and try again"
            )
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, LockHolder(os.getpid(), this_host(), now_iso(), command).to_json().encode())
        os.fsync(fd)
        return cls(path, fd, previous)

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        """Give the run up: remove the lock file, then let go of the claim. Idempotent."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        # Removed while still held, so nobody can take over a file that is about to vanish;
        # a process that opened it before the removal sees the name gone and starts afresh.
        self.path.unlink(missing_ok=True)
        os.close(fd)


def lock_holder(path: Path) -> LockHolder | None:
    """Who holds the lock at ``path`` right now, or None when nobody does (free or stale)."""
    try:
        fd = _open(path, os.O_RDWR)
    except FileNotFoundError:
        return None
    try:
        if _try_flock(fd):
            return None  # nobody holds it; closing the descriptor lets go again
        return _read_holder(fd) or LockHolder(0, "", "unknown")
    except OSError as problem:
        raise _unusable(path, problem) from None
    finally:
        os.close(fd)


def locked_message(what: str, holder: LockHolder | None) -> str:
    """A refusal in words: ``what`` is open in another process, and which one."""
    who = holder.describe() if holder else "a process that has not yet named itself"
    return (f"{what} is open in another process, {who}; a run has one writer at a time: "
            "wait for that one to end, or end it, then try again")


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists on this computer (signal 0 checks without sending)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # another user's process (or a pid that cannot be asked): it exists
    return True


def stale_message(stale: LockHolder, what: str) -> str:
    """A taken-over lock in words, for the log."""
    if stale.here and stale.pid > 0 and _running(stale.pid):
        # Nobody holds the lock, so that process is not writing the run: its pid was reused.
        gone = f"pid {stale.pid} is now another program; the writer ended without releasing it"
    else:
        gone = "that process is no longer running (killed or crashed)"
    return (f"took over the lock of {what} left by {stale.describe()}: {gone}; its run is "
            "resumed here")


@contextmanager
def held(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` for a short read-modify-write (waits for it); a
    lock file that is no regular file (a link, a FIFO, a folder) is refused, naming it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = _open(path, os.O_RDWR | os.O_CREAT, "the dataset's lock file")
    except FileNotFoundError as problem:  # its folder removed since: as any other problem
        raise _unusable(path, problem, "the dataset's lock file") from None
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)
