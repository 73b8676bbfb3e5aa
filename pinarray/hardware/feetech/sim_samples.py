"""The motion level: the moving pins' samples computed from the servo model, not read.

On the other levels the player samples where the moving pins are by one exchange per sample
in the slack between frames (`pinarray.hardware.feetech.readback.Verifier.sample_until`):
on a simulated bus that is most of a batch's work. Here the player's read-backs, heals and
everything else go as on the packet level (`pinarray.hardware.feetech.sim_packet`), while
each slack it would sample in is only noted; when the trial's trace is asked for, the samples
are worked out at once: the instants the player samples at when it holds none back (every
`pinarray.hardware.feetech.readback.SAMPLE_PERIOD_NS` from the first sample on, while a
sample still fits before the slack's limit, one exchange apart on a bus too slow for that),
and at each the Present Position each servo would report, from the moves it was given
(`horn_steps_at`, the servo model's own arithmetic over arrays). The positions are the
servos' own; the instants differ from the other levels' only where those held samples back
while every pin held its goal (`pinarray.hardware.sampling`), which shifts the grid after such
a stretch by at most a period. The samples are those of a free wire: on a bus too slow for its
traffic, where the other levels' read-backs and samples time out behind a sync write still on
the wire, theirs come late or not at all, and these do not. Where the bus leaves a moving pin's
cycle too little room around a frame (fast cycles, many pins, a slow bus), the player takes
samples off that grid (late before a frame, or within a read-back); those trials' samples are
read, as on the packet level, and measured alike.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from pinarray.clock import Clock
from pinarray.hardware.delivery import DeliveryLedger, PreparedTrial
from pinarray.hardware.feetech.feetech import FeetechBus
from pinarray.hardware.feetech.packets import status_size
from pinarray.hardware.feetech.readback import SAMPLE_PERIOD_NS, WAKE_SLACK_NS, Verifier
from pinarray.hardware.feetech.registers import Register
from pinarray.hardware.feetech.sim import SimBus
from pinarray.hardware.feetech.sim_motion import Move
from pinarray.hardware.feetech.sim_packet import PacketLink
from pinarray.hardware.feetech.sim_serial import SimSerial
from pinarray.hardware.motion import PinTrace, Samples
from pinarray.units import NS_PER_S

# Present Position's largest magnitude (sign-magnitude, 15 bits).
_LARGEST_POSITION = 32767
# A servo's answer to a sample: a status packet carrying Present Position.
_ANSWER_BYTES = status_size(Register.PRESENT_POSITION.size)


def horn_steps_at(moves: Sequence[Move], times_ns: np.ndarray) -> np.ndarray:
    """Where the horn is at each of ``times_ns`` (rising, not before the first move starts),
    in steps: `Move.state_at` of the move in force, evaluated over arrays the same way.

    ``moves`` are in the order they were planned; each is in force from its start until the
    next one's.
    """
    starts: list[int] = []
    pieces: list[tuple[float, float, float, float, bool, int, float, int]] = []
    for k, move in enumerate(moves):
        until_ns = moves[k + 1].start_ns if k + 1 < len(moves) else None
        final = move.pieces[-1]
        half = move.drive.lash_steps / 2.0
        load = move.drive.load_direction
        for piece in move.pieces:
            if until_ns is not None and piece.start_ns >= until_ns:
                break
            starts.append(piece.start_ns)
            pieces.append((piece.drive_steps, piece.speed_steps_per_s, piece.accel_steps_per_s2,
                           piece.horn_steps, piece is final, piece.direction, half, load))
    table = np.array(pieces, dtype=np.float64).T
    drive0, speed, accel, horn0, final, way, half, load = table
    index = np.maximum(np.searchsorted(np.array(starts, dtype=np.int64), times_ns,
                                       side="right") - 1, 0)
    dt_s = (times_ns - np.array(starts, dtype=np.int64)[index]) / NS_PER_S
    d0, v0, a0, h0 = drive0[index], speed[index], accel[index], horn0[index]
    drive = d0 + v0 * dt_s + 0.5 * a0 * dt_s * dt_s
    half_at, load_at, way_at = half[index], load[index], way[index]
    horn = np.where(way_at > 0, np.maximum(h0, drive - half_at),
                    np.where(way_at < 0, np.minimum(h0, drive + half_at), h0))
    horn = np.where(load_at != 0, drive + load_at * half_at, horn)
    steps: np.ndarray = np.where(final[index] != 0, h0, horn)
    return steps


class ComputedVerifier(Verifier):
    """The motion level's `FrameVerifier`: read-backs and heals as the player's own
    (`pinarray.hardware.feetech.readback.Verifier`), samples computed.

    Parameters
    ----------
    bus : FeetechBus
        The connected bus (on a `PacketLink`), for the read-backs and the exchanges' sizes.
    sim : SimBus
        The simulated servos, whose moves give the samples.
    port : SimSerial
        The simulated port, for its wire time per byte.
    clock, trial, onset_ns, ledger
        As for `pinarray.hardware.feetech.readback.Verifier`.
    """

    def __init__(self, bus: FeetechBus, sim: SimBus, port: SimSerial, clock: Clock,
                 trial: PreparedTrial, onset_ns: int, ledger: DeliveryLedger):
        super().__init__(bus, clock, trial, onset_ns, ledger)
        self.sim, self.port = sim, port
        # Computed only where sampling every period keeps every cycle's rule around every
        # frame with room to spare: the player then takes no sample off that grid (none moved
        # late before a frame, no read-back that samples too: `readback.Verifier`), so the
        # grid worked out here holds every sample it takes. Elsewhere (fast cycles, many
        # pins, a slow bus) the samples are read, as on the packet level.
        self.computed = self._grid_keeps_every_cycle()
        self._moves = {servo_id: sim.servos[servo_id].log_moves()
                       for servo_id in self.moving if self.computed and servo_id in sim.servos}
        # Each slack the player would have sampled in: (clock ns it began, its limit).
        self._slacks: list[tuple[int, int]] = []

    def _grid_keeps_every_cycle(self) -> bool:
        """Whether the longest gap sampling every period can leave around a frame (the grid's
        last sample before it, its guard, the frame on the wire, the read-back after it, the
        next sample), bounded generously, is within what every moving pin's cycles allow, and
        frames come no closer together than that gap (a sample fits between any two)."""
        ids, bus, frames = self.moving, self.bus, self.trial.frames
        tightest_ns = self._holds.tightest_gap_ns()
        if not ids or tightest_ns is None:
            return True
        cost_ns = bus.read_positions_time_ns(ids)
        worst_ns = (2 * max(SAMPLE_PERIOD_NS, cost_ns) + cost_ns + WAKE_SLACK_NS
                    + bus.wire_ns(self.frame_bytes) + bus.read_goals_time_ns(ids))
        spacing_ns = min((b.time_ns - a.time_ns for a, b in itertools.pairwise(frames)),
                         default=worst_ns)
        return worst_ns <= tightest_ns and worst_ns <= spacing_ns

    def sample_until(self, limit_ns: int) -> None:
        """Note the slack: its samples are worked out with the trace (read at once where they
        are not computed)."""
        if not self.computed:
            super().sample_until(limit_ns)
        elif self.moving and not self.pending:
            self._slacks.append((self.clock.now_ns(), limit_ns))

    def sample_starts_ns(self) -> list[int]:
        """When each sample's request would go out (clock ns), as the player sends them
        when it holds none back."""
        ids, bus, period_ns = self.moving, self.bus, SAMPLE_PERIOD_NS
        cost_ns = bus.read_positions_time_ns(ids)
        # One exchange: the request, then each servo's return delay and answer in turn.
        byte_ns = self.port.byte_ns
        took_ns = round(bus.read_request_bytes(ids) * byte_ns) + sum(
            self.sim.servos[i].return_delay_ns + round(_ANSWER_BYTES * byte_ns)
            for i in ids if i in self.sim.servos)
        starts: list[int] = []
        next_ns = 0
        for now_ns, limit_ns in self._slacks:
            if now_ns < self.onset_ns or now_ns + cost_ns > limit_ns:
                continue
            if now_ns < next_ns:
                if next_ns + cost_ns > limit_ns:
                    continue
                now_ns = next_ns
            if took_ns <= period_ns:
                last_ns = now_ns + (limit_ns - cost_ns - now_ns) // period_ns * period_ns
                starts.extend(range(now_ns, last_ns + 1, period_ns))
                next_ns = last_ns + period_ns
                continue
            while now_ns + cost_ns <= limit_ns:  # a bus slower than the period: back to back
                starts.append(now_ns)
                next_ns = now_ns + period_ns
                now_ns += took_ns
        return starts

    def trace(self) -> tuple[Samples, ...]:
        """The moving pins' samples: computed now, for the whole trial (or as read)."""
        if not self.computed:
            return super().trace()
        if not self.moving:
            return ()
        ids, bus = self.moving, self.bus
        request_bytes = bus.read_request_bytes(ids)
        starts = np.array(self.sample_starts_ns(), dtype=np.int64)
        # Each servo samples its encoder as the request's last byte reaches it; the player
        # times the sample by the request's wire time (the same at the round baud rates).
        reach_ns = round(request_bytes * self.port.byte_ns)
        at_ns = starts - self.onset_ns + bus.wire_ns(request_bytes)
        pins = self.trial.pin_of_servo
        traces = []
        for servo_id in ids:
            servo = self.sim.servos.get(servo_id)
            if servo is None:
                continue
            moves = self._moves.pop(servo_id)
            servo.stop_logging_moves()
            steps = np.rint(horn_steps_at(moves, starts + reach_ns)).astype(np.int64)
            steps -= servo.offset_steps
            if servo.folds_position:
                steps %= 4096
            np.clip(steps, -_LARGEST_POSITION, _LARGEST_POSITION, out=steps)
            traces.append(PinTrace(pins.get(servo_id, servo_id), servo_id, at_ns.copy(),
                                   steps.astype(np.int32)))
        return tuple(traces)


class MotionLevelBus(FeetechBus):
    """A simulated bus at the motion level: a `FeetechBus` whose trials' samples are computed
    (`ComputedVerifier`); everything else as on its `PacketLink`.

    Parameters
    ----------
    link : PacketLink
        The packet level's link to the simulated port.
    clock : Clock
        The simulator's clock.
    sim : SimBus
        The simulated servos behind the port.
    retries : int
        As for `FeetechBus`.
    """

    def __init__(self, link: PacketLink, clock: Clock, sim: SimBus, retries: int = 3):
        super().__init__(link, clock, retries)
        self.sim = sim
        self._servos, self._port = sim, link.port

    def verifier(self, clock: Clock, trial: PreparedTrial, onset_ns: int,
                 ledger: DeliveryLedger) -> ComputedVerifier:
        return ComputedVerifier(self, self._servos, self._port, clock, trial, onset_ns, ledger)
