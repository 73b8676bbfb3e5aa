"""Analysis of results files: reading (`load`), each paradigm's findings through the paradigm
seam (`seam`), the adaptive designs' thresholds (`thresholds`), figures (`figures`, `plots`) and
the report folder (`report`). Importing this package is cheap: numpy and matplotlib load only
when a function needs them.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pinarray.journal.records import TrialRecord


def summary_lines(records: Iterable[TrialRecord]) -> list[str]:
    """The end-of-session numbers as short lines of text, each paradigm's as its room says
    them (`pinarray.analysis.seam.ParadigmAnalysis.session_lines`)."""
    from pinarray.analysis.seam import analysis_of

    by_paradigm: dict[str, list[TrialRecord]] = {}
    for record in records:
        by_paradigm.setdefault(record.paradigm, []).append(record)
    lines = [line for name, rows in by_paradigm.items()
             for line in analysis_of(name).session_lines(rows)]
    return lines or ["no counted trials"]
