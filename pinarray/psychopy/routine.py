"""A Pin array touch component in a running Builder experiment: what the compiled script holds
for it from one repeat of its routine to the next.

The script Builder compiles does what a hand-written one does (docs/programmers/psychopy.md):
the array named in Builder's Device Manager, opened for the component's protocol as the
experiment starts (or, with none, the simulated array with pinarray's default device); each
repeat, the stimulus found in the protocol's design by name (`pinarray.find_condition`) or
built from the dialog's pins and train (`pinarray.Pattern`), and prepared on the array
(`PinArrayTouch.repeat`); on the frame it starts, `PinArrayDevice.armOnFlip` on the window, so
that the flip showing that frame starts it; at the routine's end, `Touch.addData`.
"""

from __future__ import annotations

import sys
import weakref
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from os import PathLike
from typing import Any

from psychopy import logging
from psychopy.constants import NOT_STARTED
from psychopy.hardware.manager import DeviceManager

import pinarray
from pinarray.psychopy.device import SIMULATED, PinArrayDevice
from pinarray.psychopy.touch import COLUMN_GROUPS, DataSink, Touch

__all__ = ["PinArrayTouch", "endOnProblem"]

# The arrays a component opened without a protocol (pinarray's default device), by id (a
# device is not hashable: PsychoPy's devices compare by what they are connected to): a
# component that gives one opens the array again for it, whichever the script reaches first.
_WITHOUT_PROTOCOL: weakref.WeakValueDictionary[int, PinArrayDevice] = (
    weakref.WeakValueDictionary())


