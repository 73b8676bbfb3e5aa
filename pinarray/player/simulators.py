"""The simulated arrays of one program run, kept from one connection to the next.

Real servos keep their state when the port closes: releasing them only turns torque off, and
what was written to them until power-off (a lowered return delay, a new id) stays. A
simulated array opened again by the same program (the pre-flight's "Connect again", the next
run of a batch) is therefore the one the last connection left, not a factory-new one. And how
closely a simulated array is simulated (`simulation_level`), for a command to say so.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    from pinarray.hardware.driver import ArrayDriver

T = TypeVar("T")


class SimulatedArrays:
    """Simulators by their ``sim://`` URL: one URL, one simulated array for the whole run.

    Each family's entry in `pinarray.player.families` keeps the simulator it opened and finds
    it again for the next connection to the same URL.
    """

    def __init__(self) -> None:
        self._by_url: dict[str, object] = {}

    def find(self, url: str, kind: type[T]) -> T | None:
        """The ``kind`` of simulator a connection to ``url`` left, or None."""
        found = self._by_url.get(url)
        return found if isinstance(found, kind) else None

    def keep(self, url: str, simulator: object) -> None:
        """Remember ``simulator`` for the next connection to ``url``."""
        self._by_url[url] = simulator


def simulation_level(driver: ArrayDriver) -> str | None:
    """How closely ``driver``'s array is simulated, in words (None: real hardware, or a
    simulator behind a port, which carries every byte).

    Simulated bus servos run at the level their URL names, or the packet level
    (`pinarray.hardware.feetech.sim_levels`); a simulated PWM board at its only one.
    """
    from pinarray.hardware.feetech.feetech import FeetechBus

    if isinstance(driver, FeetechBus):
        from pinarray.hardware.feetech.transport import fidelity_of

        level = fidelity_of(driver)
        return None if level is None else level.describe()
    from pinarray.hardware.pca9685.driver import Pca9685Array
    from pinarray.hardware.pca9685.sim import SimI2cLink

    if isinstance(driver, Pca9685Array) and isinstance(driver.link, SimI2cLink):
        return "every I2C message to the board's registers"
    return None
