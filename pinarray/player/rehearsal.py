"""Every stimulus played before the run: on the simulated bus servos, as a sitting plays it.

`pinarray validate` checks a protocol's conditions with what the protocol states (the pulses,
the datasheet's speed, the bus's frames: `pinarray.protocol.seam.check_conditions`); those
checks cannot see everything that decides whether `pinarray batch` delivers a stimulus: the
servo's acceleration and backlash, where a reversing horn turns back, and whether the
verifier can sample a moving pin densely enough to measure its stroke between the frames.
The simulator models all of it, so a `Rehearsal` plays each stimulus there: the simulated
array the protocol's device opens (its ``port`` when that is a ``sim://`` URL, else the
default one), in virtual time, through the same player, verifier and stroke measurement as a
sitting, under the sitting's retry policy (`MAX_ATTEMPTS`, kept here for both). A stimulus
it does not deliver is refused at validate with the player's own words; what it delivers,
batch delivers on the same simulator. One model, not a second one written beside it.

A stimulus is played once for every shape it has on the bus (each pin's train, start and
calibration, by rank: identical simulated servos play the same shape alike whichever pins
it moves), so a design's pins or repetitions cost nothing more.

Bus servos only, with feasibility from the datasheet: a PWM board's conditions are planned
on the board (`pinarray.player.families.board_refusals`), and a measured servo response is
the model of the servos it was measured on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from types import TracebackType

from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.driver import ArrayDriver
from pinarray.player.families import open_array
from pinarray.player.playback import play_prepared, prepare_trial
from pinarray.protocol.model import (
    Datasheet,
    Device,
    PinCalibration,
    PinDrive,
    ServoSettings,
    Train,
    is_simulated,
)
from pinarray.schedule import compile_drives

# How many times a trial whose stimulus failed is presented before the run stops: a sitting's
# retry policy (`pinarray.session.sitting`), which a rehearsal follows.
MAX_ATTEMPTS = 3
# Said after a pin that fell short with every goal on time: what a lab changes so that it plays.
STROKE_ADVICE = ("; command a smaller stroke (device: calibration: positions; on a longer "
                 "horn, lever_mm, fewer steps lift the pin as far) or a lower frequency")

Shape = tuple[tuple[int, int, Train, PinCalibration], ...]


def rehearses(device: Device) -> bool:
    """Whether a `Rehearsal` plays this device's stimuli (see the module docstring)."""
    return isinstance(device.servo, ServoSettings) and isinstance(device.bandwidth, Datasheet)


class Rehearsal:
    """Plays stimuli on the simulated array; `pinarray.protocol.load.load_protocol`'s
    ``rehearse``. Use as a context manager: the simulated array is closed at its end."""

    def __init__(self) -> None:
        self._arrays: dict[Device, tuple[ArrayDriver, VirtualClock]] = {}
        self._verdicts: dict[tuple[Device, Shape], str | None] = {}

    def __call__(self, drives: Sequence[PinDrive], device: Device) -> str | None:
        """Why ``drives`` are not delivered on ``device``'s simulated servos (the last
        attempt's problem, in the player's words), or None: delivered, or not rehearsed."""
        if not rehearses(device) or not drives:
            return None
        key = (device, _shape(drives, device))
        if key not in self._verdicts:
            self._verdicts[key] = self._play(drives, device)
        return self._verdicts[key]

    def _play(self, drives: Sequence[PinDrive], device: Device) -> str | None:
        try:
            bus, clock = self._array(device)
            schedule = compile_drives(drives, device)
            trial = prepare_trial(bus, schedule.targets, schedule.pulses)
            problem = ""
            for _ in range(MAX_ATTEMPTS):
                report = play_prepared(bus, trial, clock, tolerance_ns=device.delivery_tolerance_ns,
                                       release_at_end=False,
                                       stroke_tolerance=device.stroke_tolerance)
                problem = report.delivery.problem
                if not problem:
                    return None
            strokes = report.delivery.strokes
            if strokes is not None and strokes.short and problem == strokes.problem():
                problem += STROKE_ADVICE  # every goal on time, the servo too slow to follow
        except PinArrayError as error:
            problem = str(error)
        assert isinstance(device.servo, ServoSettings)
        servo = device.servo
        return (f"played as a run plays it, on simulated {servo.model} servos "
                f"({servo.baud_rate} baud, {servo.speed_steps_per_s} steps/s, return delay "
                f"{servo.return_delay_us} us), it was not delivered in {MAX_ATTEMPTS} "
                f"attempts: {problem}")

    def _array(self, device: Device) -> tuple[ArrayDriver, VirtualClock]:
        if device not in self._arrays:
            clock = VirtualClock()
            url = device.port if is_simulated(device.port) else None
            bus = open_array(device, None, url, clock)
            try:
                bus.check_servos()
                bus.hold()
                bus.move_to_rest()
            except BaseException:
                bus.close()
                raise
            self._arrays[device] = (bus, clock)
        return self._arrays[device]

    def close(self) -> None:
        """Rest and release the simulated servos."""
        for bus, _ in self._arrays.values():
            bus.rest_and_release()
            bus.close()
        self._arrays.clear()

    def __enter__(self) -> Rehearsal:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


def _shape(drives: Sequence[PinDrive], device: Device) -> Shape:
    """What decides a rehearsal of ``drives``: each train's start, its pin by rank, the
    train and the pin's calibration (but not which pin or servo it is)."""
    rank = {pin: n for n, pin in enumerate(sorted({d.pin for d in drives}), start=1)}
    shape = [(d.delay_ns, rank[d.pin], d.train,
              replace(device.calibration(d.pin), pin=0, servo_id=0)) for d in drives]
    return tuple(sorted(shape, key=lambda item: (item[0], item[1])))
