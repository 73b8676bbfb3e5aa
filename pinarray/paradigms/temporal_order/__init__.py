"""Temporal-order judgement: two pins tap; which came first?

The room: `design` (its conditions and how its design section is read; pure), `rows` (its
results' records and columns), `analysis` (what its rows show) and `observer` (its
simulated subject).
"""

from __future__ import annotations

from pinarray.paradigms.base import Room
from pinarray.paradigms.temporal_order.design import TemporalOrderDesign


class TemporalOrderParadigm(Room, TemporalOrderDesign):
    """The paradigm (`pinarray.paradigms.base.Paradigm`): its design here, its rows and
    analysis imported when first asked for."""


PARADIGM = TemporalOrderParadigm()
