"""The query of a ``sim://`` URL (simulated bus servos or PCA9685 boards): each key once."""

from __future__ import annotations

from urllib.parse import parse_qsl

from pinarray.errors import PinArrayError


def sim_query(url: str, query: str) -> dict[str, str]:
    """``query`` (of ``url``) as key -> value; a key given twice is refused, naming it, rather
    than one of its values silently kept (``address=0x40&address=0x41``: list them,
    ``address=0x40,0x41``)."""
    pairs = parse_qsl(query, keep_blank_values=True)
    found: dict[str, str] = {}
    for key, value in pairs:
        if key in found:
            raise PinArrayError(f"{url}: sim URL key {key}: expected it once (a list: values "
                                f"separated by commas), found it twice: {found[key]!r} and "
                                f"{value!r}")
        found[key] = value
    return found
