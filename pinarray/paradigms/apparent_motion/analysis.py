"""Apparent motion's findings: motion felt on wave trials, the direction named right of those
felt, and motion felt on no-wave trials (the false-alarm baseline), with subjects as the unit;
their tables, section of ``summary.md``, printout and figure (the seed's Fig. 9.17).

Only rows that count are used: main trials (not practice) with status ``ok``. Motion was felt
unless the answer is "none"; the direction is right when the answer names the wave's
direction ("unsure" counts as felt, not right). Chance: a subject who names left or right at
random is right half the time, so the chance level of "direction right, of those felt" is
50 %. Whether motion was felt is a yes/no detection with no chance level; its baseline is
the no-wave control (motion felt when no wave ran), drawn beside it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from pinarray.analysis.load import LoadedTrial
from pinarray.analysis.power import PowerModel
from pinarray.analysis.seam import AnalysisDefaults, Context, Estimate, Findings, Reported
from pinarray.analysis.stats import Proportion
from pinarray.analysis.subjects import AcrossSubjects, IntervalSettings, across_subjects
from pinarray.analysis.tables import (
    ALL_SUBJECTS,
    interval_cells,
    interval_heads,
    markdown_row,
    measure_cells,
    measure_header,
    measure_text,
    number,
    pooled_text,
    write_csv,
)
from pinarray.journal.records import TrialRecord
from pinarray.paradigms.apparent_motion.rows import MotionRecord
from pinarray.protocol.model import Protocol

DIRECTION_CHANCE = 0.5
COUNTED = "Counted: main trials with status ok."


@dataclass(frozen=True)
class MotionSummary:
    """Apparent motion of one subject: felt on wave trials, right direction among those,
    felt on no-wave trials."""

    subject: str
    felt: Proportion  # wave trials on which motion was felt
    direction_right: Proportion  # of those, the wave's direction named
    no_wave_felt: Proportion  # no-wave trials on which motion was (wrongly) felt


def motion_summary(records: Iterable[TrialRecord], subject: str = "") -> MotionSummary:
    """Felt-motion and direction proportions over the motion trials that count."""
    wave = felt = right = no_wave = no_wave_felt = 0
    for record in records:
        if not (record.counts and isinstance(record, MotionRecord)):
            continue
        answered_motion = record.response not in (None, "none")
        if record.direction == "none":
            no_wave += 1
            no_wave_felt += answered_motion
        else:
            wave += 1
            felt += answered_motion
            right += record.response == record.direction
    return MotionSummary(subject, Proportion(felt, wave), Proportion(right, felt),
                         Proportion(no_wave_felt, no_wave))


def _n(m: AcrossSubjects) -> str:
    return f"N = {m.subjects} subject(s), {m.trials} trials"


@dataclass(frozen=True)
class Motions:
    """What apparent-motion rows show (`pinarray.analysis.seam.Findings`)."""

    per_subject: tuple[MotionSummary, ...]
    felt: AcrossSubjects
    direction_right: AcrossSubjects
    no_wave_felt: AcrossSubjects
    settings: IntervalSettings
    paradigm: str = "apparent_motion"

    @property
    def trials(self) -> int:
        return self.felt.trials + self.no_wave_felt.trials

    def _measures(self) -> tuple[tuple[str, AcrossSubjects], ...]:
        return (("felt_on_wave_trials", self.felt),
                ("direction_right_of_felt", self.direction_right),
                ("felt_on_no_wave_trials", self.no_wave_felt))

    @property
    def estimates(self) -> tuple[Reported, ...]:
        found = [Reported("", s.subject, name, "%", p.trials, Estimate.of(p.pct))
                 for s in self.per_subject
                 for name, p in (("felt_on_wave_trials", s.felt),
                                 ("direction_right_of_felt", s.direction_right),
                                 ("felt_on_no_wave_trials", s.no_wave_felt))]
        for name, m in self._measures():
            low, high = m.interval_pct(self.settings.method)
            found.append(Reported("", ALL_SUBJECTS, name, "%", m.trials,
                                  Estimate.of(m.mean_pct, low, high)))
        return tuple(found)

    def counted(self) -> str:
        return f"{self.trials} motion trials"

    def methods(self) -> list[str]:
        return [f"- Motion chance: direction right {100 * DIRECTION_CHANCE:.0f} % (left or "
                "right named at random; 'unsure' counts as not right). Feeling motion has no "
                "chance level; the no-wave trials are its false-alarm baseline."]

    def tables(self, out: Path) -> list[Path]:
        settings = self.settings
        rows = [["felt_on_wave_trials", *measure_cells(self.felt, settings), "n/a"],
                ["direction_right_of_felt", *measure_cells(self.direction_right, settings),
                 number(100 * DIRECTION_CHANCE, 2)],
                ["felt_on_no_wave_trials", *measure_cells(self.no_wave_felt, settings), "n/a"]]
        per_subject = [[s.subject, s.felt.trials, s.felt.successes, number(s.felt.pct),
                        s.direction_right.successes, number(s.direction_right.pct),
                        s.no_wave_felt.trials, s.no_wave_felt.successes,
                        number(s.no_wave_felt.pct)]
                       for s in self.per_subject if s.felt.trials or s.no_wave_felt.trials]
        return [
            write_csv(out / "motion_subject_level.csv",
                      ["measure", *measure_header(settings), "chance_pct"], rows),
            write_csv(out / "motion_per_subject.csv",
                      ["subject", "wave_trials", "felt", "felt_pct", "direction_right",
                       "direction_right_pct_of_felt", "no_wave_trials", "no_wave_felt",
                       "no_wave_felt_pct"], per_subject),
        ]

    def sections(self) -> list[str]:
        settings = self.settings
        rows = [("felt a moving dot (wave trials)", self.felt, "-"),
                ("direction right (of the wave trials felt)", self.direction_right,
                 f"{100 * DIRECTION_CHANCE:.0f} %"),
                ("felt motion on no-wave trials (false alarms)", self.no_wave_felt, "-")]
        heads = interval_heads(settings)
        lines = ["## Apparent motion", "",
                 markdown_row(["measure", "subjects", "trials", "subject mean", *heads,
                       "trial-pooled [Wilson 95 %]", "chance"]), "|---" * (6 + len(heads)) + "|"]
        for name, m, chance in rows:
            lines.append(markdown_row([name, m.subjects, m.trials, f"{number(m.mean_pct)} %",
                               *interval_cells(m, settings), pooled_text(m.pooled), chance]))
        return lines + [""]

    def lines(self) -> list[str]:
        method = self.settings.method
        return [f"motion, mean of per-subject % [{method} interval]: felt "
                f"{measure_text(self.felt, method)}; direction right of those felt "
                f"{measure_text(self.direction_right, method)} (chance 50 %); felt on "
                f"no-wave trials {measure_text(self.no_wave_felt, method)}"]

    def captions(self) -> dict[str, str]:
        return {"motion": self.caption()}

    def caption(self) -> str:
        return (f"Apparent motion. Bars: mean of per-subject percentages (unit: subject); error "
                f"bars: {self.settings.describe()}; under each bar: its mean, subjects and "
                f"trials; grey dots: individual subjects. Felt a moving dot: % of wave trials "
                f"({_n(self.felt)}). Direction right: % of the wave trials on which motion was "
                f"felt ({_n(self.direction_right)}); dashed line: chance "
                f"{100 * DIRECTION_CHANCE:.0f} % (left or right named at random; 'unsure' "
                f"counts as not right). Felt on no-wave trials: the false-alarm baseline "
                f"({_n(self.no_wave_felt)}). {COUNTED}")

    def figures(self, out: Path) -> list[Path]:
        """Fig. 9.17: motion felt on wave trials, direction right of those, felt on no-wave."""
        import numpy as np

        from pinarray.analysis.figures import (
            CHANCE_COLOUR,
            OKABE_ITO,
            bar_errors,
            label_bars,
            means,
            plt,
            save,
            subject_dots,
        )

        measures = [self.felt, self.direction_right, self.no_wave_felt]
        x = np.arange(3)
        figure, axes = plt.subplots(figsize=(5.0, 3.9))
        axes.bar(x, means(measures), yerr=bar_errors(measures, self.settings.method),
                 capsize=4, color=[OKABE_ITO["green"], OKABE_ITO["blue"], OKABE_ITO["sky"]],
                 alpha=0.9)
        subject_dots(axes, x, measures, connect=False)
        label_bars(axes, x, ["felt a moving dot\n(wave trials)",
                             "direction right\n(of those felt)",
                             "felt motion\n(no-wave trials)"], measures, 0)
        axes.hlines(100 * DIRECTION_CHANCE, 0.55, 1.45, color=CHANCE_COLOUR, linestyle="--",
                    linewidth=1.2, label=f"chance {100 * DIRECTION_CHANCE:.0f} %")
        axes.legend(fontsize=7, loc="upper right")
        axes.set_ylim(0, 100)
        axes.set_ylabel("% of trials")
        axes.set_title("Apparent motion")
        return save(figure, out / "motion", self.caption())


def motions(trials: Sequence[LoadedTrial], context: Context) -> Motions:
    """What the apparent-motion rows of ``trials`` show (the counted ones)."""
    by_subject: dict[str, list[TrialRecord]] = {}
    for trial in trials:
        by_subject.setdefault(trial.subject, []).append(trial.record)
    per_subject = tuple(motion_summary(by_subject[s], s) for s in sorted(by_subject))
    settings = context.settings
    return Motions(
        per_subject,
        across_subjects(((s.subject, s.felt) for s in per_subject), settings),
        across_subjects(((s.subject, s.direction_right) for s in per_subject), settings),
        across_subjects(((s.subject, s.no_wave_felt) for s in per_subject), settings),
        settings)


class ApparentMotionAnalysis(AnalysisDefaults):
    """The apparent motion analysis (`pinarray.analysis.seam.ParadigmAnalysis`)."""

    name = "apparent_motion"

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        return motions(trials, context)

    def power(self, protocol: Protocol, model: str) -> PowerModel:
        from pinarray.paradigms.apparent_motion.observer import parse_observer
        from pinarray.paradigms.apparent_motion.power import power

        return power(protocol, parse_observer(model))

    def session_lines(self, records: Sequence[TrialRecord]) -> list[str]:
        motion = motion_summary(records)
        if not motion.felt.trials:
            return []
        lines = [f"motion felt on {motion.felt.pct:.0f} % of wave trials "
                 f"({motion.felt.successes}/{motion.felt.trials})"]
        if motion.direction_right.trials:
            lines.append(f"direction right on {motion.direction_right.pct:.0f} % of those "
                         f"({motion.direction_right.successes}/{motion.direction_right.trials})")
        return lines


ANALYSIS = ApparentMotionAnalysis()
