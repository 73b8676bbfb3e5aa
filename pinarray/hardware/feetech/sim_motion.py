"""Closed-form motion of a simulated servo: a trapezoidal speed profile, backlash and load.

A move is planned once, when something that steers the horn changes (goal, speed,
acceleration, torque), as at most four pieces of constant acceleration: brake, speed up (or
down), cruise, brake onto the goal. Where the horn is at any later instant is then a formula
evaluated at that instant; nothing is stepped, so an idle or a moving servo costs the same.

Two positions are tracked, in servo steps:

drive
    The gear train's output tooth: what the motor's trapezoid moves.
horn
    The output shaft and horn, which the encoder reads. With backlash ``b`` the horn sits
    anywhere within ``drive +- b/2`` and moves only when the tooth pushes it (a play
    operator); under a steady external load it rests on the loaded side of the tooth.

The servo closes its position loop on the encoder, so the drive is sent ``b/2`` past the
goal in the direction of approach and the horn stops on the goal itself.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pinarray.units import NS_PER_S


class MotionState(NamedTuple):
    """Drive position (steps), drive speed (steps/s, signed) and horn position (steps)."""

    drive_steps: float
    speed_steps_per_s: float
    horn_steps: float


class Drive(NamedTuple):
    """How the servo may move: limits in steps/s and steps/s^2, backlash and load.

    Attributes
    ----------
    up_speed_steps_per_s, down_speed_steps_per_s : float
        Top speed toward higher and lower step counts (they differ under load), > 0.
    accel_steps_per_s2 : float
        Acceleration and braking limit, > 0.
    lash_steps : float
        Backlash: the horn's free play around the drive, >= 0.
    load_direction : int
        0: no steady load, the lash follows the motion; -1 / +1: a load presses the horn
        toward lower / higher step counts, so it always rests on that side of the tooth.
    """

    up_speed_steps_per_s: float
    down_speed_steps_per_s: float
    accel_steps_per_s2: float
    lash_steps: float = 0.0
    load_direction: int = 0

    def speed(self, direction: int) -> float:
        return self.up_speed_steps_per_s if direction > 0 else self.down_speed_steps_per_s


class Piece(NamedTuple):
    """Constant acceleration from ``start_ns`` on; positions in steps, speeds signed."""

    start_ns: int
    drive_steps: float
    speed_steps_per_s: float
    accel_steps_per_s2: float
    horn_steps: float  # where the horn is at start_ns

    def drive_at(self, time_ns: int) -> tuple[float, float]:
        dt_s = (time_ns - self.start_ns) / NS_PER_S
        speed = self.speed_steps_per_s + self.accel_steps_per_s2 * dt_s
        drive = (
            self.drive_steps
            + self.speed_steps_per_s * dt_s
            + 0.5 * self.accel_steps_per_s2 * dt_s * dt_s
        )
        return drive, speed

    @property
    def direction(self) -> int:
        """Sign of the drive's motion during the piece (pieces never reverse inside)."""
        v, a = self.speed_steps_per_s, self.accel_steps_per_s2
        return int(math.copysign(1, v)) if v else (int(math.copysign(1, a)) if a else 0)


def horn_for(drive_steps: float, horn_before: float, direction: int, lash: Drive) -> float:
    """Horn position once the drive has moved monotonically (in ``direction``) to ``drive_steps``."""
    half = lash.lash_steps / 2.0
    if lash.load_direction:
        return drive_steps + lash.load_direction * half
    if direction > 0:
        return max(horn_before, drive_steps - half)
    if direction < 0:
        return min(horn_before, drive_steps + half)
    return horn_before


class Move(NamedTuple):
    """A planned motion: pieces in time order, the last one at rest and open-ended."""

    pieces: tuple[Piece, ...]
    drive: Drive

    @property
    def start_ns(self) -> int:
        return self.pieces[0].start_ns

    @property
    def end_ns(self) -> int:
        """When the drive comes to rest (the start of the last piece)."""
        return self.pieces[-1].start_ns

    @property
    def final(self) -> Piece:
        return self.pieces[-1]

    def _piece_at(self, time_ns: int) -> Piece:
        for piece in reversed(self.pieces):
            if piece.start_ns <= time_ns:
                return piece
        return self.pieces[0]

    def state_at(self, time_ns: int) -> MotionState:
        """Drive, drive speed and horn at ``time_ns``."""
        final = self.pieces[-1]
        piece = final if final.start_ns <= time_ns else self._piece_at(time_ns)
        if piece is final:  # at rest (the usual case: a servo holding its goal)
            return MotionState(final.drive_steps, 0.0, final.horn_steps)
        drive, speed = piece.drive_at(time_ns)
        horn = horn_for(drive, piece.horn_steps, piece.direction, self.drive)
        return MotionState(drive, speed, horn)

    def horn_at(self, time_ns: int) -> float:
        """`state_at`'s horn alone (what the encoder reads: every motion sample asks).

        `Piece.drive_at`'s drive, `Piece.direction` and `horn_for` written out here, the same
        operations in the same order (so the same floats): a sample of a moving pin is the
        simulator's most frequent question.
        """
        final = self.pieces[-1]
        if final.start_ns <= time_ns:
            return final.horn_steps
        piece = self._piece_at(time_ns)
        if piece is final:
            return final.horn_steps
        start_ns, drive_steps, speed, accel, horn_before = piece
        dt_s = (time_ns - start_ns) / NS_PER_S
        drive = drive_steps + speed * dt_s + 0.5 * accel * dt_s * dt_s
        lash = self.drive
        half = lash.lash_steps / 2.0
        if lash.load_direction:
            return drive + lash.load_direction * half
        if speed > 0 or (not speed and accel > 0):  # `Piece.direction` > 0
            return max(horn_before, drive - half)
        if speed < 0 or (not speed and accel < 0):
            return min(horn_before, drive + half)
        return horn_before

    def horn_speed_at(self, time_ns: int) -> float:
        """The horn's speed (steps/s): the drive's while it pushes the horn, else 0."""
        piece = self._piece_at(time_ns)
        if piece is self.pieces[-1]:
            return 0.0
        drive, speed = piece.drive_at(time_ns)
        half = self.drive.lash_steps / 2.0
        if self.drive.load_direction or half == 0.0:
            return speed
        horn = horn_for(drive, piece.horn_steps, piece.direction, self.drive)
        in_contact = abs(abs(drive - horn) - half) < 1e-9
        return speed if in_contact else 0.0


