"""The ``sync`` section: how a session meets a scanner (trigger, dummy volumes, TR, locking).

A trigger is one of three kinds, written the same way in a protocol and on the command line:

- ``serial:PATH[:CHAR]`` a USB trigger converter that sends one ASCII character per volume
  (``5`` unless CHAR says otherwise) on a serial device;
- ``key[:CHAR]`` a key pressed in the experimenter's UI (button boxes and converters that type);
- ``emulate:TR`` volumes emulated every TR seconds, to rehearse without a scanner.

Pure values and parsing, no I/O and no numpy (``pinarray validate`` reads it); the volumes
themselves are counted by `pinarray.imaging`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import TypeAlias, TypeVar

from pinarray.errors import PinArrayError
from pinarray.protocol.device import whole_ns
from pinarray.protocol.model import NS_PER_S
from pinarray.protocol.yaml_nodes import Node, Reader

DEFAULT_CHARACTER = "5"  # what trigger converters send by convention (PsychoPy's launchScan too)
DEFAULT_BAUD_RATE = 115_200  # USB CDC converters ignore it; FTDI-based ones need theirs
MIN_TR_NS, MAX_TR_NS = NS_PER_S // 10, 60 * NS_PER_S  # launchScan refuses TR < 0.1 s too
MAX_DUMMY_VOLUMES = 100
MAX_LOCK_VOLUMES = 1000
# How long to wait for the first volume before giving up (launchScan's default is 300 s too).
DEFAULT_WAIT_TIMEOUT_NS = 300 * NS_PER_S
MAX_WAIT_TIMEOUT_NS = 3600 * NS_PER_S
SYNC_KEYS = {"trigger", "dummy_volumes", "repetition_time_s", "lock_to_volumes", "baud_rate",
             "wait_timeout_s"}
_T = TypeVar("_T")
_DECIMAL = re.compile(r"\d{1,9}(\.\d{1,9})?", re.ASCII)  # \d alone takes any script's digits


class SyncError(PinArrayError):
    """A trigger or scanner setting that cannot work; says what was expected and found."""


@dataclass(frozen=True)
class SerialTrigger:
    """One ``character`` per volume on the serial device ``path``."""

    path: str
    character: str = DEFAULT_CHARACTER
    baud_rate: int = DEFAULT_BAUD_RATE

    def describe(self) -> str:
        return f"serial:{self.path}:{self.character}"


@dataclass(frozen=True)
class KeyTrigger:
    """One press of ``character`` per volume, in the experimenter's UI."""

    character: str = DEFAULT_CHARACTER

    def describe(self) -> str:
        return f"key:{self.character}"


@dataclass(frozen=True)
class EmulatedTrigger:
    """A volume every ``tr_ns`` nanoseconds from the start of the wait, with no scanner."""

    tr_ns: int

    def describe(self) -> str:
        return f"emulate:{_seconds(self.tr_ns)}"


Trigger: TypeAlias = SerialTrigger | KeyTrigger | EmulatedTrigger


@dataclass(frozen=True)
class ScannerSync:
    """How a run meets the scanner.

    Attributes
    ----------
    trigger : Trigger
        Where volumes come from.
    dummy_volumes : int
        Volumes logged but not counted: the run's time zero is the next one.
    repetition_time_ns : int or None
        The TR in ns, to flag irregular and missed volumes and to lock onsets; None: taken
        from the volumes seen (an emulated trigger carries its own).
    lock_to_volumes : int
        0: trials follow the protocol's timing from time zero. N > 0: each trial starts at a
        counted volume whose number is a multiple of N (0, N, 2N, ...), the first free one
        after the trial is ready.
    wait_timeout_ns : int
        How long to wait for each volume before the first counted one, in ns.
    """

    trigger: Trigger
    dummy_volumes: int = 0
    repetition_time_ns: int | None = None
    lock_to_volumes: int = 0
    wait_timeout_ns: int = DEFAULT_WAIT_TIMEOUT_NS

    @property
    def tr_ns(self) -> int | None:
        """The TR the volumes are judged against (ns), or None to estimate it from them."""
        match self.trigger:
            case EmulatedTrigger(tr_ns=tr_ns):
                return tr_ns
        return self.repetition_time_ns

    def describe(self) -> str:
        """One line for people: trigger, dummies, TR and locking."""
        parts = [self.trigger.describe(), f"{self.dummy_volumes} dummy volume(s)"]
        tr = self.tr_ns
        parts.append(f"TR {_seconds(tr)} s" if tr else "TR from the volumes")
        if self.lock_to_volumes:
            n = self.lock_to_volumes
            parts.append(f"onsets on volumes 0, {n}, {2 * n}, ...")
        return ", ".join(parts)


