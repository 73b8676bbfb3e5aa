"""Runs written by hand for tests: plans, provenance and task descriptions in a line each;
another process holding a run open."""

import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from fractions import Fraction
from pathlib import Path

from pinarray.clock import VirtualClock
from pinarray.journal.manifest import (
    LocalisationEntry,
    MotionEntry,
    PlanEntry,
    Provenance,
    RunStatus,
    TaskInfo,
)
from pinarray.journal.paths import RunPaths
from pinarray.journal.records import LocalisationRecord, MotionRecord, TrialRecord
from pinarray.journal.runs import open_run
from pinarray.journal.timebase import ClockKind, TimeScale
from pinarray.journal.writer import RunWriter
from pinarray.protocol import Paradigm, WaveKind
from pinarray.protocol.load import load_protocol
from pinarray.session.trials import task_label

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
                                                      wave=WAVE[r.direction.value],
                                                      direction=r.direction))
    return tuple(entries.values())


def start_run(root: Path, subject: str, task: str, plan, session: str | int = 1,
              clock: TimeScale = VIRTUAL, provenance: Provenance = PROVENANCE,
              **options) -> RunWriter:
    paradigm = (Paradigm.APPARENT_MOTION if plan and isinstance(plan[0], MotionEntry)
                else Paradigm.LOCALISATION)
    return RunWriter.start(root, subject, session, task, plan, provenance,
                           task_info(task, paradigm), clock, **options)


# -- another process with a run open -------------------------------------------------------------

REPO = Path(__file__).resolve().parent.parent
HOLDER = """
import sys
from pathlib import Path
from pinarray.journal.paths import RunPaths
from pinarray.journal.writer import RunWriter
from tests.runs import VIRTUAL

root, subject, session, task, run = sys.argv[1:6]
writer = RunWriter.resume(RunPaths(Path(root), subject, session, task, int(run)), VIRTUAL)
print("holding", flush=True)
sys.stdin.read()  # until the test closes our stdin (or kills us)
writer.close()
"""


@contextmanager
def open_elsewhere(paths: RunPaths) -> Iterator[subprocess.Popen]:
    """A second pinarray process with ``paths``'s run resumed (so its lock held) until exit."""
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(paths.root), paths.subject, paths.session,
         paths.task, str(paths.run)],
        cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = holder.stdout.readline()
        assert line == "holding\n", holder.stderr.read()
        yield holder
    finally:
        if holder.poll() is None:
            holder.stdin.close()
        holder.wait(timeout=30)


def unfinished_batch_run(root: Path, protocol_file: Path, subject: str = "01",
                         seed: int = 7) -> RunPaths:
    """A run of ``protocol_file`` as `pinarray batch` opens it, left aborted before trial 1."""
    protocol = load_protocol(protocol_file)
    writer, _ = open_run(protocol, root, subject, "1", task_label(protocol), resume=False,
                         seed=seed, port_url="sim://", clock=VirtualClock())
    writer.finish(RunStatus.ABORTED, "stopped before trial 1")
    return writer.paths


def write_short_localisation(folder: Path) -> Path:
    """The seed's localisation protocol with 1 s stimuli, written into ``folder``: for tests
    that go through whole runs to see what the screens do or what the files hold, where ten
    seconds of simulated servos per trial add nothing."""
    text = (REPO / "protocols" / "localisation.yaml").read_text(encoding="utf-8")
    assert "    duration_s: 10\n" in text
    path = folder / "localisation.yaml"
    path.write_text(text.replace("    duration_s: 10\n", "    duration_s: 1\n"), encoding="utf-8")
    return path
