"""What a simulated bus is told to be: its servos, wire settings, physics and injected faults.

A simulated bus is named by a URL, in the style of pyserial's ``loop://``::

    sim://?ids=1-16&baud=1000000&return_delay_us=500&drop=0.01&corrupt=0.01
          &missing=3,7&extra=17&overload=5&overheat=6&voltage=7&vanish_after=500&seed=1

Every key is optional:

``ids``             servo ids on the bus, ranges and commas (default ``1-16``)
``baud``            bit/s the servos listen at (one of the STS rates 38400 ... 1000000);
                    default: the host's speed when it first talks (in-process), else 1000000
``return_delay_us`` each servo's answer delay, 0-508 us in 2 us steps (default 500, factory)
``model``           servo model/variant: sts3215 (7.4 V, default), sts3215-12v, sts3250
``supply_v``        supply voltage in volts (default: the model's nominal); speed scales with it
                    and a supply outside the voltage-limit registers sets the voltage error bit
``backlash_deg``    free play of each horn in degrees (default: the model's, about 1 deg)
``load``            steady load as a fraction of stall torque, -1 to 1 (> 0 presses horns
                    toward lower step counts and slows motion against it)
``speed``           the horns' top speed in steps/s, 1 to 10000 (default: the model's at the
                    supply voltage): a worn, hot or under-volted servo, e.g. ``speed=1500``
``drop``            probability that an instruction packet is lost on the wire (no effect,
                    no answer)
``drop_writes``     probability that a WRITE, REG_WRITE or SYNC_WRITE is lost (reads still work)
``corrupt``         probability that a status packet arrives with a wrong checksum
``late``            probability that a status packet arrives ``late_ms`` late
``late_ms``         how late a late status packet is, in ms (default 100: after any host gave up)
``missing``         ids listed in ``ids`` that do not answer (unplugged)
``extra``           ids that answer although nobody expects them
``overload``, ``overheat``, ``voltage``, ``angle``, ``overcurrent``
                    ids whose status packets carry that error bit
``vanish_after``    the port disappears after this many instruction packets (USB unplugged)
``seed``            random seed for the random faults (default 0), so they are reproducible
``fidelity``        how closely it is simulated (`pinarray.hardware.feetech.sim_levels`):
                    ``wire`` (every byte at its time), ``packet`` (each exchange computed whole;
                    the same results), ``motion`` (the pins' motion samples computed, not read;
                    no faults); default ``packet`` in-process, ``wire`` behind `sim-serve`
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from urllib.parse import urlsplit

from pinarray.errors import PinArrayError
from pinarray.hardware.feetech.models import DEFAULT_MODEL, MODELS
from pinarray.hardware.feetech.registers import BAUD_RATE_BY_CODE, MAX_SERVO_ID, StatusError
from pinarray.hardware.feetech.sim_levels import Fidelity
from pinarray.hardware.sim_urls import sim_query

SIM_SCHEME = "sim"
# The simulated array every command uses unless told otherwise.
SIM_DEFAULT = f"{SIM_SCHEME}://"
MAX_RETURN_DELAY_US = 508  # register 7 holds 0-254 in 2 us units
MAX_LATE_MS = 60_000.0
MAX_VANISH_AFTER = 10**12
MAX_SEED = 2**63 - 1
MAX_SUPPLY_V = 25.4  # the present-voltage register holds 0-254 x 0.1 V
MAX_BACKLASH_DEG = 10.0
MAX_SPEED_STEPS_PER_S = 10_000.0

_ERROR_KEYS = {
    "overload": StatusError.OVERLOAD,
    "overheat": StatusError.OVERHEAT,
    "voltage": StatusError.VOLTAGE,
    "angle": StatusError.ANGLE_SENSOR,
    "overcurrent": StatusError.OVERCURRENT,
}
_PROBABILITY_KEYS = {
    "drop": "drop_rate",
    "drop_writes": "drop_write_rate",
    "corrupt": "corrupt_rate",
    "late": "late_rate",
}


def _check(key: str, value: float, low: float, high: float, unit: str = "") -> None:
    if not (math.isfinite(value) and low <= value <= high):
        raise PinArrayError(
            f"sim URL key {key}: expected {low:g} to {high:g}{unit}, found {value!r}"
        )


@dataclass(frozen=True)
class Faults:
    """Faults a simulated bus injects.

    Attributes
    ----------
    drop_rate : float
        Probability, 0-1, that an instruction packet is lost on the wire.
    drop_write_rate : float
        Probability, 0-1, that a write-type packet (WRITE, REG_WRITE, SYNC_WRITE) is lost.
    corrupt_rate : float
        Probability, 0-1, that a status packet arrives with a wrong checksum.
    late_rate : float
        Probability, 0-1, that a status packet arrives ``late_ms`` late.
    late_ms : float
        Lateness of a late status packet, in milliseconds.
    missing_ids : frozenset of int
        Servo ids that never answer.
    error_bits : tuple of (int, StatusError)
        Servo id and the error bits its status packets carry.
    vanish_after_packets : int or None
        The port disappears after this many instruction packets.
    seed : int
        Seed of the random source deciding every random fault.
    """

    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    missing_ids: frozenset[int] = frozenset()
    error_bits: tuple[tuple[int, StatusError], ...] = ()
    vanish_after_packets: int | None = None
    seed: int = 0
    drop_write_rate: float = 0.0
    late_rate: float = 0.0
    late_ms: float = 100.0

    def __post_init__(self) -> None:
        for key, name in _PROBABILITY_KEYS.items():
            _check(key, getattr(self, name), 0.0, 1.0, " (a probability)")
        _check("late_ms", self.late_ms, 0.0, MAX_LATE_MS, " ms")
        if self.vanish_after_packets is not None:
            _check("vanish_after", self.vanish_after_packets, 0, MAX_VANISH_AFTER, " packets")
        _check("seed", self.seed, 0, MAX_SEED)

    @property
    def late_ns(self) -> int:
        return round(self.late_ms * 1_000_000)

    @property
    def injects(self) -> bool:
        """Whether any fault happens: a seed, or how late a late answer would be, alone
        injects nothing."""
        return self != replace(Faults(), seed=self.seed, late_ms=self.late_ms)


@dataclass(frozen=True)
class SimConfig:
    """A simulated bus: which servos answer, how fast the wire is, their physics, the faults.

    ``baud_rate`` None: the servos listen at whatever speed the host first uses (in-process),
    or at the factory 1000000 bit/s behind a pseudo-terminal. ``supply_v`` and
    ``backlash_deg`` None: the model's own values.
    """

    ids: tuple[int, ...] = tuple(range(1, 17))
    baud_rate: int | None = None
    return_delay_us: int = 500
    faults: Faults = field(default_factory=Faults)
    model: str = DEFAULT_MODEL
    supply_v: float | None = None
    backlash_deg: float | None = None
    load_fraction: float = 0.0
    speed_steps_per_s: float | None = None  # None: the model's at the supply voltage
    fidelity: Fidelity | None = None  # None: the level the use defaults to

    def __post_init__(self) -> None:
        if self.baud_rate is not None and self.baud_rate not in BAUD_RATE_BY_CODE:
            rates = ", ".join(map(str, sorted(BAUD_RATE_BY_CODE)))
            raise PinArrayError(
                f"sim URL key baud: expected one of the STS rates {rates}, found {self.baud_rate!r}"
            )
        _check("return_delay_us", self.return_delay_us, 0, MAX_RETURN_DELAY_US, " us")
        if self.model.lower() not in MODELS:
            raise PinArrayError(
                f"sim URL key model: expected one of {', '.join(MODELS)}, found {self.model!r}"
            )
        if self.supply_v is not None:
            _check("supply_v", self.supply_v, 0.1, MAX_SUPPLY_V, " V")
        if self.backlash_deg is not None:
            _check("backlash_deg", self.backlash_deg, 0.0, MAX_BACKLASH_DEG, " deg")
        _check("load", self.load_fraction, -1.0, 1.0, " (a fraction of stall torque)")
        if self.speed_steps_per_s is not None:
            _check("speed", self.speed_steps_per_s, 1.0, MAX_SPEED_STEPS_PER_S, " steps/s")
        if self.fidelity is Fidelity.MOTION and self.faults.injects:
            raise PinArrayError(
                "sim URL key fidelity: motion computes every motion sample and injects no "
                "faults; expected fidelity=packet or wire with faults, found fidelity=motion")

    @property
    def answering_ids(self) -> tuple[int, ...]:
        return tuple(i for i in self.ids if i not in self.faults.missing_ids)


def parse_ids(text: str, allow_none: bool = False) -> tuple[int, ...]:
    """``"1-4,7,9-10"`` -> ``(1, 2, 3, 4, 7, 9, 10)``; ids must be 0-252.

    The one reader of servo id lists (command-line options and sim URL keys). An empty list
    (``""``, ``","``) is refused unless ``allow_none``: where servos are named, naming none
    is a mistake, not "all of them".
    """
    ids: list[int] = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        low, _, high = part.partition("-")
        try:
            if not part.isascii():  # int() reads other scripts' digits (１)
                raise ValueError(part)
            first, last = int(low), int(high or low)
        except ValueError:
            raise PinArrayError(
                f"expected servo ids such as '1-16' or '1,3,5', found {text!r}"
            ) from None
        if not 0 <= first <= last <= MAX_SERVO_ID:
            raise PinArrayError(
                f"expected servo ids 0-{MAX_SERVO_ID} in rising ranges, found {part!r}"
            )
        ids.extend(range(first, last + 1))
    if not ids and not allow_none:
        raise PinArrayError(f"expected at least one servo id 0-{MAX_SERVO_ID}, found {text!r}")
    return tuple(dict.fromkeys(ids))


def is_sim_url(url: str) -> bool:
    return url.startswith(f"{SIM_SCHEME}://")


_NUMBER_KEYS = {
    "baud": int, "return_delay_us": int, "supply_v": float, "backlash_deg": float,
    "load": float, "drop": float, "drop_writes": float, "corrupt": float, "late": float,
    "late_ms": float, "vanish_after": int, "seed": int, "speed": float,
}
_KNOWN_KEYS = {"ids", "missing", "extra", "model", "fidelity", *_NUMBER_KEYS, *_ERROR_KEYS}


def parse_sim_url(url: str) -> SimConfig:
    """Read a ``sim://?...`` URL (grammar in the module docstring) into a `SimConfig`.

    Raises
    ------
    PinArrayError
        One line naming the URL and the key for an unknown key, a value that is not a
        number, or a number out of its range.
    """
    parts = urlsplit(url)
    if parts.scheme != SIM_SCHEME:
        raise PinArrayError(f"expected a sim:// URL, found {url!r}")
    if parts.netloc or parts.path:  # sim://pca9685 is a board's; a typo of it no one's
        board = " (sim://pca9685 simulates a PCA9685 board, not STS servos)" \
            if parts.netloc.lower() == "pca9685" else ""
        raise PinArrayError(f"{url}: expected simulated STS servos as sim:// or "
                            f"sim://?KEY=VALUE&..., found {parts.netloc + parts.path!r} after "
                            f"sim://{board}")
    query = sim_query(url, parts.query)
    unknown = sorted(set(query) - _KNOWN_KEYS)
    if unknown:
        raise PinArrayError(
            f"{url}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_KNOWN_KEYS))}"
        )
    numbers: dict[str, int | float] = {}
    for key, kind in _NUMBER_KEYS.items():
        if key in query:
            try:
                if not query[key].isascii():  # int() and float() read other scripts' digits
                    raise ValueError(query[key])
                numbers[key] = kind(query[key])
            except ValueError:
                what = "a whole number" if kind is int else "a number"
                raise PinArrayError(
                    f"{url}: sim URL key {key}: expected {what}, found {query[key]!r}"
                ) from None
    def ids_of(key: str, default: str = "") -> tuple[int, ...]:
        try:
            return parse_ids(query.get(key, default), allow_none=key != "ids")
        except PinArrayError as error:
            raise PinArrayError(f"{url}: sim URL key {key}: {error}") from None

    ids = ids_of("ids", "1-16") + ids_of("extra")
    missing = frozenset(ids_of("missing"))
    error_bits: dict[int, StatusError] = {}
    for key, bit in _ERROR_KEYS.items():
        for servo_id in ids_of(key):
            error_bits[servo_id] = error_bits.get(servo_id, StatusError(0)) | bit
    try:
        faults = Faults(
            missing_ids=missing,
            error_bits=tuple(sorted(error_bits.items())),
            vanish_after_packets=numbers.get("vanish_after"),  # type: ignore[arg-type]
            seed=int(numbers.get("seed", 0)),
            late_ms=float(numbers.get("late_ms", Faults.late_ms)),
            **{name: float(numbers.get(key, 0.0)) for key, name in _PROBABILITY_KEYS.items()},
        )
        return SimConfig(
            ids=tuple(dict.fromkeys(ids)),
            baud_rate=numbers.get("baud"),  # type: ignore[arg-type]
            return_delay_us=int(numbers.get("return_delay_us", 500)),
            faults=faults,
            model=query.get("model", DEFAULT_MODEL),
            supply_v=numbers.get("supply_v"),
            backlash_deg=numbers.get("backlash_deg"),
            load_fraction=float(numbers.get("load", 0.0)),
            speed_steps_per_s=numbers.get("speed"),
            fidelity=_fidelity(query.get("fidelity")),
        )
    except PinArrayError as error:
        raise PinArrayError(f"{url}: {error}") from None



def _fidelity(text: str | None) -> Fidelity | None:
    if text is None:
        return None
    try:
        return Fidelity(text)
    except ValueError:
        levels = ", ".join(level.value for level in Fidelity)
        raise PinArrayError(f"sim URL key fidelity: expected one of {levels}, found {text!r}"
                            ) from None
