"""Opening a run for a session: a new run, or the subject's unfinished one resumed.

Shared by `pinarray batch` and the TUI so both check a resumed run the same way: the run must
not be open in another process (its lock), the protocol file must be the one the run started
with, and its plan must be the saved one.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pinarray.clock import Clock, MonotonicClock, PacedClock, ScaledClock, VirtualClock
from pinarray.errors import PinArrayError
from pinarray.journal.lock import LockHolder, lock_holder
from pinarray.journal.manifest import (
    PlanEntry,
    Provenance,
    RunManifest,
    TaskInfo,
    entry_from_record,
    find_unfinished,
    remaining_plan,
)
from pinarray.journal.paths import RunPaths
from pinarray.journal.rows import read_trials
from pinarray.journal.timebase import (
    REAL_TIME,
    Answers,
    ClockKind,
    TimeScale,
    answered_otherwise,
)
from pinarray.journal.volumes import ScannerRecord
from pinarray.journal.writer import RunWriter
from pinarray.plan import PlannedTrial, TrialPlan, make_plan
from pinarray.protocol.model import Protocol


def plan_entry(planned: PlannedTrial) -> PlanEntry:
    """The journal's record of one planned trial."""
    return entry_from_record(planned.record())


def plan_entries(plan: TrialPlan) -> tuple[PlanEntry, ...]:
    return tuple(plan_entry(t) for t in plan.trials)


def task_info(protocol: Protocol) -> TaskInfo:
    """What the sidecars say about the protocol's task and device."""
    grid = protocol.device.grid
    design = protocol.design
    return TaskInfo(name=protocol.name, paradigm=design.paradigm.name,
                    description=protocol.description,
                    instructions=design.paradigm.instructions(design),
                    grid_rows=grid.rows, grid_columns=grid.columns, pitch_mm=grid.pitch_mm,
                    mm_per_step=tuple(protocol.device.mm_per_step(pin) for pin in grid.pins),
                    answers=design.paradigm.answer_meanings(design, grid.pin_count))


def time_scale_of(clock: Clock) -> TimeScale:
    """What a session's clock measures, for the run's time base (unknown clocks: real time)."""
    match clock:
        case VirtualClock():
            return TimeScale(ClockKind.VIRTUAL, None)
        case PacedClock():
            return TimeScale(ClockKind.PACED, clock.pace)
        case ScaledClock() if clock.scale != 1:
            return TimeScale(ClockKind.SCALED, clock.scale)
        case ScaledClock():
            return REAL_TIME  # scaled by 1: the wall clock's own time
        case MonotonicClock():
            return REAL_TIME
    return REAL_TIME


def progress_text(counted: tuple[int, int], practice: tuple[int, int]) -> str:
    """"3 of 24 trials (practice 2 of 2)": main trials done of planned, then practice's.

    Said the same way wherever a run's progress is shown (the start screen, the exit line).
    """
    done, planned = counted
    text = f"{done} of {planned} trials"
    if practice[1]:
        text += f" (practice {practice[0]} of {practice[1]})"
    return text


@dataclass(frozen=True)
class Unfinished:
    """A subject's unfinished run: where, its manifest, its rows done, and who has it open."""

    paths: RunPaths
    manifest: RunManifest
    counted: tuple[int, int]  # main trials finished, of the plan's
    practice: tuple[int, int]  # practice trials finished, of the plan's
    holder: LockHolder | None  # the process writing it now, or None when it can be resumed

    @property
    def answered_otherwise(self) -> Answers | None:
        """What answered the run when a subject in the UI may not resume it (a simulated
        observer's, a responses sheet's), else None."""
        return answered_otherwise(self.manifest.sittings, Answers.SUBJECT)

    def describe(self) -> str:
        """One line for the start screen."""
        m = self.manifest
        if self.holder is not None:
            return (f"Run {self.paths.run} is open in another process, {self.holder.describe()}; "
                    "it can be resumed once that one ends.")
        why = f" ({m.abort_reason})" if m.abort_reason else ""
        done = (f"Unfinished run {self.paths.run}: {m.status}{why}, "
                f"{progress_text(self.counted, self.practice)} done, seed {m.seed}.")
        other = self.answered_otherwise
        if other is not None:
            return (f"{done} Its answers are {other.describe()}: resume it "
                    f"{other.how_to_resume()}; Start begins a new run.")
        return f"{done} Resume continues it (with its own seed)."


