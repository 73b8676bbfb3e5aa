"""Localisation: one pin moves at one frequency; which pin was it? (the seed's first experiment)

The room: `design` (its conditions and how its design section is read; pure), `rows` (its
results' records and columns), `analysis` (what its rows show) and `observer` (its
simulated subject).
"""

from __future__ import annotations

from pinarray.paradigms.base import Room
from pinarray.paradigms.localisation.design import LocalisationDesign


class LocalisationParadigm(Room, LocalisationDesign):
    """The paradigm (`pinarray.paradigms.base.Paradigm`): its design here, its rows and
    analysis imported when first asked for."""


PARADIGM = LocalisationParadigm()
