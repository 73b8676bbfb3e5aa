"""Arguments checked at the door of every public call: a wrong one is a one-line
`PinArrayError` in the library's words (``open_array: sim: expected a sim:// URL (str),
found 5 (int)``), raised before anything is opened, moved or written, never a `TypeError`
from deep inside.

Times are integer nanoseconds (a float would lose nanoseconds past 104 days of a clock and
poison a virtual one); numbers are finite; an onset lies within `MAX_AHEAD_NS` of now. Whole
numbers may be any integer type (numpy's included) but a bool (True is 1 to Python, never a
pin or a time to a lab); real numbers any real type. A value whose own methods fail (its
``repr``, its ``__fspath__``) is refused, never lets its exception out.
"""

from __future__ import annotations

import math
import numbers
import threading
from collections.abc import Callable
from fractions import Fraction
from os import PathLike, fspath
from typing import TYPE_CHECKING, Any, NoReturn, TypeGuard

from pinarray.errors import PinArrayError

if TYPE_CHECKING:
    from pinarray.clock import Clock
    from pinarray.protocol.model import Protocol

# How far ahead of the array's clock a stimulus may be armed, in ns: a minute (a stimulus
# armed further ahead is almost surely a unit slip, s for ms or ns; on a virtual clock it
# would also be waited out in slices).
MAX_AHEAD_NS = 60_000_000_000
# The largest seed a plan takes (numpy's generators take 0 to 2^63 - 1).
MAX_SEED = 2**63 - 1
# The longest path the system takes, and the longest name in it, in bytes (Linux's PATH_MAX
# and NAME_MAX): a longer one is refused at the door, not by the system deep inside.
MAX_PATH_BYTES = 4095
MAX_NAME_BYTES = 255


def shortened(text: str, limit: int = 60) -> str:
    """``text`` cut to ``limit`` characters, "..." marking the cut."""
    return text if len(text) <= limit else text[:limit - 3] + "..."


def shown(value: object) -> str:
    """A value as a message shows it: its repr, shortened (a repr that fails is named)."""
    try:
        return shortened(repr(value))
    except Exception:  # a value's own repr may fail: the message must not
        return f"<a {type(value).__name__} whose repr fails>"


def found(value: object) -> str:
    """A value as a message shows what was found: its repr (shortened) and its type."""
    if isinstance(value, int) and value.bit_length() > 200:  # too long to show in a line
        return f"an int of {value.bit_length()} bits ({type(value).__name__})"
    return f"{shown(value)} ({type(value).__name__})"


def refuse(call: str, name: str, expected: str, value: object) -> NoReturn:
    raise PinArrayError(f"{call}: {name}: expected {expected}, found {found(value)}")


