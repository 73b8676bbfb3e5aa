"""Read-backs in the slack between frames: is each changed goal on its servo? If not, heal it.

A sync write gets no reply. After each frame the `Verifier` reads the changed goals back (as
many as fit before the next frame, oldest first, in one SYNC READ), confirms those the servos
hold and writes again, acknowledged, those they do not; it records each change's fate in the
trial's `DeliveryLedger`. It never starts an exchange that would not end before the next
frame's deadline.

With every change confirmed and time left before that deadline, `Verifier.sample_until`
samples where the moving pins are (Present Position, register 56) for the trial's measured
motion (`pinarray.hardware.motion`); servos the trial does not move are never asked.

The rate this gives is bounded by one exchange per sample (all moving servos answer one
SYNC READ, each sampling its encoder as the request reaches it): the request and the replies
on the wire (8 + 8 bytes for one servo: 160 us at 1 Mbit/s, 1.4 ms at 115200), each servo's
return delay (500 us from the factory, 100 us after `pinarray servos return-delay`) and the
USB adapter's latency (1 ms with its latency timer at 1 ms; 16 ms at the FTDI default). So
about 1.5 kHz per moving servo on a tuned adapter at 1 Mbit/s, about 60 Hz at the FTDI
default, of which at most `SAMPLE_PERIOD_NS` is used (and fewer while every moving pin holds
its goal: `pinarray.hardware.sampling`); the time around each frame's write and read-back (the
guard and the read-back itself) leaves gaps of a millisecond or two in the trace.
"""

from __future__ import annotations

from array import array

import numpy as np

from pinarray.clock import Clock
from pinarray.errors import BusError
from pinarray.hardware.delivery import DeliveryLedger, PreparedFrame, PreparedTrial
from pinarray.hardware.feetech.base import ReadBackBus
from pinarray.hardware.feetech.packets import READ_REQUEST_BYTES
from pinarray.hardware.feetech.registers import StatusError
from pinarray.hardware.motion import PinTrace
from pinarray.hardware.sampling import Holds

# The moving pins' positions are sampled at most this often (250 Hz per moving servo): a horn
# turning back (at the simulated STS3215's 150 000 steps/s^2, or less) is within 0.3 step of
# its peak for 2 ms either side, and the lag from a goal change to arrival is known to 4 ms.
# Faster would only cost the host's processor: on a simulated bus every sample is a whole
# exchange simulated byte by byte (2 ms made a 24-trial batch 7 times slower).
SAMPLE_PERIOD_NS = 4_000_000
# A WRITE of a 2-byte goal, in bytes.
REWRITE_REQUEST_BYTES = 9