def unfinished_run(root: Path | str, subject: str, session: str, task: str) -> Unfinished | None:
    """The subject's latest unfinished run of ``task`` in ``session``, or None."""
    found = find_unfinished(root, subject, session, task)
    if not found:
        return None
    paths, manifest = found[-1]
    rows = (read_trials(paths.beh_tsv, manifest.task_info.paradigm)
            if paths.beh_tsv.exists() else [])
    left = remaining_plan(manifest.needed, rows)

    def finished(practice: bool) -> tuple[int, int]:
        planned = sum(1 for e in manifest.plan if e.practice is practice)
        return planned - sum(1 for e in left if e.practice is practice), planned

    return Unfinished(paths, manifest, finished(False), finished(True), lock_holder(paths.lock))


class NothingToResume(PinArrayError):
    """``resume`` was asked for and the subject has no unfinished run of the task."""


# Why a run timed from scanner volumes is never resumed, after its label.
SCANNED = ("was timed from scanner volumes and cannot be resumed, with no scanner nor in a new "
           "scan (its time zero was its scan's first volume); start a new run without --resume")


def open_run(
    protocol: Protocol, root: Path | str, subject: str, session: str, task: str, *,
    resume: bool, seed: int | None, port_url: str, clock: Clock, experimenter: str = "",
    scanner: ScannerRecord | None = None, answers: Answers = Answers.UNKNOWN,
) -> tuple[RunWriter, TrialPlan]:
    """(writer, plan) for the subject's unfinished run (``resume``) or a new one.

    Parameters
    ----------
    protocol : Protocol
        The loaded protocol; a resumed run must have started with the same file (SHA-256).
    root, subject, session, task
        Where results go and the BIDS labels (already checked).
    resume : bool
        Continue the latest unfinished run; `NothingToResume` if there is none. A run open in
        another process is refused (`pinarray.journal.lock.RunLocked`).
    seed : int or None
        Plan seed of a new run (None: the protocol's, else a fresh one); a resumed run keeps
        the seed in its manifest.
    port_url : str
        The bus the run uses, for the manifest.
    clock : Clock
        The sitting's clock (its kind and speed go into the run's time base).
    experimenter : str
        Who runs it, for the manifest.
    scanner : ScannerRecord or None
        A new run timed from scanner volumes: its trigger settings, for the manifest.
    answers : Answers
        Who or what answers the sitting's trials; a resumed run's earlier sittings must have
        been answered so too.
    """
    scale = time_scale_of(clock)
    if resume:
        found = find_unfinished(root, subject, session, task)
        if not found:
            raise NothingToResume(f"no unfinished {task} run for subject {subject}, session "
                                  f"{session} in {root}; start a new run instead (without resume)")
        paths, manifest = found[-1]
        if manifest.scanner is not None:
            raise PinArrayError(f"{paths.label} {SCANNED}")
        if manifest.protocol_sha256 != protocol.sha256:
            raise PinArrayError(
                f"{protocol.source} changed since run {paths.run} started (SHA-256 differs); "
                "resume with the protocol file it started with"
            )
        plan = make_plan(protocol, manifest.seed)
        if manifest.plan != plan_entries(plan):
            raise PinArrayError(f"{paths.manifest}: the saved plan does not match the protocol's "
                                f"plan for seed {manifest.seed}")
        return RunWriter.resume(paths, scale, answers=answers), plan
    plan = make_plan(protocol, seed)
    provenance = Provenance(
        seed=plan.seed, protocol_sha256=protocol.sha256, port=port_url,
        protocol_file=protocol.source,
        servo_models=(protocol.device.servo.model,) * protocol.device.grid.pin_count,
        experimenter=experimenter,
    )
    writer = RunWriter.start(root, subject, session, task, plan_entries(plan), provenance,
                             task_info(protocol), scale, scanner=scanner, answers=answers)
    return writer, plan
