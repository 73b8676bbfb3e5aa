"""Apparent motion: a wave along pins; did a dot move, and which way? (the seed's second experiment)

The room: `design` (its conditions and how its design section is read; pure), `rows` (its
results' records and columns), `analysis` (what its rows show) and `observer` (its
simulated subject).
"""

from __future__ import annotations

from pinarray.paradigms.apparent_motion.design import ApparentMotionDesign
from pinarray.paradigms.base import Room


class ApparentMotionParadigm(Room, ApparentMotionDesign):
    """The paradigm (`pinarray.paradigms.base.Paradigm`): its design here, its rows and
    analysis imported when first asked for."""


PARADIGM = ApparentMotionParadigm()
