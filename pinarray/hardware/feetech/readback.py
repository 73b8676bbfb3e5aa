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
return delay (500 us from the factory, 100 us after `pinarray servos return-delay`; the
answers to a SYNC READ come one after another, so every moving servo adds its own) and the
USB adapter's latency (1 ms with its latency timer at 1 ms; 16 ms at the FTDI default). So
about 1.5 kHz for one moving servo on a tuned adapter at 1 Mbit/s, about 60 Hz at the FTDI
default, of which at most `SAMPLE_PERIOD_NS` is used (and fewer while every moving pin holds
its goal: `pinarray.hardware.sampling`); 16 moving servos take about 10.5 ms an exchange on
the factory return delay (4.1 ms at 100 us).

Around each frame the trace has a gap: the last sample before it, the guard, the frame on
the wire, the read-back after it, the next sample. Where that gap would leave a moving pin's
cycle without a sample for longer than the cycle rule allows (`pinarray.hardware.motion`: an
eighth of the cycle), the read-back reads goal and position together, one SYNC READ of the
16 bytes from Goal Position to Present Position, and the last sample before a frame is taken
as late as fits; a sample a servo did not answer is asked for again at once. Where even that
leaves no room (16 pins at 10 Hz on the factory return delay, 6 pins at 10 Hz at 115 200
baud), those cycles go unmeasured and the trial says so.
"""

from __future__ import annotations

from array import array
from collections.abc import Mapping

from pinarray.clock import Clock
from pinarray.errors import BusError
from pinarray.hardware.delivery import DeliveryLedger, PreparedFrame, PreparedTrial
from pinarray.hardware.feetech.base import GoalReading, ReadBackBus
from pinarray.hardware.feetech.packets import READ_REQUEST_BYTES
from pinarray.hardware.feetech.registers import StatusError
from pinarray.hardware.motion import PinSamples, Samples
from pinarray.hardware.sampling import Holds

# The moving pins' positions are sampled at most this often (250 Hz per moving servo): a horn
# turning back (at the simulated STS3215's 150 000 steps/s^2, or less) is within 0.3 step of
# its peak for 2 ms either side, and the lag from a goal change to arrival is known to 4 ms.
# Faster would only cost the host's processor: on a simulated bus every sample is a whole
# exchange simulated byte by byte (2 ms made a 24-trial batch 7 times slower).
SAMPLE_PERIOD_NS = 4_000_000
# A sample moved as late as fits before a frame is aimed this much earlier: woken a little
# late on a busy host, it must still end before the frame.
WAKE_SLACK_NS = 500_000
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
        self._answered = True  # every servo answered the last sample
        self._frames_sent = 0  # the next frame to be written is trial.frames[_frames_sent]
        # Whether the trial's motion is sampled: the player asks for samples (`sample_until`)
        # before the first frame, so the read-backs after every frame know it.
        self._sampling = False

    def sent(self, frame: PreparedFrame, sent_ns: int) -> None:
        """A frame's write returned ``sent_ns`` after onset: its changes await confirmation."""
        # Frames written back to back queue behind each other on the wire.
        arrival_ns = max(sent_ns, self.wire_free_ns) + self.bus.wire_ns(len(frame.packet))
        self.wire_free_ns = arrival_ns
        self._frames_sent += 1
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
        then writes again, acknowledged, each goal its servo does not hold. Where that
        read-back and a sample after it would leave a moving pin's cycle unsampled for longer
        than its rule allows, and one exchange of both would not, the round reads every moving
        servo's goal and position together (`FeetechBus.read_goals_and_positions`).
        """
        bus, clock = self.bus, self.clock
        while self.pending:
            ids = tuple(self.pending)
            if self._read_back_samples(ids, limit_ns):
                start_ns = clock.now_ns()
                both = bus.read_goals_and_positions(self.moving, limit_ns)
                self._record_sample(self.moving, {i: steps for i, (_, steps) in both.items()},
                                    start_ns, *self._sample_costs(self.moving))
                if not self._confirm(ids, {i: goal for i, (goal, _) in both.items()}, limit_ns):
                    return
                continue
            count = len(ids)
            while count and clock.now_ns() + bus.read_goals_time_ns(ids[:count]) > limit_ns:
                count -= 1
            if not count:
                return
            asked = ids[:count]
            if not self._confirm(asked, bus.read_goals(asked, limit_ns), limit_ns):
                return

    def sample_until(self, limit_ns: int) -> None:
        """Sample the moving pins' positions while an exchange still fits before ``limit_ns``,
        once every change is confirmed (never at a read-back's expense) and from onset on.

        Samples follow `SAMPLE_PERIOD_NS` (or `pinarray.hardware.sampling`'s thinner rule while
        every pin holds); where the last one before ``limit_ns`` would leave the gap to the
        first after the next frame longer than a cycle's rule allows, it is taken as late as
        fits instead (or one more is, where the usual ones have all been taken).
        """
        self._sampling = True
        bus, clock, ids = self.bus, self.clock, self.moving
        if not ids:
            return
        cost_ns, request_ns, after_change_ns, thinning = self._sample_costs(ids)
        # `_next_start_ns`'s first test, done here (its usual answer, every sample): a sample
        # planned with another one and itself still fitting before ``limit_ns`` goes as planned.
        room_ns = max(SAMPLE_PERIOD_NS, cost_ns) + cost_ns
        onset_ns = self.onset_ns
        while not self.pending:
            now_ns = clock.now_ns()
            if now_ns < onset_ns or now_ns + cost_ns > limit_ns:
                return
            planned_ns = self._next_sample_ns
            if planned_ns < now_ns:
                planned_ns = now_ns
            if planned_ns + room_ns <= limit_ns:
                start_ns = planned_ns
            else:
                chosen_ns = self._next_start_ns(now_ns, cost_ns, request_ns, limit_ns)
                if chosen_ns is None:
                    return
                start_ns = chosen_ns
            if now_ns < start_ns:  # at most one sample a SAMPLE_PERIOD_NS
                self._next_sample_ns = start_ns
                clock.doze_until_ns(start_ns)
                now_ns = clock.now_ns()
                if now_ns != start_ns:
                    continue  # woken late: planned again from now
                # Woken on time, nothing else changed: planning again from now would give
                # now (the sample planned fits, as it did), so it is taken at once.
            positions = bus.read_positions(ids, limit_ns)
            self._record_sample(ids, positions, now_ns, cost_ns, request_ns, after_change_ns,
                                thinning)
            if len(ids) > 1:
                # Where SYNC READs gave way to READs (one servo each), the next one is the
                # next servo.
                ids = ids[1:] + ids[:1]
                cost_ns, request_ns, after_change_ns, thinning = self._sample_costs(ids)
                room_ns = max(SAMPLE_PERIOD_NS, cost_ns) + cost_ns

    def _next_start_ns(self, now_ns: int, cost_ns: int, request_ns: int,
                       limit_ns: int) -> int | None:
        """When the next sample's request goes out (clock ns), or None: none before
        ``limit_ns``. As planned, unless it is the last before the next frame and one later
        (as late as fits, and as the gap from the last sample allows) keeps a cycle's rule
        across the frame that it would not."""
        planned_ns = max(now_ns, self._next_sample_ns)
        fits = planned_ns + cost_ns <= limit_ns
        if fits and planned_ns + max(SAMPLE_PERIOD_NS, cost_ns) + cost_ns <= limit_ns:
            return planned_ns  # not the last before the frame
        onset_ns = self.onset_ns
        last_at_ns = self._last_sampled_ns()
        later_ns = min(limit_ns - cost_ns - WAKE_SLACK_NS,
                       onset_ns + self._holds.reach_ns(last_at_ns) - request_ns)
        instead_at_ns = planned_ns - onset_ns + request_ns if fits else last_at_ns
        soonest_ns = self._first_after_next_frame_ns()
        holds = self._holds
        if (later_ns >= now_ns and (not fits or later_ns > planned_ns)
                and not holds.gap_fits(instead_at_ns, soonest_ns)
                and holds.gap_fits(later_ns - onset_ns + request_ns, soonest_ns)):
            return later_ns
        return planned_ns if fits else None

    def _sample_costs(self, ids: tuple[int, ...]) -> tuple[int, int, int, bool]:
        """A sample of ``ids`` on this bus: what it takes, its request on the wire, from a goal
        change to the first sample after it, and whether one request reads them all."""
        bus = self.bus
        cost_ns = bus.read_positions_time_ns(ids)
        request_ns = bus.wire_ns(bus.read_request_bytes(ids))
        # From a goal change to the first sample after it: the frame on the wire, the
        # read-back of every moving servo's goal, then a sample (each as this bus usually takes).
        after_change_ns = (bus.wire_ns(self.frame_bytes) + bus.read_goals_time_ns(self.moving)
                           + cost_ns)
        return cost_ns, request_ns, after_change_ns, self._one_request(ids)

    def _one_request(self, ids: tuple[int, ...]) -> bool:
        """Whether one request reads all of ``ids`` (a bus that reads one servo a time, where
        SYNC READs go unanswered, samples each less often)."""
        return len(ids) == 1 or self.bus.read_request_bytes(ids) != READ_REQUEST_BYTES

    def _record_sample(self, ids: tuple[int, ...], positions: Mapping[int, int], start_ns: int,
                       cost_ns: int, request_ns: int, after_change_ns: int,
                       thinning: bool) -> None:
        """A sample of ``ids`` whose request started at ``start_ns`` (clock ns): kept, and the
        next one planned. Each servo samples its encoder as the request's last byte reaches it
        (behind a frame still on the wire, if any).
        """
        at_ns = max(start_ns - self.onset_ns, self.wire_free_ns) + request_ns
        holds = self._holds
        answered = True
        for servo_id in ids:
            steps = positions.get(servo_id)
            if steps is None:
                holds.moved(servo_id)  # no answer: not known to hold, sampled every period
                answered = False
                continue
            self._sampled_ns[servo_id].append(at_ns)
            self._sampled_steps[servo_id].append(steps)
            holds.sampled(servo_id, at_ns, steps)
        self._last_sample_ns = start_ns
        if not answered and self._answered:
            # A reply lost on the wire is asked for again at once (once: a servo that stays
            # silent is asked every period), so that one loss leaves no gap a cycle's rule
            # refuses.
            self._answered = False
            self._next_sample_ns = start_ns
            return
        self._answered = answered
        # Samples held back while the pins hold (`pinarray.hardware.sampling`) only where one
        # request reads them all: a bus that reads one servo a time samples each less often.
        self._next_sample_ns = start_ns + (
            holds.next_sample_ns(at_ns, cost_ns, after_change_ns) - at_ns if thinning
            else SAMPLE_PERIOD_NS)

    def _last_sampled_ns(self) -> int:
        """The moving pins' oldest last sample, ns after onset (onset where one has none)."""
        oldest_ns = None
        for servo_id in self.moving:  # a loop, not min() over a generator: once per frame
            sampled = self._sampled_ns[servo_id]
            last_ns = sampled[-1] if sampled else 0
            if oldest_ns is None or last_ns < oldest_ns:
                oldest_ns = last_ns
        return oldest_ns or 0

    def _first_after_next_frame_ns(self) -> int:
        """When, ns after onset, the first sample after the next frame reads the horns at the
        soonest: a read-back that samples too, where one request reads every moving servo (else
        the read-back of the frame's goals, then a sample); after the last frame, the trial's
        end, where its last cycle ends."""
        frames = self.trial.frames
        if self._frames_sent >= len(frames):
            return self.trial.end_ns
        bus, ids = self.bus, self.moving
        frame = frames[self._frames_sent]
        written_ns = frame.time_ns + bus.wire_ns(len(frame.packet))
        request_ns = bus.wire_ns(bus.read_request_bytes(ids))
        if self._one_request(ids):
            return written_ns + request_ns
        changed = tuple(servo_id for servo_id, _ in frame.goals)
        return written_ns + bus.read_goals_time_ns(changed) + request_ns

    def _read_back_samples(self, pending_ids: tuple[int, ...], limit_ns: int) -> bool:
        """Whether the next read-back should sample every moving pin too: the trial is sampled,
        one request reads them all, it fits before ``limit_ns``, and the usual read-back of
        ``pending_ids`` then a sample would leave a gap a cycle's rule refuses where it would not
        (nor the gap after it, to the next sample)."""
        bus, ids = self.bus, self.moving
        if not self._sampling or not self._one_request(ids):
            return False
        now_ns = self.clock.now_ns()
        cost_ns = bus.read_goals_and_positions_time_ns(ids)
        if now_ns < self.onset_ns or now_ns + cost_ns > limit_ns:
            return False
        request_ns = bus.wire_ns(bus.read_request_bytes(ids))
        at_ns = max(now_ns - self.onset_ns, self.wire_free_ns) + request_ns
        usual_ns = at_ns + bus.read_goals_time_ns(pending_ids)
        last_ns = self._last_sampled_ns()
        holds = self._holds
        return (not holds.gap_fits(last_ns, usual_ns) and holds.gap_fits(last_ns, at_ns)
                and holds.gap_fits(at_ns, at_ns + cost_ns))

    def _confirm(self, asked: tuple[int, ...], readings: Mapping[int, GoalReading],
                 limit_ns: int) -> bool:
        """Confirm each of ``asked`` whose servo holds its pending goal; write again those that
        do not. False when a write again had no time before ``limit_ns``."""
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
        return all(self._write_again(servo_id, limit_ns) for servo_id in lost)

    def trace(self) -> tuple[Samples, ...]:
        """The moving pins' samples so far (copies; no numpy: the player process has none)."""
        pins = self.trial.pin_of_servo
        return tuple(
            PinSamples(pins.get(servo_id, servo_id), servo_id, self._sampled_ns[servo_id][:],
                       self._sampled_steps[servo_id][:])
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


