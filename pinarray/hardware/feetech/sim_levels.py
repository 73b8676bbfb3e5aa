"""How closely a simulated STS bus is simulated: the fidelity ladder, chosen by ``sim://?fidelity=``.

Every level drives the same simulated servos (`pinarray.hardware.feetech.sim.SimBus`: control
tables, instructions, faults, closed-form motion) and reports the same `DeliveryRecord`,
strokes and verdicts; they differ in what is worked out on the way, and so in run time:

``wire``
    Byte-faithful: every byte crosses a simulated wire at the baud rate and reaches the host
    at its own arrival time (`pinarray.hardware.feetech.sim_serial.SimSerial`); replies are
    found in the bytes as on a real port. Where the wire is the point: `sim-serve` (a third
    party reads the bytes), and the tests of the link itself.
``packet``
    No bytes while nothing on the wire could differ: each exchange is computed whole (the
    request carried out, each answer whole when its last byte would arrive), and falls back
    to bytes whenever they matter (an answer corrupted or made late, bytes still on their
    way, a port about to vanish). The same files, byte for byte, as ``wire``
    (`tests/benchmarks/bench_fidelity.py` checks it). The in-process default: `pinarray
    batch`, `play`, the UI and ``--speed 0``, and the ``simulated_array`` fixture.
``motion``
    No exchange for the motion samples: the moving pins' positions are computed from the
    servo model at the instants the player would sample them, every
    `pinarray.hardware.feetech.readback.SAMPLE_PERIOD_NS` in
    the slack between frames (none held back while the pins hold, as the other levels do);
    goals, read-backs, heals and telemetry as ``packet``. Delivery and verdicts as the other
    levels; strokes and lags from more samples, so they may differ by a step or a sampling
    period (the benchmark measures by how much). No faults: refused with one.
"""

from __future__ import annotations

from enum import StrEnum


class Fidelity(StrEnum):
    """A level of the ladder (see the module docstring), from the finest."""

    WIRE = "wire"
    PACKET = "packet"
    MOTION = "motion"

    def describe(self) -> str:
        """The level in a few words, for a command's report."""
        return _WORDS[self]


_WORDS = {
    Fidelity.WIRE: "wire level: every byte at its time",
    Fidelity.PACKET: "packet level: exchanges computed whole",
    Fidelity.MOTION: "motion level: motion samples computed",
}

# What an in-process simulation runs at unless its URL says: the cheapest level whose results
# are those of the wire, byte for byte.
IN_PROCESS_DEFAULT = Fidelity.PACKET
