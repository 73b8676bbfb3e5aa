"""Tap counting: one pin taps a few times; how many? A lab's own paradigm for pinarray.

The package is the paradigm's room: ``design`` (its conditions and how its design section is
read), ``rows`` (its results), ``observer`` (its simulated subject) and ``analysis`` (what its
rows show). Its `PARADIGM` is what pinarray finds by the entry point in pyproject.toml
(group ``pinarray.paradigms``): the design here, the rows and analysis imported when first
asked for (`pinarray.paradigms.base.Room`), so that ``pinarray validate`` stays quick.
"""

from __future__ import annotations

from pinarray.paradigms.base import Room
from pinarray_tap_count.design import TapCountCondition, TapCountDesign

__all__ = ["PARADIGM", "TapCountCondition", "TapCountParadigm"]


# --8<-- [start:paradigm]
class TapCountParadigm(Room, TapCountDesign):
    """Tap counting (`pinarray.Paradigm`)."""


PARADIGM = TapCountParadigm()
# --8<-- [end:paradigm]
