"""Two-interval forced choice: a standard and a comparison; which interval had more?

The room: `design` (its conditions and how its design section is read; pure), `rows` (its
results' records and columns), `analysis` (what its rows show) and `observer` (its
simulated subject).
"""

from __future__ import annotations

from pinarray.paradigms.base import Room
from pinarray.paradigms.two_interval.design import TwoIntervalDesign


class TwoIntervalParadigm(Room, TwoIntervalDesign):
    """The paradigm (`pinarray.paradigms.base.Paradigm`): its design here, its rows and
    analysis imported when first asked for."""


PARADIGM = TwoIntervalParadigm()
