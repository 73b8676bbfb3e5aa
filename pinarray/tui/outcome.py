"""How the UI was left, as one line and an exit status (docs/experimenters/commands.md: the exit statuses).

Pure: built from the runs the sitting opened and how it ended, so it is tested without a
terminal. The command line prints the line once the terminal is restored.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path

from pinarray.hardware.feetech.faults import SIM_DEFAULT
from pinarray.journal.manifest import RunStatus
from pinarray.journal.runs import progress_text
from pinarray.stop import signal_name

DEFAULT_RESULTS = Path("results")


class ExitStatus(IntEnum):
    """The UI's exit statuses besides 128 + N (stopped by signal N; Ctrl-C counts as SIGINT)."""

    COMPLETED = 0  # every run this sitting opened is completed (or none was opened)
    CRASHED = 1  # an error the UI could not handle: the run is marked crashed, resumable
    UNFINISHED = 4  # quit with a run left unfinished (aborted or quit): resumable


@dataclass(frozen=True)
class Quit:
    """q, or the Quit button."""


@dataclass(frozen=True)
class Signalled:
    """A stop signal; Ctrl-C in the UI is a key, taken as SIGINT."""

    signal_number: int


@dataclass(frozen=True)
class Crashed:
    """An error nothing handled: what it was, and where its details were written."""

    what: str  # "RuntimeError: ..." or a pinarray error's own message
    log: Path | None  # None: the details could not be written
    bug: bool  # not a pinarray error (which says what went wrong in the lab's words)


Ending = Quit | Signalled | Crashed


@dataclass(frozen=True)
class RunOutcome:
    """One run the sitting opened, as it was left.

    Attributes
    ----------
    label : str
        e.g. ``run 1 of sub-01 ses-1 task-localisation``.
    status : RunStatus
        What its manifest says now.
    reason : str
        Why it was aborted or crashed ('' when completed).
    counted, practice : tuple of int
        (done, planned) trials of each kind.
    resume : str
        The command that opens the start screen on it, ready to Resume.
    """

    label: str
    status: RunStatus
    reason: str
    counted: tuple[int, int]
    practice: tuple[int, int]
    resume: str

    def progress(self) -> str:
        return progress_text(self.counted, self.practice)


def resume_command(protocol_source: str, subject: str, session: str, results_root: Path,
                   port: str | None, sim_url: str | None) -> str:
    """The `pinarray tui` line that opens the start screen filled in for this run."""
    words = ["pinarray", "tui", protocol_source, "--subject", subject, "--session", session]
    if Path(results_root) != DEFAULT_RESULTS:
        words += ["--results", str(results_root)]
    if port:
        words += ["--port", port]
    elif sim_url and sim_url != SIM_DEFAULT:
        words += ["--sim", sim_url]
    return shlex.join(words)


def exit_status(ending: Ending, runs: list[RunOutcome]) -> int:
    match ending:
        case Crashed():
            return ExitStatus.CRASHED
        case Signalled(signal_number=number):
            return 128 + number
        case Quit():
            unfinished = any(run.status.unfinished for run in runs)
            return ExitStatus.UNFINISHED if unfinished else ExitStatus.COMPLETED


def farewell(ending: Ending, runs: list[RunOutcome], pins: str) -> str:
    """One line: what happened, where the pins are, and exactly how to continue."""
    match ending:
        case Crashed(what=what, log=log, bug=bug):
            where = f"details in {log}" if log is not None else "its details could not be written"
            kind = "an unexpected error" if bug else "an error"
            head = f"stopped by {kind} ({what}; {where})"
        case Signalled(signal_number=number):
            head = f"stopped by {signal_name(number)}"
        case Quit():
            head = ""
    unfinished = [run for run in runs if run.status.unfinished]
    finished = [run for run in runs if not run.status.unfinished]
    parts = [head] if head else []
    for run in finished:
        parts.append(f"{run.label} completed: {run.progress()}")
    for run in unfinished:
        why = f" ({run.reason})" if run.reason else ""
        parts.append(f"{run.label} {run.status}{why} after {run.progress()}")
    if not runs:
        parts.append("no run was started")
    line = "; ".join(parts)
    line += f"; pins: {pins}." if pins else "."
    if unfinished:
        how = " · ".join(run.resume for run in unfinished)
        line += f" To continue: {how}, then Resume."
    return "pinarray: " + line
