"""Jogging one hobby servo's pin on a PCA9685 board while a person watches.

Calibration (`pinarray pwm calibrate`) finds a pin's rest and "up" pulse widths this way. Only
the pin's channel carries pulses (the others stay full off: their servos limp, as at power-up);
a new width is approached in steps of one board period at `JOG_SPEED_US_PER_S` at most, since
a hobby servo runs at its full speed to any width it is given; every width is read back from
the board. Hobby servos say nothing, so a reading is what the board holds, not where the horn
is; a board found asleep (it lost power) is started again at the pin's rest width. However
jogging ends, `PwmJog.release` sends the pin to rest, holds it there for the servo's travel
time, then turns every channel full off.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction
from math import ceil

from pinarray.clock import Clock
from pinarray.hardware.driver import GoalOutOfRange, SafeStopReport, ServoSetup
from pinarray.hardware.pca9685.driver import Pca9685Array
from pinarray.hardware.pca9685.registers import COUNTS, period_ns, prescale_for
from pinarray.units import NS_PER_S, NS_PER_US

# The widths a jog may send: the usual hobby-servo range (many stop hard at its ends), widened
# to hold the pin's own calibrated limits when they lie beyond it, and always a pulse shorter
# than the board's period at its pwm_hz.
JOG_RANGE_US = (500, 2500)
# How fast a jogged width changes, at most: about 90 degrees a second on a 9/100 deg/us servo.
JOG_SPEED_US_PER_S = 1000


@dataclass(frozen=True)
class PwmJogReading:
    """The width the pin's channel was sent and whether the board holds it (read back)."""

    goal_us: int
    held: bool


class PwmJog:
    """One pin's hobby servo on a board, driven to widths a person chooses.

    Parameters
    ----------
    array : Pca9685Array
        The board, opened (not yet checked) for the protocol's device.
    pin : int
        The pin to jog; its channel and rest come from ``array.setup``.
    clock : Clock, optional
        What the ramp waits on (default the board's): a `pinarray.stop.StoppableClock` ends a
        wait on a stop request.
    """

    def __init__(self, array: Pca9685Array, pin: int, clock: Clock | None = None):
        servo = next(s for s in array.setup.servos if s.pin == pin)
        self.array = array
        self.clock = clock or array.clock
        self.servo = servo
        setup = array.setup
        period = period_ns(setup.osc_hz, prescale_for(setup.osc_hz, Fraction(setup.pwm_hz)))
        widest = ceil(period * (COUNTS - 1) / COUNTS / NS_PER_US) - 1  # a pulse, not full on
        self.bounds = (min(JOG_RANGE_US[0], servo.min_steps),
                       min(max(JOG_RANGE_US[1], servo.max_steps), widest))
        self.goal_us = servo.rest_steps  # what the channel was last sent
        self.started = False
        self._only(servo.rest_steps)

    @property
    def name(self) -> str:
        return f"pin {self.servo.pin} (channel {self.servo.servo_id})"

    def _only(self, rest_us: int) -> None:
        """The board drives this pin's channel alone, within the jog's bounds."""
        low, high = min(self.bounds[0], rest_us), max(self.bounds[1], rest_us)
        self.array.setup = replace(self.array.setup, servos=(
            ServoSetup(self.servo.servo_id, self.servo.pin, rest_us, low, high),))

    def start(self) -> PwmJogReading:
        """Check the board answers, then pulses of the pin's rest width on its channel alone."""
        self.array.check_servos()
        self.array.hold()
        self.goal_us, self.started = self.servo.rest_steps, True
        return self._reading()

    def move_by(self, width_us: int) -> PwmJogReading:
        """Move the width by ``width_us`` (negative: narrower)."""
        assert self.started, "start() first"
        return self.move_to(self.goal_us + width_us)

    def move_to(self, goal_us: int) -> PwmJogReading:
        """Ramp the channel's width to ``goal_us``, one board period at a time."""
        assert self.started, "start() first"
        low, high = self.bounds
        if not low <= goal_us <= high:
            raise GoalOutOfRange(
                f"{self.name}: a {goal_us} us pulse is outside the jog's range {low}..{high} "
                "us (hobby servos' usual 500..2500, widened to the pin's calibrated limits)")
        board = self.array
        if board.asleep():  # it lost power: its reset state, no pulses; start it again
            board.hold()
            self.goal_us = self.servo.rest_steps
        period = period_ns(board.setup.osc_hz, board.prescale)
        per_period = max(1, int(JOG_SPEED_US_PER_S * period / NS_PER_S))
        channel, width = self.servo.servo_id, self.goal_us
        while width != goal_us:
            width += max(-per_period, min(per_period, goal_us - width))
            board.send_goals(board.goal_packet({channel: width}), {channel: width})
            self.goal_us = width
            self.clock.sleep_until_ns(self.clock.now_ns() + ceil(period))
        return self._reading()

    def read(self) -> PwmJogReading:
        """What the board holds for the pin, without moving it."""
        assert self.started, "start() first"
        return self._reading()

    def _reading(self) -> PwmJogReading:
        return PwmJogReading(self.goal_us, self.array.holds({self.servo.servo_id: self.goal_us}))

    def release(self, rest_us: int) -> SafeStopReport:
        """The pin to ``rest_us``, held for its travel, then every channel full off; never
        raises (see `Pca9685Array.rest_and_release`)."""
        self._only(rest_us)
        return self.array.rest_and_release()