def at_rest(time_ns: int, state: MotionState, drive: Drive) -> Move:
    """A servo that stays where it is (torque off, or nothing to do)."""
    return Move((Piece(time_ns, state.drive_steps, 0.0, 0.0, state.horn_steps),), drive)


def plan_move(time_ns: int, state: MotionState, goal_steps: float, drive: Drive) -> Move:
    """The fastest move from ``state`` at ``time_ns`` that leaves the horn on ``goal_steps``.

    The drive first brakes if it cannot stop in time while going its current way (or is going
    the wrong way), then runs a trapezoid (or triangle) to the goal plus half the lash.
    """
    q0, v0, h0 = state
    a = drive.accel_steps_per_s2
    pieces: list[Piece] = []
    if v0:
        way = 1 if v0 > 0 else -1
        stopping = v0 * v0 / (2.0 * a)
        target = _drive_target(goal_steps, way, drive)
        ahead = (target - q0) * way
        horn_ahead = bool(drive.load_direction) or (goal_steps - h0) * way >= 0
        if ahead >= stopping and horn_ahead and drive.speed(way) > 0:
            pieces = _run(time_ns, q0, abs(v0), h0, way, ahead, drive)
            return _landed(pieces, goal_steps, drive)
        # Brake to a stop first, then come back (or go on) from rest.
        brake_s = abs(v0) / a
        q1 = q0 + way * stopping
        h1 = horn_for(q1, h0, way, drive)
        pieces.append(Piece(time_ns, q0, v0, -way * a, h0))
        time_ns += round(brake_s * NS_PER_S)
        q0, v0, h0 = q1, 0.0, h1
    direction = _sign(goal_steps - h0)
    if drive.load_direction:
        target = _drive_target(goal_steps, direction, drive)
        direction = _sign(target - q0)
    else:
        target = _drive_target(goal_steps, direction, drive) if direction else q0
    distance = abs(target - q0)
    if distance == 0.0 or drive.speed(_sign(target - q0)) <= 0:  # arrived, or stalled
        pieces.append(Piece(time_ns, q0, 0.0, 0.0, h0))
        return Move(tuple(pieces), drive)
    pieces.extend(_run(time_ns, q0, 0.0, h0, _sign(target - q0), distance, drive))
    return _landed(pieces, goal_steps, drive)


def _landed(pieces: list[Piece], goal_steps: float, drive: Drive) -> Move:
    """The move, with the last rounding error taken off the horn's final position."""
    final = pieces[-1]
    if abs(final.horn_steps - goal_steps) < 1e-6:
        pieces[-1] = final._replace(horn_steps=goal_steps)
    return Move(tuple(pieces), drive)


def _sign(x: float) -> int:
    return (x > 0) - (x < 0)


def _drive_target(goal_steps: float, way: int, drive: Drive) -> float:
    """Where the drive must stop for the horn to rest on the goal, approaching ``way``."""
    half = drive.lash_steps / 2.0
    if drive.load_direction:
        return goal_steps - drive.load_direction * half
    return goal_steps + way * half


def _run(
    start_ns: int, q0: float, v0: float, h0: float, way: int, distance: float, drive: Drive
) -> list[Piece]:
    """Pieces from speed ``v0 >= 0`` (along ``way``) to rest ``distance`` steps further on.

    ``distance`` must be at least the stopping distance ``v0^2 / 2a``.
    """
    a = drive.accel_steps_per_s2
    top = drive.speed(way)
    if v0 > top:
        peak = top
    else:
        peak = min(top, math.sqrt(a * distance + v0 * v0 / 2.0))
    change_s = abs(peak - v0) / a
    change_steps = abs(peak * peak - v0 * v0) / (2.0 * a)
    brake_s = peak / a
    brake_steps = peak * peak / (2.0 * a)
    cruise_steps = max(0.0, distance - change_steps - brake_steps)
    cruise_s = cruise_steps / peak if peak > 0 else 0.0
    phases = (
        (change_s, v0, a if peak >= v0 else -a),
        (cruise_s, peak, 0.0),
        (brake_s, peak, -a),
    )
    pieces: list[Piece] = []
    elapsed_s = 0.0
    travelled = 0.0
    horn = h0
    for duration_s, speed, accel in phases:
        if duration_s <= 0.0:
            continue
        at_ns = start_ns + round(elapsed_s * NS_PER_S)
        piece = Piece(at_ns, q0 + way * travelled, way * speed, way * accel, horn)
        pieces.append(piece)
        step = speed * duration_s + 0.5 * accel * duration_s * duration_s
        travelled = min(distance, travelled + step)
        elapsed_s += duration_s
        horn = horn_for(q0 + way * travelled, horn, way, drive)
    end = q0 + way * distance
    pieces.append(
        Piece(start_ns + round(elapsed_s * NS_PER_S), end, 0.0, 0.0, horn_for(end, horn, way, drive))
    )
    return pieces
