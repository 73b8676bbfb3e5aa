"""What a simulated bus is told to be: its servos, wire settings and injected faults.

A simulated bus is named by a URL, in the style of pyserial's ``loop://``::

    sim://?ids=1-16&baud=1000000&return_delay_us=500&drop=0.01&corrupt=0.01
          &missing=3,7&extra=17&overload=5&overheat=6&voltage=7&vanish_after=500&seed=1

Every key is optional:

``ids``             servo ids on the bus, ranges and commas (default ``1-16``)
``baud``            wire speed in bit/s (default: the protocol's baud rate); 10 bits a byte
``return_delay_us`` each servo's answer delay in microseconds (default 500, the factory value)
``drop``            probability that an instruction packet is lost on the wire (no effect,
                    no answer)
``corrupt``         probability that a status packet arrives with a wrong checksum
``missing``         ids listed in ``ids`` that do not answer (unplugged)
``extra``           ids that answer although nobody expects them
``overload``, ``overheat``, ``voltage``, ``angle``, ``overcurrent``
                    ids whose status packets carry that error bit
``vanish_after``    the port disappears after this many instruction packets (USB unplugged)
``seed``            random seed for drop/corrupt (default 0), so faults are reproducible
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, urlsplit

from pinarray.bus.registers import MAX_SERVO_ID, StatusError
from pinarray.errors import PinArrayError

SIM_SCHEME = "sim"
# The simulated array every command uses unless told otherwise.
SIM_DEFAULT = f"{SIM_SCHEME}://"

_ERROR_KEYS = {
    "overload": StatusError.OVERLOAD,
    "overheat": StatusError.OVERHEAT,
    "voltage": StatusError.VOLTAGE,
    "angle": StatusError.ANGLE_SENSOR,
    "overcurrent": StatusError.OVERCURRENT,
}


@dataclass(frozen=True)
class Faults:
    """Faults a simulated bus injects.

    Attributes
    ----------
    drop_rate : float
        Probability, 0-1, that an instruction packet is lost on the wire.
    corrupt_rate : float
        Probability, 0-1, that a status packet arrives with a wrong checksum.
    missing_ids : frozenset of int
        Servo ids that never answer.
    error_bits : tuple of (int, StatusError)
        Servo id and the error bits its status packets carry.
    vanish_after_packets : int or None
        The port disappears after this many instruction packets.
    seed : int
        Seed of the random source deciding drops and corruptions.
    """

    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    missing_ids: frozenset[int] = frozenset()
    error_bits: tuple[tuple[int, StatusError], ...] = ()
    vanish_after_packets: int | None = None
    seed: int = 0


@dataclass(frozen=True)
class SimConfig:
    """A simulated bus: which servos answer, how fast the wire is, which faults happen."""

    ids: tuple[int, ...] = tuple(range(1, 17))
    baud_rate: int | None = None  # None: whatever the host asks for
    return_delay_us: int = 500
    faults: Faults = field(default_factory=Faults)

    @property
    def answering_ids(self) -> tuple[int, ...]:
        return tuple(i for i in self.ids if i not in self.faults.missing_ids)


def parse_ids(text: str) -> tuple[int, ...]:
    """``"1-4,7,9-10"`` -> ``(1, 2, 3, 4, 7, 9, 10)``; ids must be 0-252."""
    ids: list[int] = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        low, _, high = part.partition("-")
        try:
            first, last = int(low), int(high or low)
        except ValueError:
            raise PinArrayError(
                f"servo ids: expected e.g. '1-16' or '1,3,5', found {text!r}"
            ) from None
        if not 0 <= first <= last <= MAX_SERVO_ID:
            raise PinArrayError(
                f"servo ids must be 0-{MAX_SERVO_ID} in rising ranges, found {part!r}"
            )
        ids.extend(range(first, last + 1))
    return tuple(dict.fromkeys(ids))


def is_sim_url(url: str) -> bool:
    return url.startswith(f"{SIM_SCHEME}://")


def parse_sim_url(url: str) -> SimConfig:
    """Read a ``sim://?...`` URL (grammar in the module docstring) into a `SimConfig`."""
    parts = urlsplit(url)
    if parts.scheme != SIM_SCHEME:
        raise PinArrayError(f"expected a sim:// URL, found {url!r}")
    query = dict(parse_qsl(parts.query, keep_blank_values=True))
    known = {"ids", "baud", "return_delay_us", "drop", "corrupt", "missing", "extra",
             "vanish_after", "seed", *_ERROR_KEYS}
    unknown = sorted(set(query) - known)
    if unknown:
        raise PinArrayError(
            f"{url}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}"
        )

    def number(key: str, kind: type, default):
        if key not in query:
            return default
        try:
            return kind(query[key])
        except ValueError:
            raise PinArrayError(f"{url}: {key} must be a number, found {query[key]!r}") from None

    ids = parse_ids(query.get("ids", "1-16")) + parse_ids(query.get("extra", ""))
    error_bits: dict[int, StatusError] = {}
    for key, bit in _ERROR_KEYS.items():
        for servo_id in parse_ids(query.get(key, "")):
            error_bits[servo_id] = error_bits.get(servo_id, StatusError(0)) | bit
    for key in ("drop", "corrupt"):
        rate = number(key, float, 0.0)
        if not 0.0 <= rate <= 1.0:
            raise PinArrayError(f"{url}: {key} is a probability 0-1, found {rate}")
    faults = Faults(
        drop_rate=number("drop", float, 0.0),
        corrupt_rate=number("corrupt", float, 0.0),
        missing_ids=frozenset(parse_ids(query.get("missing", ""))),
        error_bits=tuple(sorted(error_bits.items())),
        vanish_after_packets=number("vanish_after", int, None),
        seed=number("seed", int, 0),
    )
    return SimConfig(
        ids=tuple(dict.fromkeys(ids)),
        baud_rate=number("baud", int, None),
        return_delay_us=number("return_delay_us", int, 500),
        faults=faults,
    )
