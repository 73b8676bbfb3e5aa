"""Simulated boards kept in a file (``sim://pca9685?state=FILE``): data only, ours only.

The file is JSON that names its format and version, then numbers, text and lists: reading it
runs no code (a pickle would run whatever a file someone hands us asks), and anything that is
not exactly what `encode` writes is refused with one line, before anything is written. A path
that is not a regular file (a FIFO, a device, a folder) is refused by its kind before it is
opened, so nothing waits on a FIFO's writer or acts on a device. The file is replaced whole
(`replace_state`), never written in place.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Mapping
from fractions import Fraction
from typing import Any

from pinarray.hardware.pca9685.board_sim import BoardParts, SimulatedBoard
from pinarray.text_files import NotText, read_bounded

FORMAT = "pinarray simulated PCA9685 boards"
VERSION = 1
MAX_STATE_BYTES = 64 << 20  # a day of messages; more is not a state file we wrote
_REGISTERS = 256
_CHANNELS = 16
_FULL_ON, _FULL_OFF = 1, 2  # a latched state's flags


class NotOurs(ValueError):
    """A file that does not hold simulated boards this simulator wrote; the message says why."""


def read_state(path: str) -> bytes | None:
    """The bytes of the state file ``path``, None when there is none; `NotOurs` for anything
    but a regular file of at most `MAX_STATE_BYTES` (refused before it is opened)."""
    if not os.path.lexists(path):
        return None
    try:
        return read_bounded(path, MAX_STATE_BYTES, "simulated boards' state")
    except NotText as problem:
        raise NotOurs(problem.message) from None


def replace_state(path: str, data: bytes) -> None:
    """Put ``data`` in ``path``'s place in one step: a program killed meanwhile leaves the old
    file or the new one, never half of one (`OSError` when it cannot)."""
    folder, name = os.path.split(path)
    handle, temporary = tempfile.mkstemp(prefix=f".{name}.", suffix=".new", dir=folder or ".")
    try:
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise


def encode(messages: int, boards: Mapping[int, SimulatedBoard]) -> bytes:
    """The state file's bytes: the messages the boards heard, and every board."""
    return json.dumps({"format": FORMAT, "version": VERSION, "messages": messages,
                       "boards": [_board_data(board.parts()) for board in boards.values()]},
                      separators=(",", ":")).encode()


def decode(data: bytes) -> tuple[int, dict[int, SimulatedBoard]]:
    """The messages and the boards (by address) ``data`` holds; `NotOurs` for anything that is
    not what `encode` writes."""
    try:
        document = json.loads(data)
    except (ValueError, RecursionError):
        raise NotOurs("not a state file this simulator wrote (not JSON)") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise NotOurs("not a state file this simulator wrote (it does not name its format)")
    if document.get("version") != VERSION:
        raise NotOurs(f"a state file of version {document.get('version')!r}, expected "
                      f"{VERSION}")
    _keys(document, ("format", "version", "messages", "boards"), "the file")
    messages = _whole(document["messages"], 0, 2**63, "messages")
    boards = [_board(item) for item in _list(document["boards"], "boards")]
    found = {board.address: board for board in boards}
    if len(found) != len(boards) or not boards:
        raise NotOurs("expected one board per address, at least one")
    return messages, found


# -- one board ------------------------------------------------------------------------------------


_Latched = tuple[tuple[tuple[int, int], tuple[int, int, bool, bool]], ...]  # one channel's


def _board_data(parts: BoardParts) -> dict[str, Any]:
    def latched(channel: _Latched) -> list[int]:
        return [number for (run, period), (on, off, full_on, full_off) in channel
                for number in (run, period, on, off,
                               _FULL_ON * full_on | _FULL_OFF * full_off)]

    return {"osc_hz": parts.osc_hz, "address": parts.address, "powered": parts.powered,
            "registers": parts.registers.hex(), "pointer": parts.pointer,
            "restart_from": _fraction_data(parts.restart_from),
            "awake_from": _fraction_data(parts.awake_from),
            "runs": [[_fraction_data(a), _fraction_data(b), _fraction_data(c)]
                     for a, b, c in parts.runs],
            "latched": [latched(channel) for channel in parts.latched]}