class PinArrayTouch:
    """One Pin array touch component of a compiled Builder experiment.

    Parameters
    ----------
    device : str or PinArrayDevice
        The array's name in Builder's Device Manager (PsychoPy's `DeviceManager`), or the
        device. ``""``: the one pin array the Device Manager holds.
    protocol : str, path-like, pinarray.Protocol or ""
        The protocol to open the array for (a path relative to the experiment's folder, where
        its script runs). ``""``: the protocol the array is open for already (another
        component's, or a Code component's); if it is not open, no protocol: the simulated
        array with pinarray's default device (`pinarray.open_array` without one), for patterns
        built in the dialog, until a component that gives a protocol opens it for that one.
    name : str
        The component's name: its data columns begin with it (``touch.delivered``).

    Raises
    ------
    pinarray.PinArrayError
        No pin array of that name, real servos and no protocol, or one open for another
        protocol; as for `PinArrayDevice`.
    """

    def __init__(self, device: str | PinArrayDevice,
                 protocol: str | PathLike[str] | pinarray.Protocol = "",
                 name: str = "touch") -> None:
        self.name = name
        self.device = _named_array(device, name)
        """The pin array (`PinArrayDevice`)."""
        if protocol != "" and protocol is not None:
            if _WITHOUT_PROTOCOL.pop(id(self.device), None) is not None:  # opened with none
                logging.exp(f"{name}: opening the pin array {self.device.url} again, for "
                            f"{name}'s protocol")
                self.device.close()
            self.device.open(protocol)
        elif not self.device.is_open:
            if not self.device.url.startswith(SIMULATED):
                raise pinarray.PinArrayError(
                    f"{name}: the pin array {self.device.url} has real servos, which need the "
                    f"protocol that calibrates them (servo ids, rest, limits): give {name} "
                    "one (its Protocol field)")
            self.device.open(None)
            _WITHOUT_PROTOCOL[id(self.device)] = self.device
        self.status = NOT_STARTED
        """Builder's status of the component in its routine (NOT_STARTED, STARTED,
        FINISHED)."""
        self.stimulus: pinarray.Presentable | None = None
        """The stimulus this repeat presents (set in `repeat`)."""
        self.touch: Touch | None = None
        """The touch armed this repeat (None before its start, or for a refused stimulus)."""
        self.refused: str | None = None
        """Why the array refused this repeat's stimulus, in its words (None: it did not)."""
        self._written = True  # this repeat's row (nothing to write before the first repeat)

    @property
    def protocol(self) -> pinarray.Protocol:
        """The protocol the array is open for, whose design a stimulus is found in.

        Raises
        ------
        pinarray.PinArrayError
            The array open with no protocol (pinarray's default device has no stimuli to
            choose from).
        """
        if id(self.device) in _WITHOUT_PROTOCOL:
            raise pinarray.PinArrayError(
                f"a stimulus of a protocol needs a protocol, and the pin array "
                f"{self.device.url} is open with none: give {self.name} one (its Protocol "
                "field), or Pins to build a pattern")
        return self.device.protocol

    @contextmanager
    def repeat(self) -> Iterator[None]:
        """This repeat's stimulus, set in the block (`stimulus`): a problem there stops the
        experiment in one line naming the component (a $variable the protocol does not hold,
        a train's argument out of range); then the stimulus is prepared on the array, checked
        against its device before anything moves. One the array cannot play as specified
        (a pin off its grid, a stroke its servos cannot follow, a bus that cannot carry it) is
        refused: never armed, and its row says so (`addData`).

        Raises
        ------
        pinarray.PinArrayError
            What went wrong in the block, after the component's name.
        """
        self.stimulus, self.touch, self.refused = None, None, None
        self._written = False
        try:
            yield
            if self.stimulus is None:
                raise pinarray.PinArrayError("no stimulus was set for this repeat")
        except pinarray.PinArrayError as error:
            raise pinarray.PinArrayError(f"{self.name}: {error}") from None
        try:
            self.device.array.prepare(self.stimulus)
        except pinarray.PinArrayError as error:
            self.refused = str(error)
            logging.warning(f"{self.name}: {_stimulus_name(self.stimulus)} refused by the "
                            f"array, not armed: {error}")

    def armOnFlip(self, win: Any) -> Touch | None:
        """Arm this repeat's stimulus on the window's next flip (`PinArrayDevice.armOnFlip`),
        unless the array refused it.

        Returns
        -------
        Touch or None
            The touch (`touch`); None for a refused stimulus.
        """
        if self.refused is None:
            self.touch = self.device.armOnFlip(self._stimulus(), win)
        return self.touch

    def present(self) -> Touch | None:
        """Start this repeat's stimulus now, not locked to a flip
        (`PinArrayDevice.present` without waiting), unless the array refused it.

        Returns
        -------
        Touch or None
            The touch (`touch`); None for a refused stimulus.
        """
        if self.refused is None:
            self.touch = self.device.present(self._stimulus(), wait=False)
        return self.touch

    @property
    def done(self) -> bool:
        """Whether this repeat's stimulus has ended (played, cut, never started) or was
        refused; False before its start."""
        return self.refused is not None if self.touch is None else self.touch.done

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
        self._written = True
        if self.touch is not None:
            return self.touch.addData(experiment, self.name, columns)
        problem = ("never started: the routine ended before its start" if self.refused is None
                   else f"refused before it played: {self.refused}")
        experiment.addData(f"{self.name}.stimulus", _stimulus_name(self.stimulus))
        if "delivered" in columns:
            experiment.addData(f"{self.name}.delivered", False)
            experiment.addData(f"{self.name}.problem", problem)
            experiment.addData(f"{self.name}.ending", "not started")
        logging.warning(f"{self.name}: {_stimulus_name(self.stimulus)} not delivered: {problem}")
        return None

    def experimentEnded(self, experiment: DataSink,
                        columns: Collection[str] = COLUMN_GROUPS) -> None:
        """The experiment ends (Escape, or its last routine; the compiled script calls this
        from PsychoPy's ``endExperiment``, before the data are saved): a touch still playing is
        cut (pins to rest, torque off), and this repeat's row, if its routine did not write it,
        says what became of it (`addData`: cut, or never started).

        Parameters
        ----------
        experiment : psychopy.data.ExperimentHandler
            Where the row is (``thisExp``).
        columns : collection of str
            The column groups to write, as for `addData`.
        """
        if self._written:
            return
        if self.touch is not None and not self.touch.done:
            self.device.stop("the experiment ending (Escape)")
        self.addData(experiment, columns)

    def __repr__(self) -> str:
        return f"<PinArrayTouch {self.name} on {self.device!r}>"

    def _stimulus(self) -> pinarray.Presentable:
        if self.stimulus is None:
            raise pinarray.PinArrayError(f"{self.name}: no stimulus for this repeat: set it in "
                                         f"`with {self.name}.repeat():`")
        return self.stimulus


@contextmanager
def endOnProblem(experiment: Any, name: str) -> Iterator[None]:
    """A problem in the block (a `pinarray.PinArrayError`: an array that cannot be opened, a
    $variable's value refused) ends the experiment as bad input ends a pinarray command: one
    line naming the component on stderr and in the log, exit status 2. The data so far are
    saved as the script exits (PsychoPy's ``ExperimentHandler`` saves at the interpreter's
    exit) and the array is closed, pins at rest.

    Parameters
    ----------
    experiment : psychopy.data.ExperimentHandler
        The experiment (``thisExp``), whose data file the line names.
    name : str
        The component's name.
    """
    try:
        yield
    except pinarray.PinArrayError as error:
        line = str(error) if str(error).startswith(f"{name}: ") else f"{name}: {error}"
        saved = getattr(experiment, "dataFileName", None)
        logging.error(line)
        logging.flush()
        sys.stderr.write(line + (f" (the data so far are saved as {saved}.csv)" if saved
                                 else "") + "\n")
        raise SystemExit(2) from None


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
