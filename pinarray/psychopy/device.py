"""The pin array as a PsychoPy device: opened through the public API, a stimulus presented at
once or armed to start on the window's next flip, and what was delivered handed back as a
`Touch` for the experiment's data and log.

Defining the class registers it with PsychoPy's `DeviceManager` (`BaseDevice.__init_subclass__`:
its class path and the alias ``"pinarray"``); PsychoPy's plugin manager imports it through the
entry point ``psychopy.hardware: PinArrayDevice`` of pinarray's package.

A device may be set up before it is opened: Builder's Device Manager names a port (or the
simulated array) on this machine, and the experiment's Pin array touch component opens it for
its protocol (`open`) as the experiment starts.

One device per port, as PsychoPy's own `SerialDevice`: asking for a port (by any name: a
link such as ``/dev/serial/by-id/...``) or ``sim://`` URL already open hands back the device
holding it, and `DeviceManager.addDevice` under a name a
pin array already has closes that array first (PsychoPy's manager would store the new device
over the old one and leave the old one open, its pins torqued).

A stop stops at once: closing the device (`DeviceManager.removeDevice`, the experiment's end),
`core.quit()` (Escape in a Builder script), the window a touch was armed on closing, and
Ctrl-C cut a stimulus still playing: every pin to rest and torque off.
"""

from __future__ import annotations

import os
import sys
import threading
import weakref
from os import PathLike, fspath
from pathlib import Path
from types import TracebackType
from typing import Any, ClassVar

from psychopy import clock, core, logging
from psychopy.hardware.base import BaseDevice

import pinarray
from pinarray.psychopy.timeline import Timeline
from pinarray.psychopy.touch import Touch

__all__ = ["PinArrayDevice"]

SIMULATED = "sim://"
"""The simulated array, as `getAvailableDevices` offers it (``sim://?...`` URLs add faults)."""

# How often a device looks whether a window it armed a stimulus on has closed, in s.
WINDOW_WATCH_S = 0.02


class _QuitWatch(threading.Thread):
    """Stops the device's pins when PsychoPy quits or a window it armed on closes.

    `psychopy.core.quit` calls ``stop()`` on every thread that has ``stop`` and ``running``
    (the way it ends its own event threads) before it exits: so `core.quit()` (and Escape in
    a Builder script, which calls it) stops the pins at once, before the interpreter's exit
    closes the device.
    """

    running = 1  # never 0: core.quit would wait for it to become so

    def __init__(self, device: PinArrayDevice) -> None:
        super().__init__(name=f"pinarray: quit watch of {device.url}", daemon=True)
        self._device = weakref.ref(device)
        self._ended = threading.Event()

    def stop(self) -> None:
        """PsychoPy quits: pins to rest, torque off, now."""
        device = self._device()
        if device is not None:
            device._stop("PsychoPy quitting (core.quit)")

    def end(self) -> None:
        self._ended.set()

    def run(self) -> None:
        while not self._ended.wait(WINDOW_WATCH_S):
            device = self._device()
            if device is None:
                return
            window = device._armed_window()
            if window is not None and not any(ref() is window for ref in core.openWindows):
                device._stop("its window closing")