def is_int(value: object) -> TypeGuard[int]:
    """A whole number of any integer type (numpy's too), not a bool (True is 1 to Python,
    never a pin or a time to a lab); ``int(value)`` is its value."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_real(value: object) -> TypeGuard[float]:
    """A real number of any real type (int, float, Fraction, numpy's), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def protocol(call: str, value: object, name: str = "protocol") -> Protocol:
    from pinarray.protocol.model import Protocol

    if not isinstance(value, Protocol):
        refuse(call, name, "a Protocol (from pinarray.load_protocol)", value)
    return value


def text(call: str, name: str, value: object) -> str:
    if not isinstance(value, str):
        refuse(call, name, "a str", value)
    return value


def optional_text(call: str, name: str, value: object) -> str | None:
    return None if value is None else text(call, name, value)


def _as_text(value: object) -> object:
    """A path-like's path (what it gives, unchecked); anything else as it is."""
    if isinstance(value, PathLike):
        try:
            return fspath(value)
        except Exception:  # its own __fspath__ failed
            return None
    return value


def _fits(text: str) -> bool:
    """Whether the system can take ``text`` as a path: no NUL, no name (nor the whole) longer
    than it allows."""
    encoded = text.encode(errors="surrogateescape")
    return ("\0" not in text and len(encoded) <= MAX_PATH_BYTES
            and all(len(part) <= MAX_NAME_BYTES for part in encoded.split(b"/")))


def path(call: str, name: str, value: object) -> str:
    """A file or folder's path: a str or path-like (not bytes), one the system can take."""
    as_text = _as_text(value)
    if isinstance(as_text, str) and as_text and _fits(as_text):
        return as_text
    refuse(call, name, "a path (a non-empty str or path-like, no NUL, no name longer than "
                       f"{MAX_NAME_BYTES} bytes)", value)


def port(call: str, value: object) -> str | None:
    if value is None:
        return None
    value = _as_text(value)
    if not isinstance(value, str) or not value or not _fits(value):
        refuse(call, "port", "a serial device's path such as '/dev/ttyUSB0' (str)", value)
    if value.startswith("sim://"):
        raise PinArrayError(f"{call}: port: {value!r} is a simulated array: give it as sim=")
    return value


def sim_url(call: str, value: object, name: str = "sim") -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.startswith("sim://"):
        refuse(call, name, "a sim:// URL such as 'sim://?drop_writes=0.1&seed=3' (str)", value)
    return value


def sim_for(call: str, protocol: Protocol, value: object, name: str = "sim") -> str | None:
    """A ``sim://`` URL of the protocol's kind of servos, read as the script wrote it (its
    problems in its own words, before pinarray adds the protocol's servo ids to it)."""
    from pinarray.hardware.pca9685.sim import is_pca9685_url
    from pinarray.protocol.model import HobbyServos

    url = sim_url(call, value, name)
    if url is None:
        return None
    board = isinstance(protocol.device.servo, HobbyServos)
    if board != is_pca9685_url(url):
        wanted = ("a sim://pca9685 URL: its device is a PWM board" if board else
                  "a sim:// URL of bus servos (not sim://pca9685): its device is STS servos")
        raise PinArrayError(f"{call}: {name}: protocol {protocol.name!r} takes {wanted}, found "
                            f"{url!r}")
    if not board:
        from pinarray.hardware.feetech.faults import parse_sim_url

        parse_sim_url(url)
    return url


def clock(call: str, value: object) -> Clock | None:
    if value is None:
        return None
    expected = "a Clock (pinarray.VirtualClock() or pinarray.MonotonicClock())"
    if isinstance(value, type) or not all(
            callable(getattr(value, method, None))
            for method in ("now_ns", "sleep_until_ns", "doze_until_ns")):
        refuse(call, "clock", expected, value)
    clock_value: Clock = value  # type: ignore[assignment]  # checked just above, as a Protocol
    try:
        now_ns = clock_value.now_ns()
    except Exception:  # a look-alike that cannot tell the time
        refuse(call, "clock", expected, value)
    if not is_int(now_ns):
        raise PinArrayError(f"{call}: clock: its now_ns() must give integer ns, gave "
                            f"{found(now_ns)}")
    return clock_value


def time_ns(call: str, name: str, value: object) -> int:
    """A time on the array's clock: a whole number of nanoseconds."""
    if not is_int(value):
        hint = (f" (as an int: {round(value)})" if is_real(value) and math.isfinite(value)
                else "")
        refuse(call, name, f"a time in integer nanoseconds{hint}", value)
    return int(value)


def onset_ns(call: str, value: object, now_ns: int, lead_ns: int) -> int:
    """An onset: integer ns, at least ``lead_ns`` and at most `MAX_AHEAD_NS` ahead of now."""
    at_ns = time_ns(call, "at_ns", value)
    ahead_ns = at_ns - now_ns
    if ahead_ns < 0:
        raise PinArrayError(f"{call}: at_ns {at_ns} had passed {-ahead_ns / 1e6:.1f} ms ago on "
                            f"the array's clock ({now_ns} ns): arm it at least "
                            f"{lead_ns / 1e6:g} ms ahead")
    if ahead_ns < lead_ns:
        ahead_ms = f"{ahead_ns / 1e6:.1f}"
        if float(ahead_ms) >= lead_ns / 1e6:  # 19.98 ms is not "20.0 ms", short of 20 ms
            ahead_ms = f"{ahead_ns / 1e6:.3f}"
        raise PinArrayError(f"{call}: at_ns {at_ns} is only {ahead_ms} ms ahead of the array's "
                            f"clock ({now_ns} ns): arm it at least {lead_ns / 1e6:g} ms ahead")
    if ahead_ns > MAX_AHEAD_NS:
        raise PinArrayError(f"{call}: at_ns {at_ns} is {ahead_ns / 1e9:.1f} s ahead of the "
                            f"array's clock ({now_ns} ns): at most {MAX_AHEAD_NS / 1e9:g} s "
                            "ahead (is it in ns?)")
    return at_ns


def timeout_s(call: str, value: object, name: str = "timeout_s") -> float | None:
    """A wait's limit in seconds: 0 up to the longest a wait can take
    (`threading.TIMEOUT_MAX`, some 292 years), or None (no limit)."""
    if value is None:
        return None
    if is_real(value):
        seconds = float(value)
        if math.isfinite(seconds) and 0 <= seconds <= threading.TIMEOUT_MAX:
            return seconds
    refuse(call, name, "a number of seconds from 0 (up to the longest wait this system has), "
                       "or None", value)


def pin(call: str, value: object) -> int:
    if not is_int(value) or not 1 <= value <= 16:
        refuse(call, "pin", "a pin number from 1 to 16 (int)", value)
    return int(value)


def optional_pin(call: str, value: object) -> int | None:
    return None if value is None else pin(call, value)


def frequency_hz(call: str, value: object) -> float | Fraction | None:
    """A frequency above 0 Hz: a whole number or a Fraction exactly, any other real number
    as a float (numpy's too)."""
    if value is None:
        return None
    if is_real(value) and math.isfinite(value) and value > 0:
        if is_int(value):
            return Fraction(int(value))
        return value if isinstance(value, Fraction) else float(value)
    refuse(call, "frequency_hz", "a finite frequency above 0 Hz (a number)", value)


def seed(call: str, value: object) -> int | None:
    if value is None:
        return None
    if not is_int(value) or not 0 <= value <= MAX_SEED:
        refuse(call, "seed", "an int from 0 to 2^63 - 1, or None", value)
    return int(value)


def flag(call: str, name: str, value: object) -> bool:
    if not isinstance(value, bool):
        refuse(call, name, "True or False", value)
    return value


def label(call: str, name: str, value: object) -> str:
    """A BIDS label (a subject's, a session's): letters and digits only."""
    from pinarray.journal.paths import LabelError, check_label

    try:
        return check_label(name, text(call, name, value))
    except LabelError:
        refuse(call, name, "letters and digits only (a BIDS label: no spaces, dots, slashes, "
                           "dashes or underscores)", value)


def answer(call: str, value: object) -> str | int | None:
    """What an answer source gave: a name (str), a whole number (a pin, a count) or None;
    never a bool (True is 1 to Python, never a pin) nor a number with a fraction (6.7 is not
    pin 6)."""
    if value is None or isinstance(value, str):
        return value
    if is_int(value):
        return int(value)
    if is_real(value) and math.isfinite(value) and float(value).is_integer():
        return int(value)
    refuse(call, "answer", "a pin's number or a count (a whole number), a name (str) or None",
           value)


def answer_source(call: str, value: object) -> Callable[..., Any]:
    if not callable(value):
        refuse(call, "answer", "a function taking a Question and returning an answer", value)
    return value


def paths(call: str, values: tuple[object, ...]) -> tuple[str, ...]:
    if not values:
        raise PinArrayError(f"{call}: expected at least one results file or folder, found none")
    return tuple(path(call, "path", value) for value in values)


def port_list(call: str, value: object) -> tuple[str, ...] | None:
    if value is None:
        return None
    if isinstance(value, str) or not isinstance(value, list | tuple):
        refuse(call, "ports", "a list of serial devices or sim:// URLs, or None", value)
    for item in value:
        if not isinstance(item, str) or not item:
            refuse(call, "ports", "a list of serial devices or sim:// URLs (str)", item)
    return tuple(value)
