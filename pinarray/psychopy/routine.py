"""A Pin array touch component in a running Builder experiment: what the compiled script holds
for it from one repeat of its routine to the next.

The script Builder compiles does what a hand-written one does (docs/programmers/psychopy.md):
the array named in Builder's Device Manager, opened for the component's protocol as the
experiment starts; each repeat, the stimulus found in the protocol's design by name
(`pinarray.find_condition`); on the frame it starts, `PinArrayDevice.armOnFlip` on the window,
so that the flip showing that frame starts it; at the routine's end, `Touch.addData`.
"""

from __future__ import annotations

from collections.abc import Collection
from os import PathLike
from typing import Any

from psychopy import logging
from psychopy.constants import NOT_STARTED
from psychopy.hardware.manager import DeviceManager

import pinarray
from pinarray.psychopy.device import SIMULATED, PinArrayDevice
from pinarray.psychopy.touch import COLUMN_GROUPS, DataSink, Touch

__all__ = ["PinArrayTouch"]


class PinArrayTouch:
    """One Pin array touch component of a compiled Builder experiment.

    Parameters
    ----------
    device : str or PinArrayDevice
        The array's name in Builder's Device Manager (PsychoPy's `DeviceManager`), or the
        device. ``""``: the one pin array the Device Manager holds.
    protocol : str, path-like, pinarray.Protocol or ""
        The protocol to open the array for (a path relative to the experiment's folder, where
        its script runs); ``""``: the protocol the array is open for already (another
        component's, or a Code component's).
    name : str
        The component's name: its data columns begin with it (``touch.delivered``).

    Raises
    ------
    pinarray.PinArrayError
        No pin array of that name, none open for a protocol and none given, or one open for
        another protocol; as for `PinArrayDevice`.
    """

    def __init__(self, device: str | PinArrayDevice,
                 protocol: str | PathLike[str] | pinarray.Protocol = "",
                 name: str = "touch") -> None:
        self.name = name
        self.device = _named_array(device, name)
        """The pin array (`PinArrayDevice`)."""
        if protocol != "" and protocol is not None:
            self.device.open(protocol)
        elif not self.device.is_open:
            raise pinarray.PinArrayError(
                f"{name}: the pin array {self.device.url} is open for no protocol: give {name} "
                "one (its Protocol field)")
        self.status = NOT_STARTED
        """Builder's status of the component in its routine (NOT_STARTED, STARTED,
        FINISHED)."""
        self.stimulus: pinarray.Presentable | None = None
        """The stimulus this repeat presents (set as the routine starts)."""
        self.touch: Touch | None = None
        """The touch armed this repeat (None before its start)."""

    def addData(self, experiment: DataSink,
                columns: Collection[str] = COLUMN_GROUPS) -> pinarray.Delivery | None:
        """Add this repeat's touch to the current row: `Touch.addData` (waiting until it has
        ended), or, for a routine that ended before the touch's start, the stimulus as not
        delivered, with the reason, in the data and the log: a stimulus is delivered or
        reported as not delivered.

        Parameters
        ----------
        experiment : psychopy.data.ExperimentHandler
            Where the row is (``thisExp``).
        columns : collection of str
            The column groups to write (`pinarray.psychopy.touch.COLUMN_GROUPS`).

        Returns
        -------
        pinarray.Delivery or None
            What the array delivered; None for a touch never armed.
        """
        if self.touch is not None:
            return self.touch.addData(experiment, self.name, columns)
        problem = "never started: the routine ended before its start"
        experiment.addData(f"{self.name}.stimulus", _stimulus_name(self.stimulus))
        if "delivered" in columns:
            experiment.addData(f"{self.name}.delivered", False)
            experiment.addData(f"{self.name}.problem", problem)
            experiment.addData(f"{self.name}.ending", "not started")
        logging.warning(f"{self.name}: {_stimulus_name(self.stimulus)} not delivered: {problem}")
        return None

    def __repr__(self) -> str:
        return f"<PinArrayTouch {self.name} on {self.device!r}>"


def _named_array(device: str | PinArrayDevice, name: str) -> PinArrayDevice:
    if isinstance(device, PinArrayDevice):
        return device
    if device == "":
        arrays = [found for found in DeviceManager.devices.values()
                  if isinstance(found, PinArrayDevice)]
        if len(arrays) == 1:
            return arrays[0]
        raise pinarray.PinArrayError(
            f"{name}: expected one pin array in PsychoPy's Device Manager, found {len(arrays)}: "
            f"name the one to use (the component's Device field)")
    found: Any = DeviceManager.getDevice(device)
    if not isinstance(found, PinArrayDevice):
        raise pinarray.PinArrayError(
            f"{name}: expected a pin array named {device!r} in PsychoPy's Device Manager, found "
            f"{'none' if found is None else type(found).__name__}: add it in Builder's Device "
            f"Manager (the simulated array is 'pin array@{SIMULATED}')")
    return found


def _stimulus_name(stimulus: pinarray.Presentable | None) -> str | None:
    if stimulus is None:
        return None
    condition = stimulus.condition if isinstance(stimulus, pinarray.PlannedTrial) else stimulus
    return condition.stimulus if isinstance(condition, pinarray.Condition) else repr(condition)
