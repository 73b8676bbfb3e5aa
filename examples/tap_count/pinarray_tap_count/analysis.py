"""What tap-counting rows show: each subject's share of counts right, at each number of taps.

The analysis side of the paradigm seam (`pinarray.analysis.seam.ParadigmAnalysis`): its
findings from the counted rows (main trials with status ok) and its simulated subject (found
in the ``observer`` module beside this one). Every estimate carries its status: a share of
trials (`Proportion.estimate`) is *estimated* with its 95 % Wilson interval, or *not
resolved* without trials.
``pinarray analyse`` lists it in ``estimates.csv`` beside every other paradigm's, writes the
tables and figures it gives, and puts its section in ``summary.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.seam import AnalysisDefaults, Context, Findings, Reported
from pinarray.analysis.stats import Proportion
from pinarray.analysis.tables import markdown_row, write_csv
from pinarray_tap_count.rows import TapCountRecord

COLUMNS = ("subject", "task", "taps", "correct", "trials", "pct", "ci_low_pct", "ci_high_pct",
           "status")


# --8<-- [start:findings]
@dataclass(frozen=True)
class TapCounts:
    """Counts right by subject, task and taps (`pinarray.analysis.seam.Findings`)."""

    right: tuple[tuple[str, str, int, Proportion], ...]  # subject, task, taps, counted right
    paradigm: str = "tap_count"

    @property
    def trials(self) -> int:
        return sum(p.trials for *_, p in self.right)

    @property
    def estimates(self) -> tuple[Reported, ...]:
        return tuple(Reported(task, subject, f"correct_{taps}_taps", "", p.trials, p.estimate)
                     for subject, task, taps, p in self.right)
# --8<-- [end:findings]

    def counted(self) -> str:
        return f"{self.trials} tap-counting trials"

    def methods(self) -> list[str]:
        return ["- Tap counting: the share of counts right at each number of taps, with its "
                "95 % Wilson interval, per subject."]

    def sections(self) -> list[str]:
        lines = ["## Tap counting", "", markdown_row(["subject", "task", "taps", "right"]),
                 "|---" * 4 + "|"]
        for subject, task, taps, p in self.right:
            e = p.estimate
            lines.append(markdown_row([subject, task, taps, f"{p.successes}/{p.trials} "
                                       f"({100 * e.value:.0f} %)"]))
        return lines + ["", "[tap_count.csv](tap_count.csv)", ""]

    def lines(self) -> list[str]:
        return [f"tap counting: {sum(p.successes for *_, p in self.right)} of {self.trials} "
                "counts right"]

    def tables(self, out: Path) -> list[Path]:
        rows = []
        for subject, task, taps, p in self.right:
            e = p.estimate
            rows.append([subject, task, taps, p.successes, p.trials, f"{100 * e.value:.1f}",
                         f"{100 * e.ci_low:.1f}", f"{100 * e.ci_high:.1f}", e.status.value])
        return [write_csv(out / "tap_count.csv", COLUMNS, rows)]

    def figures(self, out: Path) -> list[Path]:
        from matplotlib.figure import Figure  # no pyplot, no window: a figure to save

        from pinarray.analysis.figures import save

        figure = Figure(figsize=(4.5, 3.2))
        axes = figure.subplots()
        for subject in sorted({s for s, *_ in self.right}):
            mine = [(taps, p) for s, _, taps, p in self.right if s == subject]
            axes.plot([t for t, _ in mine], [100 * p.successes / p.trials for _, p in mine],
                      marker="o", label=f"subject {subject}")
        axes.set_xlabel("taps")
        axes.set_ylabel("% counted right")
        axes.set_ylim(0, 100)
        axes.legend(fontsize=7)
        return save(figure, out / "tap_count", self.captions()["tap_count"])

    def captions(self) -> dict[str, str]:
        return {"tap_count": "Tap counting: the share of counts right at each number of taps, "
                             "per subject. Counted: main trials with status ok."}


def tap_counts(trials: Sequence[LoadedTrial], context: Context) -> TapCounts:
    """The counted tap-counting rows of ``trials``, by subject, task and taps."""
    said: dict[tuple[str, str, int], list[bool]] = {}
    for trial in trials:
        record = trial.record
        if isinstance(record, TapCountRecord) and record.counts and record.correct is not None:
            said.setdefault((trial.subject, record.task, record.taps), []).append(record.correct)
    return TapCounts(tuple((subject, task, taps, Proportion(sum(right), len(right)))
                           for (subject, task, taps), right in sorted(said.items())))


class TapCountAnalysis(AnalysisDefaults):
    """Tap counting's analysis; its simulated subject is `pinarray_tap_count.observer`'s."""

    name = "tap_count"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return tap_counts(trials, context)


ANALYSIS = TapCountAnalysis()