class PinArrayDevice(BaseDevice, aliases=["pinarray"]):  # type: ignore[call-arg]  # PsychoPy is untyped
    """A protocol's pin array, open: real bus servos on a serial port, or the simulated array.

    Open it directly, as a context manager, or through PsychoPy's device manager
    (``DeviceManager.addDevice("pinarray", "touch", protocol=..., port=...)``), which closes
    it when the experiment ends. Closing rests the pins and switches torque off, however the
    experiment ends. Asking for a port already open hands back the device that holds it.

    Parameters
    ----------
    protocol : str, path-like, pinarray.Protocol or None
        The protocol file (or one read with `pinarray.load_protocol`): its device section names
        the servos, their calibration and the delivery tolerance; its stimuli are what can be
        presented. None: the device is set up for its port, and opened for a protocol by
        `open` (as Builder's Device Manager sets it up for a Pin array touch component).
    port : str or None
        The serial device of real bus servos (``/dev/ttyUSB0``), or the I2C bus of a PWM board.
    sim : str or None
        A ``sim://`` URL (faults included: ``sim://?drop=0.01&seed=3``). With neither ``port``
        nor ``sim``: the simulated array. Simulated servos play in real time here, on the
        clock real ones play on, so that their onsets and the screen's flips share one line.

    Raises
    ------
    pinarray.PinArrayError
        The port held by another program's array (`pinarray.PortInUse`, naming it), the same
        port asked for with another protocol, servos missing (named), a protocol with problems.
    """

    _open: ClassVar[dict[str, PinArrayDevice]] = {}  # port's real path or sim URL -> device

    def __new__(cls, protocol: str | PathLike[str] | pinarray.Protocol | None = None,
                port: str | None = None, sim: str | None = None) -> PinArrayDevice:
        existing = cls._open.get(_device_key(_asked_for(port, sim)))
        _close_another_array_of_the_same_name(sys._getframe(1), existing)
        if existing is not None:
            return existing  # as PsychoPy's SerialDevice does for a port it has open
        device: PinArrayDevice = super().__new__(cls)
        return device

    def __init__(self, protocol: str | PathLike[str] | pinarray.Protocol | None = None,
                 port: str | None = None, sim: str | None = None) -> None:
        if getattr(self, "_asked_for", None) is not None:  # handed back by __new__
            if protocol is not None and protocol != "":
                self.open(protocol)  # checks it is the protocol it is open for, if it is
            return
        if port is None and sim is None:
            sim = SIMULATED
        self._port, self._sim = port, sim
        self._asked_for = _asked_for(port, sim)  # as a profile names it
        self._key = _device_key(self._asked_for)  # the same whichever link names the port
        self._clock = pinarray.MonotonicClock()
        self._array: pinarray.PinArray | None = None
        self._last_touch: Touch | None = None
        self._windows: weakref.WeakKeyDictionary[Any, None] = weakref.WeakKeyDictionary()
        self._watch: _QuitWatch | None = None
        PinArrayDevice._open[self._key] = self
        if port is not None:
            self.portString = port  # where PsychoPy's device manager looks for ports in use
        if protocol is not None and protocol != "":
            self.open(protocol)
        else:
            logging.exp(f"pinarray {self._asked_for}: set up, to be opened for a protocol")

    def open(self, protocol: str | PathLike[str] | pinarray.Protocol | None) -> PinArrayDevice:
        """Open the array for ``protocol``, if it is not open yet: its servos checked, held,
        pins at rest, every stimulus of the protocol prepared. A device open already for the
        same protocol (or asked for with None) is left as it is.

        Parameters
        ----------
        protocol : str, path-like, pinarray.Protocol or None
            As for the class. None: no protocol, the simulated array with pinarray's default
            device (`pinarray.open_array` without one), for stimuli built in code; real
            servos are refused without the protocol that calibrates them.

        Returns
        -------
        PinArrayDevice
            This device, open.

        Raises
        ------
        pinarray.PinArrayError
            A device open already for another protocol; as for the class.
        """
        if self._array is not None and self._array.is_open:
            if protocol is not None:
                self._check_same_protocol(protocol)
            return self
        if protocol is not None and not isinstance(protocol, pinarray.Protocol):
            protocol = pinarray.load_protocol(protocol)
        self._array = pinarray.open_array(protocol, port=self._port, sim=self._sim,
                                          clock=self._clock)
        PinArrayDevice._open[self._key] = self  # again, after a close
        # Every stimulus compiled and encoded now: arming one on a flip then costs the frame
        # loop only the call.
        for condition in self._array.protocol.design.conditions:
            self._array.prepare(condition)
        self._watch = _QuitWatch(self)
        self._watch.start()
        _ready_for_quit()
        for warning in self._array.warnings:
            logging.warning(f"pinarray {self.url}: {warning}")
        logging.exp(f"pinarray {self.url}: open for protocol {self.protocol.name!r}, pins at rest")
        return self

    @property
    def is_open(self) -> bool:
        """Whether the array is open (for a protocol), its pins held."""
        return self._array is not None and self._array.is_open

    @property
    def array(self) -> pinarray.PinArray:
        """The open array (`pinarray.PinArray`): everything the library offers.

        Raises
        ------
        pinarray.PinArrayError
            A device set up but not opened for a protocol (`open`).
        """
        if self._array is None:
            raise pinarray.PinArrayError(
                f"the pin array {self._asked_for} is not open for a protocol: open it with "
                "device.open(protocol), or give the Pin array touch component a protocol")
        return self._array

    @property
    def protocol(self) -> pinarray.Protocol:
        """The protocol the array was opened for."""
        return self.array.protocol

    @property
    def url(self) -> str:
        """The serial device of real servos, or the ``sim://`` URL of the simulated array."""
        return self._array.url if self._array is not None else self._asked_for

    def __repr__(self) -> str:
        state = repr(self._array) if self._array is not None else "not open"
        return f"<PinArrayDevice {self._asked_for}: {state}>"

    # -- what PsychoPy's device manager asks ------------------------------------------------

    def isSameDevice(self, other: object) -> bool:
        """Whether ``other`` (a device, or a profile from `getAvailableDevices`, or the keyword
        arguments of this class) is this array: the same serial port or ``sim://`` URL."""
        if isinstance(other, PinArrayDevice):
            return other.url == self.url
        if isinstance(other, dict):
            return bool({self.url, self._asked_for} & {other.get("port"), other.get("sim")})
        return False

    @staticmethod
    def getAvailableDevices() -> list[dict[str, Any]]:
        """The arrays this machine can open: each serial port on which bus servos answer a
        PING (`pinarray.find_servo_ports`; ports an array holds are not asked), then the
        simulated array.

        Returns
        -------
        list of dict
            Each a profile PsychoPy's device manager shows: ``deviceName``, and ``port`` or
            ``sim`` (keyword arguments of this class, beside the protocol).
        """
        from psychopy.hardware.manager import DeviceManager
        from serial.tools.list_ports import comports

        busy = set(PinArrayDevice._open) | {
            getattr(device, "portString", None) for device in DeviceManager.devices.values()}
        free = [info.device for info in comports() if info.device not in busy]
        profiles: list[dict[str, Any]] = [
            {"deviceName": f"pin array@{found.port}", "port": found.port}
            for found in pinarray.find_servo_ports(free)]
        profiles.append({"deviceName": f"pin array@{SIMULATED}", "sim": SIMULATED})
        return profiles

    # -- presenting ----------------------------------------------------------------------------

    def present(self, stimulus: pinarray.Presentable, wait: bool = True) -> Touch:
        """Play ``stimulus`` now, not locked to a flip, and (by default) wait until it has
        played.

        Parameters
        ----------
        stimulus : pinarray.PlannedTrial or pinarray.Condition (any paradigm's)
            A trial of the protocol's plan or a condition of its design
            (``pinarray.find_condition(device.protocol, stimulus="rightwards")``).
        wait : bool
            True: played `pinarray.PinArray.lead_ns` from the call, returned once it has
            ended. False: started at once (its time zero a fraction of a millisecond after
            the call), returned while it plays (`Touch.wait`).
        """
        timeline = self._timeline()
        if wait:
            result: pinarray.Delivery | pinarray.Armed = self.array.present(stimulus)
        else:
            result = self.array.arm(stimulus)
            result.start()
        touch = Touch(stimulus, timeline, result, _clock_zero_s(), on_flip=False)
        self._last_touch = touch
        return touch

    def armOnFlip(self, stimulus: pinarray.Presentable, win: Any) -> Touch:
        """Arm ``stimulus`` to start on the window's next flip, and return at once.

        The stimulus is ready in the player before the flip and started by the flip itself
        (`win.callOnFlip`, right after PsychoPy stamps it): its time zero lies a fraction of a
        millisecond after the flip that actually happened, however late that flip was. The
        touch keeps PsychoPy's stamp of the flip (`win.timeOnFlip`) and the pins' measured
        onset: a touch whose onset lay further from its flip than the protocol's delivery
        tolerance is not delivered, with the reason. Arming costs the frame loop well under a
        millisecond (`make bench`).

        Parameters
        ----------
        stimulus : pinarray.PlannedTrial or pinarray.Condition (any paradigm's)
            As for `present`.
        win : psychopy.visual.Window
            The window whose next flip starts the stimulus. A touch whose flip is never made
            (its `Touch.wait` comes first) is cancelled: not delivered, nothing moved.

        Returns
        -------
        Touch
            Its `Touch.wait` (or `Touch.addData`) gives what was delivered, once played.

        Raises
        ------
        pinarray.PinArrayError
            A stimulus the protocol does not hold, another one still playing, a closed device,
            a ``win`` that is not a window (nothing is left armed).
        """
        if not all(callable(getattr(win, method, None)) for method in ("timeOnFlip", "callOnFlip")):
            raise pinarray.PinArrayError(
                f"armOnFlip: win: expected a psychopy.visual.Window, found a "
                f"{type(win).__name__}")
        armed = self.array.arm(stimulus)
        touch = Touch(stimulus, self._timeline(), armed, _clock_zero_s(), on_flip=True)
        try:
            win.timeOnFlip(touch._flip_stamp, "flip")
            win.callOnFlip(touch._flipped)  # after the stamp: PsychoPy calls them in this order
        except Exception as error:  # a look-alike that failed: nothing is left armed
            armed.cancel()
            raise pinarray.PinArrayError(
                f"armOnFlip: win: {type(win).__name__} did not take the flip's callbacks "
                f"({type(error).__name__}: {error}); nothing is armed") from None
        self._last_touch = touch
        self._windows[win] = None
        touch._window = weakref.ref(win)
        return touch

    # -- leaving -------------------------------------------------------------------------------

    def stop(self, by: str = "stop()") -> None:
        """Cut the stimulus armed or playing now, if any: every pin to rest, torque off (the
        next stimulus turns it on again). Its touch then says it was cut, and ``by`` what.

        Parameters
        ----------
        by : str
            What cut it, in words, for the data and the log ("the routine's end").
        """
        self._stop(by)

    def close(self) -> pinarray.SafeStopReport | None:
        """Cut a stimulus still playing, then pins to rest, torque off, port closed. Safe to
        call more than once (PsychoPy's device manager calls it at exit).

        Returns
        -------
        pinarray.SafeStopReport or None
            What the safe stop confirmed; None for a device never opened (no pin was held).
        """
        if PinArrayDevice._open.get(self._key) is self:
            del PinArrayDevice._open[self._key]
        if self._watch is not None:
            self._watch.end()
        if self._array is None:
            return None
        report = self._array.close()
        logging.exp(f"pinarray {self.url}: closed: {report.describe()}")
        return report

    def __enter__(self) -> PinArrayDevice:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if self._array is not None:
            self._array.__exit__(kind, error, traceback)  # cuts a stimulus still playing
        self.close()

    # -- below the face ------------------------------------------------------------------------

    def _stop(self, by: str) -> None:
        """Cut the stimulus playing, if any: pins to rest and torque off (the quit watch's)."""
        touch = self._last_touch
        if self.is_open and touch is not None and not touch.done:
            logging.warning(f"pinarray {self.url}: {touch.stimulus} cut short by {by}")
            touch._cut_by = by
            try:
                self.array.stop()
            except pinarray.PinArrayError:
                pass  # closed meanwhile: the close rested the pins

    def _armed_window(self) -> Any:
        """The window the touch armed or playing now was armed on (None: none is)."""
        touch = self._last_touch
        if touch is None or touch.done or touch._window is None:
            return None
        return touch._window()

    def _check_same_protocol(self, protocol: str | PathLike[str] | pinarray.Protocol) -> None:
        if isinstance(protocol, pinarray.Protocol):
            same = protocol == self.protocol
        else:
            same = Path(fspath(protocol)).resolve() == Path(self.protocol.source).resolve()
        if not same:
            raise pinarray.PinArrayError(
                f"{self._asked_for} is open already as a pin array for protocol "
                f"{self.protocol.name!r} ({self.protocol.source}): remove that device first "
                "(DeviceManager.removeDevice), or ask for it with the same protocol")

    def _timeline(self) -> Timeline:
        return Timeline.measure(clock.getTime, self.array.now_ns)


