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

A composition root of its own: it builds on the public face (`import pinarray`) and nothing
in pinarray imports it, so the rest of the package never imports PsychoPy.
"""

from pinarray.psychopy.device import PinArrayDevice
from pinarray.psychopy.touch import Touch

__all__ = ["PinArrayDevice", "Touch"]
