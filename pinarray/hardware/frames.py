"""A trial's goal changes as frames for the wire: limits checked, packets encoded before onset.

What every family shares: a schedule that would take any pin outside its calibrated limits is
refused before anything is sent; each frame's packet is the driver's own encoding
(`ArrayDriver.goal_packet`). A family whose frames are not simply "the goal changes due at
one instant" (a PWM board writes each change in the period before its pulse) builds its own
`PreparedTrial` from the same `Targets` and says so in its `ArrayDriver.prepare`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinarray.errors import PinArrayError
from pinarray.hardware.delivery import Change, PreparedFrame, PreparedTrial

# numpy is imported where targets are looked at (their arrays are numpy's: it is loaded by
# then), not here: the bring-up commands import the Feetech bus, which encodes frames here,
# and need no numpy.
if TYPE_CHECKING:
    import numpy as np

    from pinarray.hardware.driver import ArrayDriver, ArraySetup, Targets


def distinct_pins(pins: np.ndarray) -> list[int]:
    """The pins a target or pulse list names, each once, ascending.

    `numpy.unique` would do, but it imports `numpy.ma` to ask whether the array is masked:
    some 15 ms of every command's and player process's start-up, for arrays never masked.
    """
    import numpy as np

    ordered = np.sort(pins)
    first = np.ones(len(ordered), dtype=bool)
    first[1:] = ordered[1:] != ordered[:-1]
    pins_once: list[int] = ordered[first].tolist()
    return pins_once


def check_limits(targets: Targets, setup: ArraySetup) -> None:
    """Refuse a target list that would take any pin outside its calibrated limits.

    Raises
    ------
    PinArrayError
        Naming the pin, its servo id, the offending position and time, and the limits.
    """
    by_pin = {s.pin: s for s in setup.servos}
    for pin in distinct_pins(targets.pin):
        servo = by_pin.get(pin)
        if servo is None:
            known = ", ".join(map(str, sorted(by_pin)))
            raise PinArrayError(f"the schedule moves pin {pin}, which has no servo (pins: {known})")
        mask = targets.pin == pin
        positions = targets.position_steps[mask]
        outside = (positions < servo.min_steps) | (positions > servo.max_steps)
        if outside.any():
            first = int(outside.argmax())
            time_s = targets.time_ns[mask][first] / 1e9
            raise PinArrayError(
                f"refusing to play: pin {pin} (servo {servo.servo_id}) would go to "
                f"{positions[first]} {setup.position_unit} at {time_s:.3f} s, outside its "
                f"calibrated limits {servo.min_steps}..{servo.max_steps}"
            )


def goal_frames(driver: ArrayDriver, targets: Targets) -> PreparedTrial:
    """One frame per instant at which goals change, due at that instant."""
    setup = driver.setup
    check_limits(targets, setup)
    servo_of_pin = {s.pin: s.servo_id for s in setup.servos}
    frames: list[PreparedFrame] = []
    changes: list[Change] = []
    for frame in targets.frames():
        goals = tuple(
            (servo_of_pin[int(pin)], int(position))
            for pin, position in zip(frame.pins, frame.position_steps, strict=True)
        )
        frames.append(PreparedFrame(frame.time_ns, driver.goal_packet(dict(goals)), goals,
                                    len(changes)))
        changes.extend(
            Change(servo_id, int(pin), goal, frame.time_ns)
            for (servo_id, goal), pin in zip(goals, frame.pins, strict=True)
        )
    return PreparedTrial(tuple(frames), tuple(changes), targets.end_ns,
                         {s.servo_id: s.pin for s in setup.servos})
