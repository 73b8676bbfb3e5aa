"""Paradigms for scripts: each paradigm's conditions and records, as its room defines them.

A trial presents a `Condition` and its row is a `TrialRecord`; each paradigm has a type of each
of its own (`LocalisationCondition` and `LocalisationRecord`, ...), which a script matches on
(``match record: case LocalisationRecord(pin=pin): ...``) or checks with ``isinstance``. A
lab's own paradigm, in a package of its own, has its own too (see the documentation's "Adding
a paradigm"), which implements `Paradigm`: the seam every paradigm's room implements.
"""

from __future__ import annotations

from pinarray.paradigms.apparent_motion.design import MotionCondition
from pinarray.paradigms.apparent_motion.rows import MotionRecord
from pinarray.paradigms.base import Paradigm
from pinarray.paradigms.identification.design import IdentificationCondition
from pinarray.paradigms.identification.rows import IdentificationRecord
from pinarray.paradigms.localisation.design import LocalisationCondition
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.paradigms.temporal_order.design import TemporalOrderCondition
from pinarray.paradigms.temporal_order.rows import TemporalOrderRecord
from pinarray.paradigms.two_interval.design import TwoIntervalCondition
from pinarray.paradigms.two_interval.rows import TwoIntervalRecord
from pinarray.paradigms.two_point.design import TwoPointCondition
from pinarray.paradigms.two_point.rows import TwoPointRecord

__all__ = ["IdentificationCondition", "IdentificationRecord", "LocalisationCondition",
           "LocalisationRecord", "MotionCondition", "MotionRecord", "Paradigm", "TemporalOrderCondition",
           "TemporalOrderRecord", "TwoIntervalCondition", "TwoIntervalRecord",
           "TwoPointCondition", "TwoPointRecord"]
