"""Text files people hand us (protocols, answer sheets): read with a size cap, decoded or located.

A path can name anything: a regular file, a folder, a FIFO, ``/dev/zero``, a 50 MB export.
Only a regular file is read: anything else is refused by its kind before it is opened, so no
command waits on a FIFO's writer or reads a device that never ends. Reading stops one byte
past the cap, so a file that keeps growing costs at most that much, and text arrives as the
editors and spreadsheets of a lab save it: UTF-8 with or without a byte-order mark, UTF-16
or UTF-32 with one (Excel's "Unicode text", Windows Notepad's "Unicode"), CRLF or CR line
ends. Anything else is refused at the line and column of the first byte that is not text.
"""

from __future__ import annotations

import codecs
import os
import stat

# Byte-order marks, longest first: a UTF-32 LE mark begins with the UTF-16 LE one.
_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32-le"),
    (codecs.BOM_UTF32_BE, "utf-32-be"),
    (codecs.BOM_UTF8, "utf-8"),
    (codecs.BOM_UTF16_LE, "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be"),
)


class NotText(Exception):
    """A file that cannot be read as text; ``line`` and ``col`` are 1-based, 0 when unknown.

    Callers turn it into their own located error (a protocol's, an answer sheet's).
    """

    def __init__(self, message: str, line: int = 0, col: int = 0):
        super().__init__(message)
        self.message, self.line, self.col = message, line, col


def read_bounded(path: str | os.PathLike[str], limit_bytes: int, what: str) -> bytes:
    """The bytes of ``path``, at most ``limit_bytes`` of them; `NotText` for anything else.

    ``what`` names the file for people ("protocol", "answers").
    """
    try:
        # Looked at before it is opened: opening a FIFO waits for a writer, and opening a
        # device can act on it.
        _refuse_unless_regular(os.stat(path).st_mode, what)
        # O_NONBLOCK: should a FIFO take its place before the open, that must not wait either.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise NotText(f"no such {what} file") from None
    except OSError as problem:
        raise NotText(f"cannot read the {what}: {problem.strerror}") from None
    try:
        info = os.fstat(fd)
        _refuse_unless_regular(info.st_mode, what)  # what was opened, if it was swapped
        if info.st_size > limit_bytes:
            raise NotText(_too_large(what, limit_bytes, f"{info.st_size:,} bytes"))
        chunks, size = [], 0
        while size <= limit_bytes:
            chunk = os.read(fd, min(1 << 20, limit_bytes + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as problem:
        raise NotText(f"cannot read the {what}: {problem.strerror}") from None
    finally:
        os.close(fd)
    if size > limit_bytes:
        raise NotText(_too_large(what, limit_bytes, "more (it does not end where a file would)"))
    return b"".join(chunks)


# What a path that is not a regular file names, for people.
_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def kind_of(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, for people: "a folder", "a FIFO (named pipe)"..."""
    if stat.S_ISREG(mode):
        return "a regular file"
    return next((kind for test, kind in _KINDS if test(mode)), "a file of another kind")


def _refuse_unless_regular(mode: int, what: str) -> None:
    if not stat.S_ISREG(mode):
        raise NotText(f"expected a {what} file, found {kind_of(mode)}")


def _too_large(what: str, limit_bytes: int, found: str) -> str:
    return f"expected a {what} file of at most {limit_bytes // 1024:,} KiB, found {found}"


def decode_text(data: bytes) -> str:
    """``data`` as text with ``\\n`` line ends; `NotText` at the first byte that is not text."""
    encoding, start = "utf-8", 0
    for bom, name in _BOMS:
        if data.startswith(bom):
            encoding, start = name, len(bom)
            break
    body = data[start:]
    if encoding == "utf-8" and b"\0" in body:
        line, col = position_of(body, body.index(b"\0"))
        raise NotText(
            "expected UTF-8 text, found a NUL byte (a binary file, or UTF-16 without a "
            "byte-order mark? save it as UTF-8)", line, col)
    try:
        text = body.decode(encoding)
    except UnicodeDecodeError as problem:
        line, col = position_of(body, problem.start, encoding)
        raise NotText(
            f"expected {encoding.upper().removesuffix('-LE').removesuffix('-BE')} text, found "
            f"byte 0x{body[problem.start]:02x} (save the file as UTF-8)", line, col) from None
    if "\0" in text:
        line, col = position_of(text.encode("utf-8"), text.encode("utf-8").index(b"\0"))
        raise NotText("expected text, found a NUL character", line, col)
    # What universal newlines would give: CRLF and lone CR both end a line.
    return text.replace("\r\n", "\n").replace("\r", "\n")


def position_of(data: bytes, offset: int, encoding: str = "utf-8") -> tuple[int, int]:
    """1-based (line, column) of byte ``offset``, counting characters as an editor does."""
    prefix = data[:offset].decode(encoding, errors="replace")
    prefix = prefix.replace("\r\n", "\n").replace("\r", "\n")
    line = prefix.count("\n") + 1
    return line, len(prefix) - (prefix.rfind("\n") + 1) + 1
