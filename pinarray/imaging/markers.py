"""What an LSL marker says about a stimulus, and the stimulator that sends one at each end.

Each presented stimulus gives two markers, ``onset`` at its schedule's onset and ``offset``
at its schedule's end, as compact JSON with sorted keys::

    {"block":1,"event":"onset","frequency_hz":5,"pin":10,"practice":false,"task":"demo","trial":3}
    {"block":1,"direction":"left","event":"onset","frequency_hz":10,"practice":false,"row":2,...}

The player knows the onset only once the trial has played, so both markers are pushed when
the stimulus ends, each stamped with the time it stands for (LabRecorder and every LSL
reader use the stamp, not the arrival).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Protocol as Interface

from pinarray.hardware.delivery import Presentation
from pinarray.plan import PlannedTrial
from pinarray.protocol import LocalisationCondition, Protocol
from pinarray.schedule import TrialSchedule


class Outlet(Interface):
    def push(self, marker: str, at_ns: int) -> None: ...


class Presenter(Interface):
    def present(self, schedule: TrialSchedule) -> Presentation: ...


def _number(value) -> int | float:
    number = float(value)
    return int(number) if number.is_integer() else number


def marker_text(event: str, planned: PlannedTrial, protocol: Protocol, task: str) -> str:
    """The marker for ``event`` ("onset" or "offset") of ``planned``'s stimulus."""
    condition = planned.condition
    data: dict[str, object] = {"event": event, "task": task, "trial": planned.trial,
                               "block": planned.block, "practice": planned.practice}
    if isinstance(condition, LocalisationCondition):
        data |= {"pin": condition.pin, "frequency_hz": _number(condition.frequency_hz)}
    else:
        wave = protocol.wave(condition.stimulus)
        data |= {"row": condition.row, "direction": condition.direction.value,
                 "frequency_hz": _number(wave.train.frequency_hz)}
    return json.dumps(data, sort_keys=True, separators=(",", ":"))


class MarkedStimulator:
    """Presents through ``stimulator``, then pushes the onset and offset markers of the trial.

    Parameters
    ----------
    stimulator
        What really presents (the rig).
    outlet
        Where markers go (`pinarray.imaging.lsl.MarkerOutlet`).
    protocol, task
        For the markers' payload.
    current : callable
        The trial being presented (the session's ``current``).
    """

    def __init__(self, stimulator: Presenter, outlet: Outlet, protocol: Protocol, task: str,
                 current: Callable[[], PlannedTrial | None]):
        self.stimulator = stimulator
        self.outlet = outlet
        self.protocol = protocol
        self.task = task
        self.current = current

    def present(self, schedule: TrialSchedule) -> Presentation:
        presentation = self.stimulator.present(schedule)
        planned = self.current()
        if planned is not None:
            for event, at_ns in (("onset", presentation.onset_ns),
                                 ("offset", presentation.onset_ns + schedule.end_ns)):
                self.outlet.push(marker_text(event, planned, self.protocol, self.task), at_ns)
        return presentation