def _seconds(ns: int | None) -> str:
    return "?" if ns is None else f"{ns / NS_PER_S:g}"


def _duration_ns(text: str, what: str, low_ns: int, high_ns: int) -> int:
    """Decimal seconds (digits and at most one point: no exponent, no sign) as ns, in range."""
    if not _DECIMAL.fullmatch(text):
        raise SyncError(f"expected {what} in seconds as a decimal number (e.g. 2 or 1.5), "
                        f"found {text[:40]!r}")
    ns = round(Fraction(text) * NS_PER_S)
    if not low_ns <= ns <= high_ns:
        raise SyncError(f"expected {what} from {_seconds(low_ns)} to {_seconds(high_ns)} s, "
                        f"found {text}")
    return ns


def _character(text: str, kind: str) -> str:
    if len(text) != 1 or not 32 < ord(text) < 127:
        raise SyncError(f"expected one printable ASCII character for the {kind} trigger "
                        f"(e.g. {DEFAULT_CHARACTER}), found {text[:40]!r}")
    return text


def parse_trigger(text: str) -> Trigger:
    """``serial:PATH[:CHAR]``, ``key[:CHAR]`` or ``emulate:TR``, checked; `SyncError` if not.

    A serial path whose last ``:`` is followed by exactly one character needs its CHAR
    written out (``serial:/dev/x:y:5``): that character is otherwise taken for CHAR.
    """
    kind, _, rest = text.partition(":")
    match kind:
        case "serial":
            path, character = rest, DEFAULT_CHARACTER
            head, colon, tail = rest.rpartition(":")
            if colon and len(tail) == 1:
                path, character = head, _character(tail, "serial")
            if not path:
                raise SyncError(f"expected serial:PATH[:CHAR], found {text[:60]!r} (no device path)")
            return SerialTrigger(path, character)
        case "key":
            return KeyTrigger(_character(rest, "key") if rest else DEFAULT_CHARACTER)
        case "emulate":
            return EmulatedTrigger(_duration_ns(rest, "the emulated TR", MIN_TR_NS, MAX_TR_NS))
    raise SyncError(f"expected a trigger serial:PATH[:CHAR], key[:CHAR] or emulate:TR, "
                    f"found {text[:60]!r}")


def _check(sync: ScannerSync) -> ScannerSync:
    """What the values cannot be together, said in words."""
    match sync.trigger:
        case EmulatedTrigger(tr_ns=tr_ns) if sync.repetition_time_ns not in (None, tr_ns):
            raise SyncError(f"the emulated trigger's TR ({_seconds(tr_ns)} s) and the repetition "
                            f"time ({_seconds(sync.repetition_time_ns)} s) differ; give one TR")
    if sync.lock_to_volumes and sync.tr_ns is None:
        raise SyncError("locking onsets to volumes needs the TR, to go on when a volume is "
                        "missing: give the repetition time (--tr, or repetition_time_s)")
    return sync


