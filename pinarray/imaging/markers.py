"""What an LSL marker says about a stimulus, and the stimulator that has one sent at each end.

Each presented stimulus gives two markers, ``onset`` at its schedule's onset and ``offset``
at its schedule's end, as compact JSON with sorted keys::

    {"block":1,"event":"onset","frequency_hz":5,"pin":10,"practice":false,"task":"demo","trial":3}
    {"block":1,"direction":"left","event":"onset","frequency_hz":10,"practice":false,"row":2,...}

The player that plays the trial pushes them (`pinarray.player.markers`): the onset marker
right after the onset frame's write, the offset marker at the trial's end, each stamped with
the schedule's time it stands for (LabRecorder and every LSL reader use the stamp; an online
reader also learns of the stimulus as it starts).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Protocol as Interface

from pinarray.hardware.delivery import Presentation
from pinarray.plan import PlannedTrial
from pinarray.player.markers import TrialMarkers
from pinarray.protocol.model import Protocol
from pinarray.schedule import TrialSchedule


class Presenter(Interface):
    def present(self, schedule: TrialSchedule, markers: TrialMarkers | None = None
                ) -> Presentation: ...


def _number(value) -> int | float:
    number = float(value)
    return int(number) if number.is_integer() else number


def marker_text(event: str, planned: PlannedTrial, protocol: Protocol, task: str) -> str:
    """The marker for ``event`` ("onset" or "offset") of ``planned``'s stimulus."""
    condition = planned.condition
    data: dict[str, object] = {"event": event, "task": task, "trial": planned.trial,
                               "block": planned.block, "practice": planned.practice}
    data |= protocol.design.paradigm.marker_fields(condition,
                                                   protocol.stimulus(condition.stimulus))
    return json.dumps(data, sort_keys=True, separators=(",", ":"))


class MarkedStimulator:
    """Presents through ``stimulator``, handing it the trial's onset and offset markers.

    Parameters
    ----------
    stimulator
        What really presents (the rig, opened with a `pinarray.imaging.lsl.MarkerStream`):
        its player sends the markers as the trial plays.
    protocol, task
        For the markers' payload.
    current : callable
        The trial being presented (the session's ``current``).
    """

    def __init__(self, stimulator: Presenter, protocol: Protocol, task: str,
                 current: Callable[[], PlannedTrial | None]):
        self.stimulator = stimulator
        self.protocol = protocol
        self.task = task
        self.current = current

    def present(self, schedule: TrialSchedule) -> Presentation:
        planned = self.current()
        markers = None
        if planned is not None:
            markers = TrialMarkers(*(marker_text(event, planned, self.protocol, self.task)
                                     for event in ("onset", "offset")))
        return self.stimulator.present(schedule, markers)