class Verifier:
    """Reads changed goals back in the slack between frames and re-writes the lost ones."""

    def __init__(self, bus: ReadBackBus, clock: Clock, trial: PreparedTrial, onset_ns: int,
                 ledger: DeliveryLedger):
        self.bus, self.clock, self.trial, self.onset_ns = bus, clock, trial, onset_ns
        self.ledger = ledger
        self.pending: dict[int, int] = {}  # servo id -> index of its unconfirmed change
        self.sent_lateness_ns = [0] * len(trial.changes)
        self.rewritten_at_ns: dict[int, int] = {}  # change index -> ns from onset
        self.wire_free_ns = 0  # when the last frame written will have left, ns from onset
        # The servos the trial moves, and each one's samples: (ns after onset, steps).
        self.moving = tuple(dict.fromkeys(change.servo_id for change in trial.changes))
        self._sampled_ns = {servo_id: array("q") for servo_id in self.moving}
        self._sampled_steps = {servo_id: array("i") for servo_id in self.moving}
        self._next_sample_ns = 0  # clock ns: the earliest the next sample is taken
        self._last_sample_ns = 0  # clock ns: when the last one was
        self._holds = Holds(trial.changes, self.moving, trial.end_ns, SAMPLE_PERIOD_NS)
        self.frame_bytes = max((len(frame.packet) for frame in trial.frames), default=0)

    def sent(self, frame: PreparedFrame, sent_ns: int) -> None:
        """A frame's write returned ``sent_ns`` after onset: its changes await confirmation."""
        # Frames written back to back queue behind each other on the wire.
        arrival_ns = max(sent_ns, self.wire_free_ns) + self.bus.wire_ns(len(frame.packet))
        self.wire_free_ns = arrival_ns
        for offset, (servo_id, _goal) in enumerate(frame.goals):
            index = frame.first_change + offset
            previous = self.pending.pop(servo_id, None)
            if previous is not None:
                self.ledger.lose(previous, "the servo's next change came before a read-back "
                                           "could confirm it")
            self.pending[servo_id] = index
            self.sent_lateness_ns[index] = arrival_ns - frame.time_ns
            self._holds.moved(servo_id)
        # Sampling goes back to every period from the change on (if it was holding back).
        self._next_sample_ns = min(self._next_sample_ns, self._last_sample_ns + SAMPLE_PERIOD_NS)

    def work_until(self, limit_ns: int) -> None:
        """Confirm or heal pending changes while an exchange still fits before ``limit_ns``.

        Each round reads back as many pending goals as fit (oldest first, one SYNC READ),
        then writes again, acknowledged, each goal its servo does not hold.
        """
        bus, clock = self.bus, self.clock
        while self.pending:
            ids = tuple(self.pending)
            count = len(ids)
            while count and clock.now_ns() + bus.read_goals_time_ns(ids[:count]) > limit_ns:
                count -= 1
            if not count:
                return
            asked = ids[:count]
            readings = bus.read_goals(asked, limit_ns)
            lost: list[int] = []
            for servo_id in asked:
                reading = readings.get(servo_id)
                if reading is None:
                    self._later(servo_id)  # no reply: the others first, this one again later
                    continue
                self._check(servo_id, reading.errors)
                index = self.pending[servo_id]
                change = self.trial.changes[index]
                if reading.goal_steps != change.goal_steps:
                    lost.append(servo_id)
                    continue
                del self.pending[servo_id]
                rewritten_ns = self.rewritten_at_ns.get(index)
                if rewritten_ns is None:
                    self.ledger.confirm(index, self.sent_lateness_ns[index], healed=False)
                else:
                    self.ledger.confirm(index, rewritten_ns - change.time_ns, healed=True)
            for servo_id in lost:
                if not self._write_again(servo_id, limit_ns):
                    return

    def sample_until(self, limit_ns: int) -> None:
        """Sample the moving pins' positions while an exchange still fits before ``limit_ns``,
        once every change is confirmed (never at a read-back's expense) and from onset on."""
        bus, clock, ids = self.bus, self.clock, self.moving
        if not ids:
            return
        cost_ns = bus.read_positions_time_ns(ids)
        request_ns = bus.wire_ns(bus.read_request_bytes(ids))
        sampled_ns, sampled_steps, holds = self._sampled_ns, self._sampled_steps, self._holds
        # Samples held back while the pins hold (`pinarray.hardware.sampling`) only where one
        # request reads them all: a bus that reads one servo a time samples each less often.
        thinning = len(ids) == 1 or bus.read_request_bytes(ids) != READ_REQUEST_BYTES
        # From a goal change to the first sample after it: the frame on the wire, the
        # read-back of every moving servo's goal, then a sample (each as this bus usually takes).
        after_change_ns = (bus.wire_ns(self.frame_bytes) + bus.read_goals_time_ns(self.moving)
                           + cost_ns)
        while not self.pending:
            now_ns = clock.now_ns()
            if now_ns < self.onset_ns or now_ns + cost_ns > limit_ns:
                return
            if now_ns < self._next_sample_ns:  # at most one sample a SAMPLE_PERIOD_NS
                if self._next_sample_ns + cost_ns > limit_ns:
                    return
                clock.doze_until_ns(self._next_sample_ns)
                continue
            # Each servo samples its encoder as the request's last byte reaches it.
            at_ns = now_ns - self.onset_ns + request_ns
            positions = bus.read_positions(ids, limit_ns)
            for servo_id in ids:
                steps = positions.get(servo_id)
                if steps is None:
                    holds.moved(servo_id)  # no answer: not known to hold, sampled every period
                    continue
                sampled_ns[servo_id].append(at_ns)
                sampled_steps[servo_id].append(steps)
                holds.sampled(servo_id, at_ns, steps)
            self._last_sample_ns = now_ns
            self._next_sample_ns = now_ns + (
                holds.next_sample_ns(at_ns, cost_ns, after_change_ns) - at_ns if thinning
                else SAMPLE_PERIOD_NS)
            if len(ids) > 1:
                # Where SYNC READs gave way to READs (one servo each), the next one is the
                # next servo.
                ids = ids[1:] + ids[:1]
                cost_ns = bus.read_positions_time_ns(ids)
                request_ns = bus.wire_ns(bus.read_request_bytes(ids))

    def trace(self) -> tuple[PinTrace, ...]:
        """The moving pins' samples so far."""
        pins = self.trial.pin_of_servo
        return tuple(
            PinTrace(pins.get(servo_id, servo_id), servo_id,
                     np.frombuffer(self._sampled_ns[servo_id], dtype=np.int64).copy(),
                     np.frombuffer(self._sampled_steps[servo_id], dtype=np.int32).copy())
            for servo_id in self.moving)

    def _write_again(self, servo_id: int, limit_ns: int) -> bool:
        """The servo does not hold its goal (its sync write was lost): say it again.

        False when there was no time for it before ``limit_ns``.
        """
        bus, clock = self.bus, self.clock
        now_ns = clock.now_ns()
        if now_ns + bus.reply_time_ns(servo_id, REWRITE_REQUEST_BYTES, 0) > limit_ns:
            return False
        index = self.pending[servo_id]
        change = self.trial.changes[index]
        self.rewritten_at_ns[index] = now_ns - self.onset_ns + bus.wire_ns(REWRITE_REQUEST_BYTES)
        errors = bus.rewrite_goal(servo_id, change.goal_steps, limit_ns)
        if errors is None:
            self._later(servo_id)  # no acknowledgement: read back again later
            return True
        self._check(servo_id, errors)
        del self.pending[servo_id]
        self.ledger.confirm(index, self.rewritten_at_ns[index] - change.time_ns, healed=True)
        return True

    def _later(self, servo_id: int) -> None:
        self.pending[servo_id] = self.pending.pop(servo_id)  # to the back of the queue

    def _check(self, servo_id: int, errors: StatusError) -> None:
        if errors:
            pin = self.trial.pin_of_servo.get(servo_id)
            raise BusError(f"servo fault: servo {servo_id} (pin {pin}) reports {errors.describe()}")


