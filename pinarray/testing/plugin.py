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
