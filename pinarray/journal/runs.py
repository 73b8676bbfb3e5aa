"""Opening a run for a session: a new run, or the subject's unfinished one resumed.

Shared by `pinarray batch` and the TUI so both check a resumed run the same way: the
protocol file must be the one the run started with, and its plan must be the saved one.
"""

from __future__ import annotations

from pathlib import Path

from pinarray.errors import PinArrayError
from pinarray.journal.manifest import RunPaths, SessionManifest, find_unfinished
from pinarray.journal.records import RunWriter
from pinarray.plan import TrialPlan, make_plan
from pinarray.protocol import Protocol
from pinarray.session import plan_records


def unfinished_run(
    root: Path | str, subject: str, session: str, task: str
) -> tuple[RunPaths, SessionManifest] | None:
    """The subject's latest unfinished run of ``task`` in ``session``, or None."""
    found = find_unfinished(root, subject, session, task)
    return found[-1] if found else None


def open_run(
    protocol: Protocol, root: Path | str, subject: str, session: str, task: str, *,
    resume: bool, seed: int | None, port_url: str, experimenter: str = "",
) -> tuple[RunWriter, TrialPlan]:
    """(writer, plan) for the subject's unfinished run (``resume``) or a new one.

    Parameters
    ----------
    protocol : Protocol
        The loaded protocol; a resumed run must have started with the same file (SHA-256).
    root, subject, session, task
        Where results go and the BIDS labels (already checked).
    resume : bool
        Continue the latest unfinished run if there is one; with none, a new run starts
        (``writer.resumed`` then says False, for the caller to mention).
    seed : int or None
        Plan seed of a new run (None: the protocol's, else a fresh one); a resumed run keeps
        the seed in its manifest.
    port_url : str
        The bus the run uses, for the manifest.
    experimenter : str
        Who runs it, for the manifest.
    """
    unfinished = unfinished_run(root, subject, session, task) if resume else None
    if unfinished is not None:
        paths, manifest = unfinished
        if manifest.protocol_sha256 != protocol.sha256:
            raise PinArrayError(
                f"{protocol.source} changed since run {paths.run} started (SHA-256 differs); "
                "resume with the protocol file it started with"
            )
        plan = make_plan(protocol, manifest.seed)
        if [dict(e) for e in manifest.plan] != plan_records(plan):
            raise PinArrayError(f"{paths.manifest}: the saved plan does not match the protocol's "
                                f"plan for seed {manifest.seed}")
        return RunWriter.resume(paths), plan
    plan = make_plan(protocol, seed)
    writer = RunWriter.start(
        root, subject, session, task, plan_records(plan), seed=plan.seed,
        protocol_sha256=protocol.sha256, port=port_url,
        servo_models=[protocol.device.servo.model] * protocol.device.grid.pin_count,
        experimenter=experimenter,
    )
    return writer, plan