def read_sync(reader: Reader, node: Node) -> ScannerSync:
    """The ``sync`` section, every problem located."""
    keys = reader.mapping(node, SYNC_KEYS, {"trigger"}, "sync section")
    with reader.section():
        trigger = reader.attempt(lambda: _located(reader, keys["trigger"], lambda: parse_trigger(
            reader.string(keys["trigger"], "the trigger"))), None)
        dummies = reader.optional(keys, "dummy_volumes", lambda n: reader.integer(
            n, "dummy volumes", 0, MAX_DUMMY_VOLUMES), 0)
        tr_ns = reader.optional(keys, "repetition_time_s", lambda n: _between(
            reader, n, "the repetition time", MIN_TR_NS, MAX_TR_NS), None)
        lock = reader.optional(keys, "lock_to_volumes", lambda n: reader.integer(
            n, "lock_to_volumes", 0, MAX_LOCK_VOLUMES), 0)
        baud = reader.optional(keys, "baud_rate", lambda n: reader.integer(
            n, "the trigger's baud rate", 50, 4_000_000), DEFAULT_BAUD_RATE)
        timeout_ns = reader.optional(keys, "wait_timeout_s", lambda n: _between(
            reader, n, "the wait timeout", NS_PER_S, MAX_WAIT_TIMEOUT_NS), DEFAULT_WAIT_TIMEOUT_NS)
    assert trigger is not None
    if isinstance(trigger, SerialTrigger):
        trigger = replace(trigger, baud_rate=baud)
    return _located(reader, node, lambda: _check(
        ScannerSync(trigger, dummies, tr_ns, lock, timeout_ns)))


def _between(reader: Reader, node: Node, what: str, low_ns: int, high_ns: int) -> int:
    value = reader.number(node, what, "s", minimum=Fraction(low_ns, NS_PER_S), allow_zero=True,
                          maximum=Fraction(high_ns, NS_PER_S))
    return whole_ns(reader, node, value, NS_PER_S, what, "s")


def _located(reader: Reader, node: Node, read):
    try:
        return read()
    except SyncError as problem:
        raise reader.error(node, str(problem)) from None


# The command line's name for each setting it can override.
OPTION_NAMES = {"dummy_volumes": "--dummy-volumes", "repetition_time_ns": "--tr",
                "lock_to_volumes": "--lock-to-volumes", "wait_timeout_ns": "--trigger-timeout"}


@dataclass(frozen=True)
class SyncOverrides:
    """The command line's scanner choices; None where it leaves the protocol's."""

    trigger: Trigger | None = None
    dummy_volumes: int | None = None
    repetition_time_ns: int | None = None
    lock_to_volumes: int | None = None
    wait_timeout_ns: int | None = None

    def over(self, base: ScannerSync | None) -> ScannerSync | None:
        """The protocol's ``sync`` section (``base``) with these choices on top (they win).

        None when neither names a trigger; `SyncError` when scanner options come without one.
        """
        trigger = self.trigger
        changes = {name: value for name, value in (
            ("dummy_volumes", self.dummy_volumes), ("repetition_time_ns", self.repetition_time_ns),
            ("lock_to_volumes", self.lock_to_volumes), ("wait_timeout_ns", self.wait_timeout_ns))
            if value is not None}
        if base is None:
            if trigger is None:
                if changes:
                    options = ", ".join(OPTION_NAMES[name] for name in changes)
                    raise SyncError(f"{options}: a scanner trigger is needed too: give --trigger "
                                    "serial:PATH, key or emulate:TR, or a sync: section in the "
                                    "protocol")
                return None
            base = ScannerSync(trigger)
        if trigger is not None:
            if isinstance(trigger, SerialTrigger) and isinstance(base.trigger, SerialTrigger):
                trigger = replace(trigger, baud_rate=base.trigger.baud_rate)
            # An emulated trigger brings its own TR; the protocol's is the real scanner's.
            tr_ns = None if isinstance(trigger, EmulatedTrigger) else base.repetition_time_ns
            base = replace(base, trigger=trigger, repetition_time_ns=tr_ns)
        return _check(replace(
            base, dummy_volumes=_given(self.dummy_volumes, base.dummy_volumes),
            repetition_time_ns=_given(self.repetition_time_ns, base.repetition_time_ns),
            lock_to_volumes=_given(self.lock_to_volumes, base.lock_to_volumes),
            wait_timeout_ns=_given(self.wait_timeout_ns, base.wait_timeout_ns)))


def _given(chosen: int | None, protocol_value: _T) -> int | _T:
    """The command line's value where it gives one, else the protocol's."""
    return protocol_value if chosen is None else chosen
