"""Two-point discrimination: one pin or two at a distance; one point or two?

The room: `design` (its conditions and how its design section is read; pure), `rows` (its
results' records and columns), `analysis` (the threshold distance, in mm from the grid's
pitch) and `observer` (its simulated subject).
"""

from __future__ import annotations

from pinarray.paradigms.base import Room
from pinarray.paradigms.two_point.design import TwoPointDesign


class TwoPointParadigm(Room, TwoPointDesign):
    """The paradigm (`pinarray.paradigms.base.Paradigm`): its design here, its rows and
    analysis imported when first asked for."""


PARADIGM = TwoPointParadigm()
