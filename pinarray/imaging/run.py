"""A session in the scanner or beside an EEG: what `pinarray batch` and the UI both put together.

With a scanner, the session's time zero is the first counted volume (the scanner has waited
for it already), trials may be held for their volumes, and the run's volume log is written
with its rows. With an LSL outlet, every presentation sends its onset and offset markers.
"""

from __future__ import annotations

from collections.abc import Callable

from pinarray.imaging.lsl import MarkerOutlet
from pinarray.imaging.markers import MarkedStimulator
from pinarray.imaging.scanner import Scanner
from pinarray.journal.writer import RunWriter
from pinarray.plan import TrialPlan
from pinarray.protocol import Protocol
from pinarray.session.trials import Session, Stimulator


def start_session(protocol: Protocol, plan: TrialPlan, writer: RunWriter, stimulator: Stimulator,
                  clock, *, scanner: Scanner | None = None, outlet: MarkerOutlet | None = None,
                  on_change: Callable[[Session], None] | None = None) -> Session:
    """A `Session` on ``writer``'s run, timed from ``scanner`` and marked on ``outlet`` if given.

    ``writer`` must have been started with ``scanner.record()`` when there is a scanner, and
    ``scanner`` must be past `Scanner.wait_for_time_zero`.
    """
    session: Session | None = None
    if outlet is not None:
        stimulator = MarkedStimulator(stimulator, outlet, protocol, writer.paths.task,
                                      lambda: session.current if session else None)
    if scanner is None:
        session = Session(protocol, plan, writer, stimulator, clock, on_change)
        return session
    zero_ns = scanner.timeline.zero_ns
    assert zero_ns is not None, "wait for the scanner's time zero first"
    writer.log_volumes(scanner.pending_rows)
    session = Session(protocol, plan, writer, stimulator, clock, on_change,
                      time_zero_ns=zero_ns, time_zero_event=scanner.zero_event,
                      gate=scanner.gate)
    return session
