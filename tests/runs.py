"""Runs written by hand for tests: plans, provenance and task descriptions in a line each;
another process holding a run open."""

import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from fractions import Fraction
from pathlib import Path

from pinarray.clock import VirtualClock
from pinarray.journal.manifest import PlanEntry, Provenance, RunStatus, TaskInfo
from pinarray.journal.paths import RunPaths
from pinarray.journal.records import TrialRecord
from pinarray.journal.runs import open_run
from pinarray.journal.timebase import Answers, ClockKind, TimeScale
from pinarray.journal.writer import RunWriter
from pinarray.paradigms.apparent_motion.rows import MotionRecord
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.protocol import WaveKind
from pinarray.protocol.load import load_protocol
from pinarray.session.trials import task_label

PROVENANCE = Provenance(seed=42, protocol_sha256="0" * 64, port="sim://",
                        servo_models=("STS3215",), experimenter="AB")
VIRTUAL = TimeScale(ClockKind.VIRTUAL, None)
WAVE = {"left": WaveKind.LEFTWARDS, "right": WaveKind.RIGHTWARDS, "none": WaveKind.NONE}


def task_info(task: str, paradigm: str = "localisation") -> TaskInfo:
    return TaskInfo(task, paradigm)


def localisation_entry(trial: int, pin: int, frequency_hz: float, **common) -> PlanEntry:
    """A localisation trial of a plan, as its manifest keeps it."""
    return PlanEntry(trial=trial, **common,
                     fields={"pin": pin, "frequency_hz": str(Fraction(str(frequency_hz)))})


def motion_entry(trial: int, row: int | None, direction: str, **common) -> PlanEntry:
    """An apparent-motion trial of a plan (a wave along ``row`` going ``direction``)."""
    return PlanEntry(trial=trial, **common,
                     fields={"direction": WAVE[direction].value, "row": row})


def localisation_plan(*pins_and_frequencies: tuple[int, float]) -> tuple[PlanEntry, ...]:
    """Main trials 1..N at these (pin, frequency_hz)."""
    return tuple(localisation_entry(n, pin, f)
                 for n, (pin, f) in enumerate(pins_and_frequencies, start=1))


def plan_of(records: list[TrialRecord]) -> tuple[PlanEntry, ...]:
    """A plan with one entry per (trial, practice) of ``records``, in their order."""
    entries: dict[tuple[int, bool], PlanEntry] = {}
    for r in records:
        common = {"block": r.block, "practice": r.practice}
        match r:
            case LocalisationRecord():
                entries.setdefault(r.key, localisation_entry(r.trial, r.pin, r.frequency_hz,
                                                             **common))
            case MotionRecord():
                entries.setdefault(r.key, motion_entry(r.trial, r.row, r.direction.value,
                                                       **common))
    return tuple(entries.values())


def start_run(root: Path, subject: str, task: str, plan, session: str | int = 1,
              clock: TimeScale = VIRTUAL, provenance: Provenance = PROVENANCE,
              **options) -> RunWriter:
    paradigm = ("apparent_motion" if plan and plan[0]["direction"] is not None
                else "localisation")
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
                         seed: int = 7, answers: Answers = Answers.UNKNOWN) -> RunPaths:
    """A run of ``protocol_file`` as `pinarray batch` opens it, left aborted before trial 1;
    who answers it, ``answers`` (by default not recorded, as an earlier pinarray wrote it:
    any resume may take it on)."""
    protocol = load_protocol(protocol_file)
    writer, _ = open_run(protocol, root, subject, "1", task_label(protocol), resume=False,
                         seed=seed, port_url="sim://", clock=VirtualClock(), answers=answers)
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
