"""pinarray's pytest plugin (entry point ``pytest11``): the ``simulated_array`` fixture.

pytest loads this module wherever pinarray is installed, so it imports pytest and nothing
else: the array and numpy are imported by the first test that opens one.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from pinarray.testing import ArrayOpener


@pytest.fixture
def simulated_array() -> Iterator[ArrayOpener]:
    """Opens protocols' arrays on simulated servos in virtual time; after the test each is
    closed (pins to rest, torque off). See `pinarray.testing.ArrayOpener`."""
    with ArrayOpener() as opener:
        yield opener


def pytest_report_header(config: pytest.Config) -> str:
    """The header line that says how closely ``simulated_array`` simulates the array."""
    from pinarray.hardware.feetech.sim_levels import IN_PROCESS_DEFAULT, Fidelity

    others = ", ".join(level.value for level in Fidelity if level is not IN_PROCESS_DEFAULT)
    return (f"pinarray: simulated_array plays bus servos in virtual time at the "
            f"{IN_PROCESS_DEFAULT.describe()} (the wire's results, byte for byte; a URL's "
            f"fidelity= chooses {others})")
