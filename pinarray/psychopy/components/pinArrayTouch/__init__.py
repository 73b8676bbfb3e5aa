"""Builder's "Pin array touch": a stimulus on the pin array, a protocol's or a pattern built
in the dialog, started by the flip that shows its frame, its delivery checked and written to
the data file.

The dialog: the array (a device of Builder's Device Manager: `PinArrayDeviceBackend` offers
every port where bus servos answer, and the simulated array), the protocol to open it for (or
none), the stimulus, when it starts and stops, whether the routine waits for its end, and
which data columns to write. The stimulus is one of two kinds, and Pins chooses (`CHOICE`):

- Pins blank: a stimulus of the protocol's design, by name (Stimulus) and, for a localisation
  design, its pin (Pin) and frequency (Frequency); `pinarray.find_condition` at each repeat.
- Pins given: a pattern built here, those pins raised together on a train of Frequency,
  Duration, Duty cycle and Pulses per cycle; `pinarray.Pattern(pins=..., train=
  pinarray.Train(...))` at each repeat, checked against the array's device then.

A dialog that mixes the two kinds stops the compiling (`CodeGenerationException`, one line),
as does a field that is neither a value nor a $variable, and a pattern's fixed value that
`pinarray.Train` or `pinarray.Pattern` refuse (each on its own, beside $variables too);
$variables are read at their repeat, where a problem ends the experiment in one line naming
the component, exit status 2 (`pinarray.psychopy.endOnProblem`).

The script compiled from it does what docs/programmers/psychopy.md's hand-written one does:
each repeat, the stimulus found or built and prepared on the array (one the array cannot play
as specified is refused there, never armed, and its row says so); on its start frame,
`PinArrayDevice.armOnFlip` (the flip showing that frame starts it and checks it); at the
routine's end, the touch's columns (`pinarray.psychopy.PinArrayTouch.addData`).

Builder imports this module to show the panel and to compile: it imports PsychoPy's
experiment classes and nothing of PsychoPy's hardware or of pinarray's array. The icons are
drawn by tests/psychopy/icons.py.
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

# Which fields make which kind of stimulus: Pins given, a pattern built from these (the
# train's arguments after Pins, each a `pinarray.Train` keyword); Pins blank, a stimulus of the
# protocol's design chosen by those. Frequency serves both: the pattern's train, or a
# localisation condition's. (Not "duration": Builder's loader takes a parameter of that name
# for the stop time of experiments older than PsychoPy 1.70.)
TRAIN_PARAMS = {"frequency": "frequency_hz", "trainDuration": "duration_s",
                "dutyCycle": "duty_cycle", "pulsesPerCycle": "pulses_per_cycle"}
CHOICE = {"pattern": ("pins", *TRAIN_PARAMS), "design": ("stimulus", "pin", "frequency")}


class PinArrayTouchComponent(BaseDeviceComponent):  # type: ignore[misc]  # PsychoPy is untyped
    """A touch on the pin array: a protocol's stimulus or a pattern built in the dialog,
    started by the flip that shows the frame it starts on, checked against that flip, its
    delivery in the data file."""

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
                 protocol: str = "", stimulus: str = "", pin: str = "", pins: str = "",
                 frequency: str = "", trainDuration: str = "", dutyCycle: str = "",
                 pulsesPerCycle: str = "", waitForEnd: bool = True,
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
        self.exp.requireImport(importName="endOnProblem", importFrom="pinarray.psychopy")
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
                       "pins", *TRAIN_PARAMS, *SAVE_PARAMS, "saveStartStop"]
        self.params["waitForEnd"] = Param(
            waitForEnd, valType="bool", inputType="bool", categ="Basic", direct=False,
            label=_translate("Wait for the end"),
            hint=_translate(
                "The touch keeps its routine going until its stop (blank: its own end). When "
                "another component ends the routine first (a key press), checked: the routine "
                "ends once the touch has; unchecked: the routine's end cuts it"))
        # What it presents: a stimulus of the protocol's design, or a pattern built from Pins
        # and the train's fields (`CHOICE`); found or built again at every repeat, so that each
        # field may be a $variable of the loop's conditions file.
        for param, (value, valType, label, hint) in {
            "protocol": (protocol, "file", _translate("Protocol"), _translate(
                "The protocol file (YAML) to open the array for, relative to the experiment's "
                "folder: its servos, calibration and stimuli. Blank: the protocol another Pin "
                "array touch component opens the array for; if none does, no protocol: the "
                "simulated array with pinarray's default device, for patterns built here "
                "(real servos need their protocol)")),
            "stimulus": (stimulus, "str", _translate("Stimulus"), _translate(
                "A stimulus of the protocol: its name (rightwards), or $variable from the "
                "loop's conditions file; found again at every repeat. Blank: chosen by Pin and "
                "Frequency alone. Leave blank for a pattern built from Pins")),
            "pin": (pin, "code", _translate("Pin"), _translate(
                "A localisation design's pin (1-16, 1 bottom-left as the subject sees them), or "
                "$variable; blank: any. Leave blank for a pattern built from Pins")),
            "pins": (pins, "list", _translate("Pins"), _translate(
                "A pattern built here, not a stimulus of the protocol: the pins raised "
                "together (6, 7, 10, 11), or $variable (a cell [6, 7, 10, 11] of the "
                "conditions file), on the train below. Blank: the protocol's stimulus "
                "(Stimulus, Pin)")),
            "frequency": (frequency, "code", _translate("Frequency (Hz)"), _translate(
                "With Pins: the train's cycles a second, in Hz (needed). Without: a "
                "localisation design's train frequency, blank for any. Or $variable")),
            "trainDuration": (trainDuration, "code", _translate("Duration (s)"), _translate(
                "With Pins: the train's length in s (needed), or $variable")),
            "dutyCycle": (dutyCycle, "code", _translate("Duty cycle"), _translate(
                "With Pins: the share of each cycle's pulses that lift the pins, a whole "
                "number of them (0.5 of 10), or $variable; blank: 0.5")),
            "pulsesPerCycle": (pulsesPerCycle, "code", _translate("Pulses per cycle"),
                               _translate("With Pins: servo pulses in one cycle of the train "
                                          "(2-1000), or $variable; blank: 10")),
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
        if self._builds_pattern():
            self._check_pattern()
        else:
            self._check_stimulus()
        inits = getInitVals(self.params)
        code = (
            "# *%(name)s*: touches on the pin array %(deviceLabel)s of Builder's Device Manager,\n"
            "# opened now for its protocol (none: the simulated array, pinarray's default\n"
            "# device): servos checked, pins at rest, stimuli prepared; a problem ends the\n"
            "# experiment in one line (exit status 2)\n"
            "with endOnProblem(thisExp, '%(name)s'):\n"
            "    %(name)s = PinArrayTouch(\n"
            "        device=%(deviceLabel)s,\n"
            "        protocol=%(protocol)s,\n"
            "        name='%(name)s',\n"
            "    )\n"
            "# the experiment ending (Escape) cuts a touch still playing, and its row says so\n"
            "runAtExit.append(lambda: %(name)s.experimentEnded(thisExp, columns=%(columns)s))\n"
        )
        buff.writeIndentedLines(code % {**_blank_as_text(inits, "deviceLabel", "protocol"),
                                        "columns": repr(self._columns())})

    def writeRoutineStartCode(self, buff: Any) -> None:
        inits = getInitVals(self.params)
        if self._builds_pattern():
            train = ", ".join(f"{keyword}={inits[param]}" for param, keyword in TRAIN_PARAMS.items()
                              if self._given(param))
            code = (
                "# *%(name)s*: this repeat's stimulus, the dialog's pins raised together on its "
                "train,\n"
                "# checked against the array's device (one it refuses is not armed: its row "
                "says why)\n"
                "with endOnProblem(thisExp, '%(name)s'), %(name)s.repeat():\n"
                "    %(name)s.stimulus = pinarray.Pattern(\n"
                "        pins=%(pins)s,\n"
                f"        train=pinarray.Train({train}))\n"
            )
        else:
            code = (
                "# *%(name)s*: this repeat's stimulus, found in the protocol's design\n"
                "with endOnProblem(thisExp, '%(name)s'), %(name)s.repeat():\n"
                "    %(name)s.stimulus = pinarray.find_condition(\n"
                "        %(name)s.protocol, stimulus=%(stimulus)s, pin=%(pin)s,\n"
                "        frequency_hz=%(frequency)s)\n"
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
                    "%(name)s.armOnFlip(win)\n"
                )
            else:
                code = (
                    "# started now, not locked to a flip\n"
                    "%(name)s.present()\n"
                )
            buff.writeIndentedLines(code % self.params)
            buff.setIndentLevel(-indented, relative=True)
        # It finishes at its stop, or when the stimulus has ended (played, cut, never started,
        # refused).
        indented = self.writeStopTestCode(buff, extra="or %(name)s.done")
        if indented:
            if self._has_stop_time():
                # Cut now, not on the coming flip: the routine may end without one (every
                # component finished), and a callback left for the next routine's first flip
                # would cut the next touch.
                code = (
                    "if not %(name)s.done:  # its stop came first: cut short\n"
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
                "if %(name)s.status == STARTED and not routineForceEnded and not %(name)s.done:\n"
                "    %(name)s.device.stop('its stop time')\n"
            )
            buff.writeIndentedLines(code % self.params)
        if not self.params["waitForEnd"].val:
            code = (
                "# *%(name)s*: the routine's end cuts it if it is still playing\n"
                "if not %(name)s.done:\n"
                "    %(name)s.device.stop(\"the routine's end\")\n"
            )
            buff.writeIndentedLines(code % self.params)
        code = (
            "# *%(name)s*: its data (once it has ended), and a line in the log\n"
            f"%(name)s.addData(thisExp, columns={self._columns()!r})\n"
        )
        buff.writeIndentedLines(code % self.params)
        super().writeRoutineEndCode(buff)

    def _columns(self) -> list[str]:
        return [group for param, group in SAVE_PARAMS.items() if self.params[param].val]

    def _given(self, param: str) -> bool:
        return str(self.params[param].val).strip() not in ("", "None")

    def _builds_pattern(self) -> bool:
        """Whether the dialog builds a pattern (Pins given), not a stimulus of the protocol's
        design; a dialog that gives fields of both kinds stops the compiling."""
        pattern, design = ([name for name in CHOICE[kind] if self._given(name)
                            and name != "frequency"] for kind in ("pattern", "design"))
        label = {name: str(param.label) for name, param in self.params.items()}
        if pattern and design:
            raise CodeGenerationException(self.params["name"].val, (
                "expected a stimulus of the protocol (Stimulus, Pin) or a pattern built here "
                "(Pins and its train), found both: "
                f"{', '.join(label[name] for name in design + pattern)} given"))
        if pattern and "pins" not in pattern:
            given = ", ".join(label[name] for name in pattern)
            raise CodeGenerationException(self.params["name"].val, (
                f"expected Pins beside {given} (a pattern's train), found Pins blank: give "
                f"Pins, or leave {given} blank"))
        missing = [label[name] for name in ("frequency", "trainDuration")
                   if not self._given(name)]
        if pattern and missing:
            raise CodeGenerationException(self.params["name"].val, (
                "expected Frequency (Hz) and Duration (s) for a pattern built from Pins, "
                f"found {' and '.join(missing)} blank"))
        return bool(pattern)

    def _check_pattern(self) -> None:
        """A pattern's fixed values (not $variables) that are not values, or that
        `pinarray.Train` or `pinarray.Pattern` refuse, stop the compiling in one line: each on
        its own, whatever the other fields are; what depends on the array (its grid, each
        pin's stroke, the servo bus) is checked where it runs, and $variables at their repeat."""
        values = {name: self._value(name) for name in ("pins", *TRAIN_PARAMS)
                  if self._given(name) and not self._variable(name)}
        import pinarray  # only now: Builder imports this module without the array

        fixed = {keyword: values[param] for param, keyword in TRAIN_PARAMS.items()
                 if param in values}
        variable = {keyword for param, keyword in TRAIN_PARAMS.items()
                    if self._given(param) and self._variable(param)}
        try:
            train = pinarray.Train(**_completed(fixed, variable))
            if "pins" in values:
                pinarray.Pattern(pins=values["pins"], train=train)
        except pinarray.PinArrayError as error:
            raise CodeGenerationException(self.params["name"].val, str(error)) from None

    def _variable(self, name: str) -> bool:
        return str(self.params[name].val).strip().startswith("$")

    def _value(self, name: str) -> Any:
        """A field's fixed value, read as the Python literal it must be (``6, 7`` a tuple of
        pins); one that is not stops the compiling, naming the field."""
        text = str(self.params[name].val).strip()
        try:
            return ast.literal_eval(text if name != "pins" or text.startswith(("[", "("))
                                    else f"[{text}]")
        except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
            expected = ("pin numbers such as 6, 7, 10, 11" if name in ("pins",)
                        else "a pin number such as 6" if name == "pin"
                        else "a number such as 5")
            raise CodeGenerationException(self.params["name"].val, (
                f"{self.params[name].label}: expected {expected}, or a $variable, found "
                f"{text!r}")) from None

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
        for name in ("pin", "frequency"):
            if given[name] and not given[name].startswith("$"):
                self._value(name)  # a value, not words: stops the compiling if not
        if not given["protocol"] or any(value.startswith("$") for value in given.values()):
            return
        folder = Path(self.exp.filename).parent if self.exp.filename else Path.cwd()
        protocol_file = folder / given["protocol"]
        pin, frequency_hz = (self._value(name) if given[name] else None
                             for name in ("pin", "frequency"))
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


def _completed(fixed: dict[str, Any], variable: set[str]) -> dict[str, Any]:
    """A train's fixed arguments with its ``variable`` ones ($variables, known at their repeat)
    filled in so that every fixed one passes if any value of those could: as many pulses a
    cycle as make a fixed duty cycle whole (else two, the longest pulse period), one of them
    up, at the frequency whose pulse period fits the seed's 2 ms pulse, for a minute. A train
    with no $variable: exactly its arguments."""
    from fractions import Fraction

    completed = dict(fixed)
    if "pulses_per_cycle" in variable:
        try:
            pulses = Fraction(str(fixed["duty_cycle"])).denominator
        except (KeyError, ValueError, TypeError, ZeroDivisionError):
            pulses = 2
        completed["pulses_per_cycle"] = pulses if 2 <= pulses <= 1000 else 2
    pulses = completed.get("pulses_per_cycle", 10)
    if not isinstance(pulses, int) or isinstance(pulses, bool) or not 2 <= pulses <= 1000:
        return completed  # refused for itself
    if "duty_cycle" in variable:
        completed["duty_cycle"] = Fraction(1, pulses)
    if "frequency_hz" in variable:
        completed["frequency_hz"] = Fraction(500, pulses)  # a pulse period of 2 ms
    if "duration_s" in variable:
        completed["duration_s"] = 60
    return completed


def _blank_as_text(inits: dict[str, Any], *names: str) -> dict[str, Any]:
    """``inits`` with the blank ones of ``names`` as the empty text, not None: a blank device
    means the one pin array, a blank protocol the one it is open for."""
    for name in names:
        if inits[name].val is None:
            inits[name].val, inits[name].valType = "", "str"
    return inits


PinArrayTouchComponent.registerBackend(PinArrayDeviceBackend)
