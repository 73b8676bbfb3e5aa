"""Builder's "Pin array touch": a protocol's stimulus on the pin array, started by the flip
that shows its frame, its delivery checked and written to the data file.

The dialog: the array (a device of Builder's Device Manager: `PinArrayDeviceBackend` offers
every port where bus servos answer, and the simulated array), the protocol to open it for,
the stimulus by name (and, for a localisation design, its pin and frequency), when it starts
and stops, whether the routine waits for its end, and which data columns to write. The script
compiled from it does what docs/programmers/psychopy.md's hand-written one does: each repeat,
`pinarray.find_condition` in the protocol's design; on its start frame,
`PinArrayDevice.armOnFlip` (the flip showing that frame starts it and checks it); at the
routine's end, the touch's columns (`pinarray.psychopy.PinArrayTouch.addData`).

Builder imports this module to show the panel and to compile: it imports PsychoPy's
experiment classes and nothing of PsychoPy's hardware or of pinarray's array. The icons are
drawn by tests/psychopy/icons.py.

Stimuli built in the dialog from pins and a train, without a protocol's design, come with
stimuli built in code (issue 47, part 2): their fields will sit beside Stimulus, Pin and
Frequency in the Stimulus tab, and `writeRoutineStartCode` will build them where it now finds
a condition.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

from psychopy.experiment.components import BaseDeviceComponent, Param, getInitVals
from psychopy.experiment.devices import DeviceBackend
from psychopy.experiment.utils import CodeGenerationException
from psychopy.localization import _translate

__all__ = ["PinArrayDeviceBackend", "PinArrayTouchComponent"]

DEVICE_CLASS = "pinarray.psychopy.device.PinArrayDevice"
HERE = Path(__file__).parent

# The data column groups the Data tab offers (pinarray.psychopy.touch.COLUMN_GROUPS), each
# with the parameter that chooses it.
SAVE_PARAMS = {"saveDelivered": "delivered", "saveOnset": "onset", "saveStrokes": "strokes"}


class PinArrayTouchComponent(BaseDeviceComponent):  # type: ignore[misc]  # PsychoPy is untyped
    """A touch on the pin array: a protocol's stimulus, started by the flip that shows the
    frame it starts on, checked against that flip, its delivery in the data file."""

    categories = ["Stimuli", "I/O"]
    targets = ["PsychoPy"]
    iconFile = HERE / "pinArrayTouch.png"
    tooltip = _translate("Pin array touch: a tactile stimulus on the pin array, "
                         "started by the screen's flip")
    plugin = "pinarray"
    beta = True
    deviceClasses = [DEVICE_CLASS]

    def __init__(self, exp: Any, parentName: str, name: str = "touch",
                 startType: str = "time (s)", startVal: str = "0.0",
                 stopType: str = "duration (s)", stopVal: str = "",
                 startEstim: str = "", durationEstim: str = "",
                 deviceLabel: str = "",
                 protocol: str = "", stimulus: str = "", pin: str = "", frequency: str = "",
                 waitForEnd: bool = True,
                 saveDelivered: bool = True, saveOnset: bool = True, saveStrokes: bool = True,
                 saveStartStop: bool = True, syncScreenRefresh: bool = True,
                 disabled: bool = False) -> None:
        BaseDeviceComponent.__init__(
            self, exp, parentName, name=name,
            startType=startType, startVal=startVal, stopType=stopType, stopVal=stopVal,
            startEstim=startEstim, durationEstim=durationEstim, deviceLabel=deviceLabel,
            saveStartStop=saveStartStop, syncScreenRefresh=syncScreenRefresh,
            disabled=disabled)
        self.exp.requireImport(importName="pinarray")
        self.exp.requireImport(importName="PinArrayTouch", importFrom="pinarray.psychopy")
        self.params["deviceLabel"].hint = _translate(
            "The pin array, as named in Builder's Device Manager (add it there: a serial port "
            "where bus servos answer, or the simulated array, 'pin array@sim://'); blank: the "
            "one pin array the experiment has")
        self.params["stopVal"].hint = _translate(
            "When the touch ends: blank, at the stimulus's own end; earlier, it is cut short "
            "(pins to rest, and the data say so)")
        self.params["syncScreenRefresh"].categ = "Basic"  # when it starts, beside its start
        self.params["syncScreenRefresh"].label = _translate("Start on the flip")
        self.params["syncScreenRefresh"].hint = _translate(
            "Checked: armed on the frame it starts on and started by the flip that shows that "
            "frame (with a visual stimulus starting at the same time), its onset checked "
            "against PsychoPy's stamp of that flip. Unchecked: started at once when its start "
            "comes, not locked to a flip")

        self.order += ["syncScreenRefresh", "waitForEnd", "protocol", "stimulus", "pin",
                       "frequency", *SAVE_PARAMS, "saveStartStop"]
        self.params["waitForEnd"] = Param(
            waitForEnd, valType="bool", inputType="bool", categ="Basic", direct=False,
            label=_translate("Wait for the end"),
            hint=_translate(
                "The touch keeps its routine going until its stop (blank: its own end). When "
                "another component ends the routine first (a key press), checked: the routine "
                "ends once the touch has; unchecked: the routine's end cuts it"))
        # What it presents: found in the protocol's design at every repeat, so each may be a
        # $variable of the loop's conditions file.
        for param, (value, valType, label, hint) in {
            "protocol": (protocol, "file", _translate("Protocol"), _translate(
                "The protocol file (YAML) to open the array for, relative to the experiment's "
                "folder: its servos, calibration and stimuli. Blank: the protocol the array is "
                "open for already (another Pin array touch component's)")),
            "stimulus": (stimulus, "str", _translate("Stimulus"), _translate(
                "The stimulus's name in the protocol (rightwards), or $variable from the loop's "
                "conditions file; found again at every repeat. Blank: chosen by pin and "
                "frequency alone")),
            "pin": (pin, "code", _translate("Pin"), _translate(
                "A localisation design's pin (1-16, 1 bottom-left as the subject sees them), or "
                "$variable; blank: any")),
            "frequency": (frequency, "code", _translate("Frequency (Hz)"), _translate(
                "A localisation design's train frequency in Hz, or $variable; blank: any")),
        }.items():
            self.params[param] = Param(
                value, valType=valType, inputType="file" if valType == "file" else "single",
                categ="Stimulus", updates="constant", allowedUpdates=[], label=label, hint=hint)
        for param, (checked, label, hint) in {
            "saveDelivered": (saveDelivered, _translate("Save delivered"), _translate(
                "The verdict (delivered as scheduled, within the protocol's tolerance of its "
                "flip), why not, how it ended, and the record of goal changes")),
            "saveOnset": (saveOnset, _translate("Save onset from flip"), _translate(
                "The flip's stamp and the pins' time zero on PsychoPy's clock, and the onset "
                "from the flip in ms")),
            "saveStrokes": (saveStrokes, _translate("Save strokes"), _translate(
                "Each moving pin's commanded and measured stroke (steps) and its lag")),
        }.items():
            self.params[param] = Param(checked, valType="bool", inputType="bool", categ="Data",
                                       direct=False, label=label, hint=hint)

    def writeInitCode(self, buff: Any) -> None:
        self._check_stimulus()
        inits = getInitVals(self.params)
        code = (
            "# *%(name)s*: touches on the pin array %(deviceLabel)s of Builder's Device Manager,\n"
            "# opened for its protocol now (servos checked, pins at rest, stimuli prepared)\n"
            "%(name)s = PinArrayTouch(\n"
            "    device=%(deviceLabel)s,\n"
            "    protocol=%(protocol)s,\n"
            "    name='%(name)s',\n"
            ")\n"
        )
        buff.writeIndentedLines(code % _blank_as_text(inits, "deviceLabel", "protocol"))

    def writeRoutineStartCode(self, buff: Any) -> None:
        inits = getInitVals(self.params)
        code = (
            "# *%(name)s*: this repeat's stimulus, found in the protocol's design\n"
            "%(name)s.stimulus = pinarray.find_condition(\n"
            "    %(name)s.device.protocol, stimulus=%(stimulus)s, pin=%(pin)s,\n"
            "    frequency_hz=%(frequency)s)\n"
            "%(name)s.touch = None\n"
        )
        buff.writeIndentedLines(code % inits)

    def writeFrameCode(self, buff: Any) -> None:
        buff.writeIndentedLines(f"\n# *{self.params['name']}* updates\n")
        indented = self.writeStartTestCode(buff)
        if indented:
            if self.params["syncScreenRefresh"].val:
                code = (
                    "# armed now: the flip that shows this frame starts it, and its stamp "
                    "checks it\n"
                    "%(name)s.touch = %(name)s.device.armOnFlip(%(name)s.stimulus, win)\n"
                )
            else:
                code = (
                    "# started now, not locked to a flip\n"
                    "%(name)s.touch = %(name)s.device.present(%(name)s.stimulus, wait=False)\n"
                )
            buff.writeIndentedLines(code % self.params)
            buff.setIndentLevel(-indented, relative=True)
        # It finishes at its stop, or when the stimulus has ended (played, cut, never started).
        indented = self.writeStopTestCode(buff, extra="or %(name)s.touch.done")
        if indented:
            if self._has_stop_time():
                # Cut now, not on the coming flip: the routine may end without one (every
                # component finished), and a callback left for the next routine's first flip
                # would cut the next touch.
                code = (
                    "if not %(name)s.touch.done:  # its stop came first: cut short\n"
                    "    %(name)s.device.stop('its stop time')\n"
                )
                buff.writeIndentedLines(code % self.params)
            buff.setIndentLevel(-indented, relative=True)

    def writeRoutineEndCode(self, buff: Any) -> None:
        if self._has_stop_time():
            # A routine of known duration ends on its own clock, which started before this
            # component's first flip (the stop time counts from it): at a stop time that is
            # the routine's end, the check in the frame code may never have run.
            code = (
                "# *%(name)s*: the routine ended on its clock at the stop time: cut there too\n"
                "if (%(name)s.touch is not None and %(name)s.status != FINISHED\n"
                "        and not routineForceEnded and not %(name)s.touch.done):\n"
                "    %(name)s.device.stop('its stop time')\n"
            )
            buff.writeIndentedLines(code % self.params)
        if not self.params["waitForEnd"].val:
            code = (
                "# *%(name)s*: the routine's end cuts it if it is still playing\n"
                "if %(name)s.touch is not None and not %(name)s.touch.done:\n"
                "    %(name)s.device.stop(\"the routine's end\")\n"
            )
            buff.writeIndentedLines(code % self.params)
        columns = [group for param, group in SAVE_PARAMS.items() if self.params[param].val]
        code = (
            "# *%(name)s*: its data (once it has ended), and a line in the log\n"
            f"%(name)s.addData(thisExp, columns={columns!r})\n"
        )
        buff.writeIndentedLines(code % self.params)
        super().writeRoutineEndCode(buff)


    def _has_stop_time(self) -> bool:
        """Whether the dialog gives the touch a stop (it is cut there if still playing)."""
        return self.params["stopVal"].val not in ("", None, -1, "None")

    def _check_stimulus(self) -> None:
        """A stimulus given as constants that the protocol does not hold stops the compiling,
        with the protocol's own words (its file and the stimuli it holds), not the experiment
        at its first trial. Values from the loop ($variables), and a protocol that is not
        where the experiment is compiled (it is read, and checked, where it runs), are left to
        the run."""
        given = {name: str(self.params[name].val).strip()
                 for name in ("protocol", "stimulus", "pin", "frequency")}
        if not given["protocol"] or any(value.startswith("$") for value in given.values()):
            return
        folder = Path(self.exp.filename).parent if self.exp.filename else Path.cwd()
        protocol_file = folder / given["protocol"]
        try:
            pin, frequency_hz = (ast.literal_eval(given[name]) if given[name] else None
                                 for name in ("pin", "frequency"))
        except (ValueError, SyntaxError):
            return  # code, not a value: it is known at run time only
        if not protocol_file.is_file():
            return
        import pinarray  # only now: Builder imports this module without the array

        try:
            pinarray.find_condition(pinarray.load_protocol(protocol_file),
                                    stimulus=given["stimulus"] or None, pin=pin,
                                    frequency_hz=frequency_hz)
        except pinarray.PinArrayError as error:
            raise CodeGenerationException(self.params["name"].val, str(error)) from None


class PinArrayDeviceBackend(DeviceBackend):  # type: ignore[misc]  # PsychoPy is untyped
    """The pin array in Builder's Device Manager: each serial port where bus servos answer
    (`PinArrayDevice.getAvailableDevices`), and the simulated array. The compiled script sets
    it up by name (``deviceManager.addDevice``); the component opens it for its protocol."""

    backendLabel = "Pin array (pinarray)"
    deviceClass = DEVICE_CLASS
    icon = "light/pinArrayTouch.png"
    plugin = "pinarray"

    def getParams(self) -> tuple[dict[str, Any], list[str]]:
        return {}, []

    def writeDeviceCode(self, buff: Any) -> None:
        self.writeBaseDeviceCode(buff, close=True)


def _blank_as_text(inits: dict[str, Any], *names: str) -> dict[str, Any]:
    """``inits`` with the blank ones of ``names`` as the empty text, not None: a blank device
    means the one pin array, a blank protocol the one it is open for."""
    for name in names:
        if inits[name].val is None:
            inits[name].val, inits[name].valType = "", "str"
    return inits


PinArrayTouchComponent.registerBackend(PinArrayDeviceBackend)
