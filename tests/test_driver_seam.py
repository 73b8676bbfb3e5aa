"""A second kind of servo plugs in at the array-driver seam: the player needs nothing else.

`Pulses` below stands for a family that is not Feetech (say, hobby servos on a PWM board):
its frames are its own bytes, it confirms a change by its own means, and it stops its own
way. The player plays it to the same absolute deadlines, keeps the same delivery record and
makes it safe on the same ways out.
"""

from dataclasses import dataclass, field

import numpy as np
import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import BusError
from pinarray.hardware.driver import BusStats, SafeStopReport, ServoSetup
from pinarray.hardware.frames import goal_frames
from pinarray.player.playback import PlaybackAborted, play_trial

from .hardware.lab import pulse_train

REST = 2048


@dataclass(frozen=True)
class Setup:
    servos: tuple[ServoSetup, ...]

    @property
    def servo_ids(self):
        return tuple(s.servo_id for s in self.servos)

    position_unit = "steps"


class EchoVerifier:
    """This family hears its goals back at once, except those its channel drops."""

    def __init__(self, driver, ledger, trial):
        self.driver, self.ledger, self.trial = driver, ledger, trial
        self.pending = {}

    def sent(self, frame, sent_ns):
        for offset, (servo_id, _goal) in enumerate(frame.goals):
            self.pending[servo_id] = frame.first_change + offset

    def work_until(self, limit_ns):
        for servo_id, index in list(self.pending.items()):
            if servo_id in self.driver.dropped:
                continue  # never confirmed: the ledger says so at the end
            self.ledger.confirm(index, 0, healed=False)
            del self.pending[servo_id]

    def sample_until(self, limit_ns):
        pass  # this family cannot say where its pins are

    def trace(self):
        return ()


@dataclass
class Pulses:
    """An array driver of another family, in memory."""

    clock: VirtualClock
    dropped: frozenset = frozenset()
    fail_at_frame: int | None = None
    setup: Setup = field(default_factory=lambda: Setup(tuple(
        ServoSetup(i, i, REST, 1900, 2300) for i in range(1, 17))))
    frames: list = field(default_factory=list)
    stops: int = 0
    begun: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    port_name: str = "pwm-board"
    descriptor: None = None
    latency_timer_ms: None = None

    def goal_packet(self, goals_steps):
        return b"".join(bytes([i]) + g.to_bytes(2, "little") for i, g in goals_steps.items())

    def prepare(self, targets, pulses):
        return goal_frames(self, targets)

    def begin(self, trial, onset_ns):
        self.begun.append(onset_ns)

    def send_goals(self, packet, goals_steps):
        if self.fail_at_frame == len(self.frames):
            raise BusError("pwm-board: channel write not acknowledged")
        self.frames.append((self.clock.now_ns(), packet))

    def verifier(self, clock, trial, onset_ns, ledger):
        return EchoVerifier(self, ledger, trial)

    def heal_time_ns(self, changes_per_frame):
        return 0

    def move_to_rest(self, timeout_ns=0):
        return self.setup.servo_ids

    def read_telemetry(self, servo_ids):
        return ()  # this family reports nothing back

    def rest_and_release(self):
        self.stops += 1
        ids = self.setup.servo_ids
        return SafeStopReport(ids, ids, ())

    def stats(self):
        return BusStats(0, 0, len(self.frames), 0, 0)


def test_another_family_is_played_on_the_schedules_absolute_deadlines():
    clock = VirtualClock()
    driver = Pulses(clock)
    train = pulse_train([1, 6, 11, 16], 10, 3)
    report = play_trial(driver, train, clock)
    np.testing.assert_array_equal(report.sent_ns, report.scheduled_ns)
    onset_ns = report.onset_ns
    assert [t - onset_ns for t, _ in driver.frames] == list(report.scheduled_ns)
    assert report.delivery.delivered and report.delivery.confirmed == report.delivery.scheduled
    assert driver.stops == 1  # the normal end made it safe, its own way
    assert driver.begun == [onset_ns]  # readied once, before its onset, its own way


def test_a_change_another_family_cannot_confirm_is_reported_not_delivered():
    clock = VirtualClock()
    driver = Pulses(clock, dropped=frozenset({6}))
    report = play_trial(driver, pulse_train([1, 6], 10, 3), clock)
    assert not report.delivery.delivered
    assert report.delivery.missing > 0


def test_another_family_failing_mid_trial_is_made_safe_and_says_where():
    clock = VirtualClock()
    driver = Pulses(clock, fail_at_frame=3)
    with pytest.raises(PlaybackAborted, match="at frame 4 of .*channel write not acknowledged"):
        play_trial(driver, pulse_train([1, 6], 10, 3), clock)
    assert driver.stops == 1