_BOARD_KEYS = ("osc_hz", "address", "powered", "registers", "pointer", "restart_from",
               "awake_from", "runs", "latched")


def _board(item: object) -> SimulatedBoard:
    if not isinstance(item, dict):
        raise NotOurs("boards: expected objects")
    _keys(item, _BOARD_KEYS, "a board")
    registers = item["registers"]
    try:
        raw = bytes.fromhex(registers) if isinstance(registers, str) else b""
    except ValueError:
        raw = b""
    if len(raw) != _REGISTERS:
        raise NotOurs(f"registers: expected {_REGISTERS} bytes in hex")
    if not isinstance(item["powered"], bool):
        raise NotOurs("powered: expected true or false")
    runs = tuple(_run(run) for run in _list(item["runs"], "runs"))
    channels = _list(item["latched"], "latched")
    if len(channels) != _CHANNELS:
        raise NotOurs(f"latched: expected {_CHANNELS} channels")
    return SimulatedBoard.from_parts(BoardParts(
        _whole(item["osc_hz"], 1, 10**10, "osc_hz"), _whole(item["address"], 0, 127, "address"),
        item["powered"], raw, _whole(item["pointer"], 0, _REGISTERS - 1, "pointer"),
        _fraction(item["restart_from"], "restart_from"),
        _fraction(item["awake_from"], "awake_from"), runs,
        tuple(_channel(channel, len(runs)) for channel in channels)))


def _run(item: object) -> tuple[Fraction, Fraction, Fraction | None]:
    start, period, end = _list(item, "runs", 3)
    start_ns, period_ns = _fraction(start, "runs"), _fraction(period, "runs")
    end_ns = _fraction(end, "runs")
    if start_ns is None or period_ns is None or period_ns <= 0 or (
            end_ns is not None and end_ns < start_ns):
        raise NotOurs("runs: expected a start, a period above 0 and an end not before the start")
    return start_ns, period_ns, end_ns


def _channel(item: object, runs: int) -> _Latched:
    numbers = _list(item, "latched")
    if len(numbers) % 5 or not all(type(n) is int for n in numbers):
        raise NotOurs("latched: expected whole numbers, five per latch")
    found = []
    for at in range(0, len(numbers), 5):
        run, period, on, off, flags = numbers[at:at + 5]
        if not (0 <= run <= runs and period >= 0 and 0 <= on < 4096 and 0 <= off < 4096
                and 0 <= flags <= _FULL_ON | _FULL_OFF):
            raise NotOurs("latched: a latch out of range")
        found.append(((run, period), (on, off, bool(flags & _FULL_ON), bool(flags & _FULL_OFF))))
    keys = [key for key, _ in found]
    if keys != sorted(set(keys)):
        raise NotOurs("latched: expected latches in time order")
    return tuple(found)


# -- values ---------------------------------------------------------------------------------------


def _fraction_data(value: Fraction | None) -> list[int] | None:
    return None if value is None else [value.numerator, value.denominator]


def _fraction(item: object, what: str) -> Fraction | None:
    if item is None:
        return None
    numerator, denominator = _list(item, what, 2)
    if type(numerator) is not int or type(denominator) is not int or denominator <= 0:
        raise NotOurs(f"{what}: expected [numerator, denominator] whole numbers")
    return Fraction(numerator, denominator)


def _whole(item: object, low: int, high: int, what: str) -> int:
    if type(item) is not int or not low <= item <= high:
        raise NotOurs(f"{what}: expected a whole number from {low} to {high}")
    return item


def _list(item: object, what: str, length: int | None = None) -> list[Any]:
    if not isinstance(item, list) or (length is not None and len(item) != length):
        raise NotOurs(f"{what}: expected a list" + (f" of {length}" if length else ""))
    return item


def _keys(item: dict[str, Any], keys: tuple[str, ...], what: str) -> None:
    if sorted(item) != sorted(keys):
        raise NotOurs(f"{what}: expected the keys {', '.join(keys)}")
