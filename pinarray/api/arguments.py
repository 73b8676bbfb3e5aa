"""Arguments checked at the door of every public call: a wrong one is a one-line
`PinArrayError` in the library's words (``open_array: sim: expected a sim:// URL (str),
found 5 (int)``), raised before anything is opened, moved or written, never a `TypeError`
from deep inside.

Times are integer nanoseconds (a float would lose nanoseconds past 104 days of a clock and
poison a virtual one); numbers are finite; an onset lies within `MAX_AHEAD_NS` of now.
"""

from __future__ import annotations

import math
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


def found(value: object) -> str:
    """A value as a message shows what was found: its repr (shortened) and its type."""
    if isinstance(value, int) and value.bit_length() > 200:  # repr fails past 4300 digits
        return f"an int of {value.bit_length()} bits ({type(value).__name__})"
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    return f"{shown} ({type(value).__name__})"


def refuse(call: str, name: str, expected: str, value: object) -> NoReturn:
    raise PinArrayError(f"{call}: {name}: expected {expected}, found {found(value)}")


def is_int(value: object) -> TypeGuard[int]:
    """An int, not a bool (True is 1 to Python, never a pin or a time to a lab)."""
    return isinstance(value, int) and not isinstance(value, bool)


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


def path(call: str, name: str, value: object) -> str:
    """A file or folder's path: a str or path-like (not bytes)."""
    if isinstance(value, str | PathLike):
        as_text = fspath(value)
        if isinstance(as_text, str) and as_text:
            return as_text
    refuse(call, name, "a path (a non-empty str or path-like)", value)


def port(call: str, value: object) -> str | None:
    if value is None:
        return None
    if isinstance(value, PathLike):
        value = fspath(value)
    if not isinstance(value, str) or not value or "\0" in value:
        refuse(call, "port", "a serial device's path such as '/dev/ttyUSB0' (str)", value)
    if value.startswith("sim://"):
        raise PinArrayError(f"{call}: port: {value!r} is a simulated array: give it as sim=")
    return value


def sim_url(call: str, value: object) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.startswith("sim://"):
        refuse(call, "sim", "a sim:// URL such as 'sim://?drop_writes=0.1&seed=3' (str)", value)
    return value


def sim_for(call: str, protocol: Protocol, value: object) -> str | None:
    """A ``sim://`` URL of the protocol's kind of servos, read as the script wrote it (its
    problems in its own words, before pinarray adds the protocol's servo ids to it)."""
    from pinarray.hardware.pca9685.sim import is_pca9685_url
    from pinarray.protocol.model import HobbyServos

    url = sim_url(call, value)
    if url is None:
        return None
    board = isinstance(protocol.device.servo, HobbyServos)
    if board != is_pca9685_url(url):
        wanted = ("a sim://pca9685 URL: its device is a PWM board" if board else
                  "a sim:// URL of bus servos (not sim://pca9685): its device is STS servos")
        raise PinArrayError(f"{call}: sim: protocol {protocol.name!r} takes {wanted}, found "
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
    """A time on the array's clock: an int of nanoseconds."""
    if not is_int(value):
        hint = (f" (as an int: {round(value)})" if isinstance(value, float) and math.isfinite(value)
                else "")
        refuse(call, name, f"a time in integer nanoseconds{hint}", value)
    return value


def onset_ns(call: str, value: object, now_ns: int, lead_ns: int) -> int:
    """An onset: integer ns, at least ``lead_ns`` and at most `MAX_AHEAD_NS` ahead of now."""
    at_ns = time_ns(call, "at_ns", value)
    ahead_ns = at_ns - now_ns
    if ahead_ns < lead_ns:
        raise PinArrayError(f"{call}: at_ns {at_ns} is {ahead_ns / 1e6:.1f} ms ahead of the "
                            f"array's clock ({now_ns} ns): arm it at least {lead_ns / 1e6:g} ms "
                            "ahead")
    if ahead_ns > MAX_AHEAD_NS:
        raise PinArrayError(f"{call}: at_ns {at_ns} is {ahead_ns / 1e9:.1f} s ahead of the "
                            f"array's clock ({now_ns} ns): at most {MAX_AHEAD_NS / 1e9:g} s "
                            "ahead (is it in ns?)")
    return at_ns


def timeout_s(call: str, value: object) -> float | None:
    if value is None:
        return None
    if is_int(value) or isinstance(value, float | Fraction):
        seconds = float(value)
        if math.isfinite(seconds) and seconds >= 0:
            return seconds
    refuse(call, "timeout_s", "a finite number of seconds, 0 or more, or None", value)


def pin(call: str, value: object) -> int:
    if not is_int(value) or not 1 <= value <= 16:
        refuse(call, "pin", "a pin number from 1 to 16 (int)", value)
    return value


def optional_pin(call: str, value: object) -> int | None:
    return None if value is None else pin(call, value)


def frequency_hz(call: str, value: object) -> float | Fraction | None:
    if value is None:
        return None
    if (is_int(value) or isinstance(value, float | Fraction)) and math.isfinite(value) \
            and value > 0:
        return value if isinstance(value, float | Fraction) else Fraction(value)
    refuse(call, "frequency_hz", "a finite frequency above 0 Hz (a number)", value)


def seed(call: str, value: object) -> int | None:
    if value is None:
        return None
    if not is_int(value) or not 0 <= value <= MAX_SEED:
        refuse(call, "seed", "an int from 0 to 2^63 - 1, or None", value)
    return value


def flag(call: str, name: str, value: object) -> bool:
    if not isinstance(value, bool):
        refuse(call, name, "True or False", value)
    return value


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
