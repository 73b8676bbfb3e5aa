"""A simulated hobby servo: it follows the width of the pulses it is sent, and tells nobody.

A hobby servo's position is the pulse width it was last told, in microseconds (1500 us is the
middle, about 1000 us per 90 degrees). It measures each pulse at its falling edge; a width
within the dead band of where it stands stops it there; it moves at most ``speed_us_per_s``
of width per second (an SG90: 0.1 s per 60 degrees, about 6667 us/s); and with no pulse for
longer than ``limp_after_periods`` times the spacing of its last two pulses it goes limp where
it is (no torque, position held by friction) until the next pulse. Positions are exact
fractions of a microsecond, times integer ns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

from pinarray.units import NS_PER_S, NS_PER_US

DEFAULT_PERIOD_NS = 20_000_000  # the classic 50 Hz servo frame, until two pulses show another


@dataclass(frozen=True)
class ServoPoint:
    """The servo at one moment: where it is, where it is going, whether it is limp."""

    t_ns: int
    position_us: Fraction
    target_us: Fraction
    limp: bool


@dataclass(frozen=True)
class HobbyServo:
    """A hobby servo's behaviour.

    Attributes
    ----------
    dead_band_us : float
        Widths this close to the present position are ignored, us.
    speed_us_per_s : float
        The fastest the position moves, us of pulse width per second.
    limp_after_periods : float
        Silence, in pulse spacings, after which the servo goes limp.
    """

    dead_band_us: Fraction = Fraction(8)
    speed_us_per_s: Fraction = Fraction(6667)
    limp_after_periods: Fraction = Fraction(3)

    def follow(self, pulses: Sequence[tuple[int, int]], start_us: Fraction,
               until_ns: int | None = None) -> list[ServoPoint]:
        """Where the servo was at each pulse's falling edge and each time it went limp.

        ``pulses`` are ``(start_ns, width_ns)`` in time order, as
        `SimulatedBoard.pulses` gives them; the servo starts limp at ``start_us``. With
        ``until_ns``, a last point says where it is then.
        """
        position, target = Fraction(start_us), Fraction(start_us)
        limp = True
        now: int | None = None
        spacing = DEFAULT_PERIOD_NS
        last_start: int | None = None
        points: list[ServoPoint] = []

        def move_to(t_ns: int) -> None:
            nonlocal position, now
            if now is not None and not limp:
                reach = self.speed_us_per_s * Fraction(t_ns - now, NS_PER_S)
                step = max(-reach, min(reach, target - position))
                position += step
            now = t_ns

        for start_ns, width_ns in pulses:
            if last_start is not None and not limp:
                silent_until = now if now is not None else start_ns
                limp_at = silent_until + int(self.limp_after_periods * spacing)
                if limp_at < start_ns:
                    move_to(limp_at)
                    limp = True
                    points.append(ServoPoint(limp_at, position, target, True))
            if last_start is not None:
                spacing = start_ns - last_start
            last_start = start_ns
            edge_ns = start_ns + width_ns
            move_to(edge_ns)
            limp = False
            width_us = Fraction(width_ns, NS_PER_US)
            # the motor runs while the error exceeds the dead band, and stops inside it
            target = width_us if abs(width_us - position) > self.dead_band_us else position
            points.append(ServoPoint(edge_ns, position, target, False))
        if until_ns is not None:
            if now is not None and not limp:
                limp_at = now + int(self.limp_after_periods * spacing)
                if limp_at < until_ns:
                    move_to(limp_at)
                    limp = True
                    points.append(ServoPoint(limp_at, position, target, True))
            move_to(until_ns)
            points.append(ServoPoint(until_ns, position, target, limp))
        return points


def swing_us(servo: HobbyServo, pulses: Sequence[tuple[int, int]],
             start_us: Fraction) -> tuple[Fraction, Fraction]:
    """The narrowest and widest position the servo reached following ``pulses`` from
    ``start_us`` (it moves monotonically between the points `HobbyServo.follow` gives, so
    its extremes are among them)."""
    positions = [p.position_us for p in servo.follow(pulses, start_us)] or [Fraction(start_us)]
    return min(positions), max(positions)
