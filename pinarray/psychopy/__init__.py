"""pinarray in PsychoPy: the pin array as a PsychoPy hardware device (``pip install
'pinarray[psychopy]'``).

PsychoPy's plugin manager finds it by entry point (group ``psychopy.hardware``) and defining
`PinArrayDevice` registers it with the `DeviceManager` (alias ``"pinarray"``)::

    from psychopy.hardware.manager import DeviceManager

    touch_device = DeviceManager.addDevice("pinarray", "touch",
                                           protocol="protocols/apparent_motion.yaml")
    wave = pinarray.find_condition(touch_device.protocol, stimulus="rightwards")
    touch = touch_device.armOnFlip(wave, win)     # returns at once: the next flip starts it
    flash.draw()
    win.flip()                                    # the flash and the wave start together
    touch.addData(thisExp)                        # onset from the flip, delivery, strokes

Builder's "Pin array touch" component is `pinarray.psychopy.components` (entry point
``psychopy.experiment.components``); a compiled experiment holds each one as a
`PinArrayTouch`, a problem there ending the experiment in one line (`endOnProblem`).

A composition root of its own: it builds on the public face (`import pinarray`) and nothing
in pinarray imports it, so the rest of the package never imports PsychoPy. Its names are
imported on first use (PEP 562), so that Builder can load the component without the device,
PsychoPy's hardware or pinarray's array behind it.
"""

import importlib

# typing.TYPE_CHECKING without importing typing: type checkers take this name as true.
TYPE_CHECKING = False

__all__ = ["PinArrayDevice", "PinArrayTouch", "Touch", "endOnProblem"]

_HOME_OF = {
    "PinArrayDevice": "pinarray.psychopy.device",
    "PinArrayTouch": "pinarray.psychopy.routine",
    "Touch": "pinarray.psychopy.touch",
    "endOnProblem": "pinarray.psychopy.routine",
}


def __getattr__(name: str) -> object:
    module = _HOME_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'pinarray.psychopy' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


if TYPE_CHECKING:  # what type checkers and documentation tools see; never run
    from pinarray.psychopy.device import PinArrayDevice
    from pinarray.psychopy.routine import PinArrayTouch, endOnProblem
    from pinarray.psychopy.touch import Touch
