"""Runs written by hand for tests: plans, provenance and task descriptions in a line each."""

from fractions import Fraction
from pathlib import Path

from pinarray.journal.manifest import (
    LocalisationEntry,
    MotionEntry,
    PlanEntry,
    Provenance,
    TaskInfo,
)
from pinarray.journal.records import LocalisationRecord, MotionRecord, TrialRecord
from pinarray.journal.timebase import ClockKind, TimeScale
from pinarray.journal.writer import RunWriter
from pinarray.protocol import Paradigm, WaveKind

PROVENANCE = Provenance(seed=42, protocol_sha256="0" * 64, port="sim://",
                        servo_models=("STS3215",), experimenter="AB")
VIRTUAL = TimeScale(ClockKind.VIRTUAL, None)
WAVE = {"left": WaveKind.LEFTWARDS, "right": WaveKind.RIGHTWARDS, "none": WaveKind.NONE}


def task_info(task: str, paradigm: Paradigm = Paradigm.LOCALISATION) -> TaskInfo:
    return TaskInfo(task, paradigm)


def localisation_plan(*pins_and_frequencies: tuple[int, float]) -> tuple[PlanEntry, ...]:
    """Main trials 1..N at these (pin, frequency_hz)."""
    return tuple(LocalisationEntry(trial=n, pin=pin, frequency_hz=Fraction(str(f)))
                 for n, (pin, f) in enumerate(pins_and_frequencies, start=1))


def plan_of(records: list[TrialRecord]) -> tuple[PlanEntry, ...]:
    """A plan with one entry per (trial, practice) of ``records``, in their order."""
    entries: dict[tuple[int, bool], PlanEntry] = {}
    for r in records:
        common = {"trial": r.trial, "block": r.block, "practice": r.practice}
        match r:
            case LocalisationRecord():
                entries.setdefault(r.key, LocalisationEntry(
                    **common, pin=r.pin, frequency_hz=Fraction(str(r.frequency_hz))))
            case MotionRecord():
                entries.setdefault(r.key, MotionEntry(**common, row=r.row,
                                                      wave=WAVE[r.direction.value]))
    return tuple(entries.values())


def start_run(root: Path, subject: str, task: str, plan, session: str | int = 1,
              clock: TimeScale = VIRTUAL, **options) -> RunWriter:
    paradigm = (Paradigm.APPARENT_MOTION if plan and isinstance(plan[0], MotionEntry)
                else Paradigm.LOCALISATION)
    return RunWriter.start(root, subject, session, task, plan, PROVENANCE,
                           task_info(task, paradigm), clock, **options)
