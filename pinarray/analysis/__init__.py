"""Analysis of results files: statistics (`stats`), reading (`load`), figures (`plots`) and the
report folder (`report`). Importing this package is cheap: numpy and matplotlib load only
when a function needs them.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pinarray.analysis.stats import Summary
    from pinarray.journal.records import TrialRecord


def summary(records: Iterable[TrialRecord]) -> Summary:
    """Statistics of one session's trial rows, e.g. for the end-of-session screen."""
    from pinarray.analysis.stats import summarise

    return summarise(list(records), group="session")


def summary_lines(records: Iterable[TrialRecord]) -> list[str]:
    """The end-of-session numbers as short lines of text, one per frequency and for motion."""
    numbers = summary(records)
    lines = []
    for row in numbers.localisation:
        low, high = row.correct.interval_pct
        errors = ", ".join(f"{c} {row.error_pct(c):.0f} %" for c in "ABCD")
        if row.none_felt:  # its own category, shown whenever it happened
            errors += f", nothing felt {row.share('none').pct:.0f} %"
        lines.append(
            f"{row.frequency_hz:g} Hz: {row.correct.pct:.1f} % correct "
            f"({row.correct.successes}/{row.trials}, 95 % CI {low:.0f}-{high:.0f} %); {errors}"
        )
    motion = numbers.motion
    if motion.felt.trials:
        lines.append(f"motion felt on {motion.felt.pct:.0f} % of wave trials "
                     f"({motion.felt.successes}/{motion.felt.trials})")
        if motion.direction_right.trials:
            lines.append(f"direction right on {motion.direction_right.pct:.0f} % of those "
                         f"({motion.direction_right.successes}/{motion.direction_right.trials})")
    return lines or ["no counted trials"]