def _ready_for_quit() -> None:
    """`core.quit()` imports ioHub's client before it stops the threads it knows (the quit
    watch among them; psychopy/core.py, `quit`): imported now, as the device opens, so that a
    quit reaches the pins at once, not a quarter of a second later (the import's time here)."""
    try:
        import psychopy.iohub.client  # noqa: F401
    except ImportError:
        pass  # no ioHub in this PsychoPy: core.quit will not import it either


def _asked_for(port: str | None, sim: str | None) -> str:
    return port if port is not None else sim if sim is not None else SIMULATED


def _device_key(asked_for: str) -> str:
    """A serial device's real path (the same whichever link names it); a URL, or what is no
    path at all (refused as the array opens, in pinarray's words), as it is."""
    if not isinstance(asked_for, str) or "://" in asked_for or not os.path.exists(asked_for):
        return asked_for
    return os.path.realpath(asked_for)


def _close_another_array_of_the_same_name(caller: Any, kept: PinArrayDevice | None) -> None:
    """When `DeviceManager.addDevice` asks for a device under a name another pin array has
    (not ``kept``, the one handed back), close that array first: the manager stores the new
    device over it without closing it (psychopy/hardware/manager.py, `addDevice`), which would
    leave its pins torqued and its port held. The name is the manager's own argument, read
    from its frame."""
    from psychopy.hardware.manager import DeviceManager

    if (caller.f_code.co_name != "addDevice"
            or caller.f_globals.get("__name__") != "psychopy.hardware.manager"):
        return
    name = caller.f_locals.get("deviceName")
    named = DeviceManager.devices.get(name)
    if isinstance(named, PinArrayDevice) and named is not kept:
        logging.exp(f"pinarray: a new device named {name!r}: closing the pin array of that name")
        DeviceManager.removeDevice(name)


def _clock_zero_s() -> float:
    """Where PsychoPy's flip and log clock (`logging.defaultClock`) stands at zero, on its
    time base, in s."""
    return float(logging.defaultClock.getLastResetTime())
