"""The player: absolute deadlines, limit refusal, and a safe stop on every way out."""

import numpy as np
import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.player.playback import pins_made_safe, play_trial
from pinarray.stop import Stopped

from .lab import assert_safe, pulse_train, sim_bus, targets


def test_frames_go_out_exactly_on_their_deadlines_in_virtual_time():
    bus = sim_bus()
    train = pulse_train(range(1, 17), 10, 5)
    report = play_trial(bus, train, bus.clock)
    assert report.frames_sent == 10
    np.testing.assert_array_equal(report.scheduled_ns, np.unique(train.time_ns))
    np.testing.assert_array_equal(report.sent_ns, report.scheduled_ns)
    assert report.deadline_error_ns(100) == 0
    assert report.bytes_written >= 10 * 56


def test_frames_faster_than_the_wire_reach_the_servos_later_and_later_without_drifting():
    # 16 servos every 400 us needs 560 us of wire per frame: each frame arrives later than the
    # last, while the writes themselves stay on the schedule's absolute deadlines.
    bus = sim_bus()
    changes = [(k * 400_000, pin, 2100 if k % 2 == 0 else 2048)
               for k in range(20) for pin in range(1, 17)]
    report = play_trial(bus, targets(changes, 50_000_000), bus.clock)
    np.testing.assert_array_equal(report.scheduled_ns, np.arange(20) * 400_000)
    np.testing.assert_array_equal(report.sent_ns, report.scheduled_ns)
    # The last frame leaves the wire 20 x 560 us after the first began: 3.2 ms behind.
    assert report.delivery.worst_lateness_ns == 20 * 560_000 - 19 * 400_000
    assert report.delivery.missing > 0  # no slack to read back frames 400 us apart
    assert not report.delivery.delivered


def test_a_schedule_outside_calibrated_limits_is_refused_before_anything_is_sent():
    bus = sim_bus()
    before = bus.stats()
    bad = targets([(0, 3, 2100), (500_000_000, 6, 2500)], 1_000_000_000)
    with pytest.raises(PinArrayError) as caught:
        play_trial(bus, bad, bus.clock)
    assert "pin 6 (servo 6) would go to 2500 steps at 0.500 s" in str(caught.value)
    assert "limits 1900..2300" in str(caught.value)
    assert bus.stats() == before


def test_the_bus_itself_refuses_a_goal_outside_the_limits():
    bus = sim_bus()
    with pytest.raises(PinArrayError, match="pin 2 \\(servo 2\\): GOAL_POSITION 1000"):
        bus.write_goals({2: 1000})


def test_a_normal_end_leaves_pins_at_rest_with_torque_off():
    bus = sim_bus()
    report = play_trial(bus, pulse_train([1, 6, 11, 16], 5, 3), bus.clock)
    assert report.safe_stop.complete
    assert_safe(bus)


class StopAt(VirtualClock):
    """Virtual time that raises ``error`` when the player waits for frame ``frame``."""

    def __init__(self, error: BaseException, frame: int):
        super().__init__()
        self.error, self.frame, self.waits = error, frame, 0
        self.armed = False

    def sleep_until_ns(self, deadline_ns: int) -> None:
        if self.armed:
            self.waits += 1
            if self.waits == self.frame:
                self.armed = False
                raise self.error
        super().sleep_until_ns(deadline_ns)


@pytest.mark.parametrize("error, expected", [
    (KeyboardInterrupt(), KeyboardInterrupt),
    (Stopped("stopped by SIGTERM", 15), Stopped),  # a stop request, not a playback fault
    (RuntimeError("bug in a callback"), RuntimeError),
])
def test_every_way_out_leaves_pins_at_rest_with_torque_off(error, expected):
    from pinarray.hardware.feetech.transport import open_bus

    from .lab import device_setup

    clock = StopAt(error, frame=4)
    bus = open_bus("sim://?ids=1-16", device_setup(), clock)
    clock.armed = True
    with pytest.raises(expected):
        play_trial(bus, pulse_train(range(1, 17), 5, 5), clock)
    assert_safe(bus)


def test_pins_made_safe_covers_a_whole_session_of_trials():
    bus = sim_bus()
    with pytest.raises(KeyboardInterrupt), pins_made_safe(bus):
        play_trial(bus, pulse_train([2], 5, 2), bus.clock, release_at_end=False)
        assert bus.sim.servos[2].torque_enabled  # still holding between trials
        raise KeyboardInterrupt
    assert_safe(bus)


def test_the_simulated_pin_never_moves_faster_than_the_servo_can():
    bus = sim_bus()  # goal speed 3000 steps/s, acceleration register 0 (the servo's maximum)
    servo = bus.sim.servos[1]
    servo.start_recording()
    report = play_trial(bus, pulse_train([1], 10, 10, up_steps=2300), bus.clock)
    times = np.arange(report.onset_ns, report.onset_ns + 1_000_000_000, 250_000)
    positions = np.array([servo.position_at_ns(int(t)) for t in times])
    speeds = np.abs(np.diff(positions)) / (np.diff(times) / 1e9)
    assert speeds.max() <= 3000 * 1.001
    # 252 steps each way in 50 ms is out of reach: a swing lasts at most the 50 ms its goal
    # holds plus the time to brake from 3000 steps/s, so no cycle swings the full stroke.
    braking_s = 3000 / servo.model.max_acceleration_steps_per_s2
    for cycle in range(10):
        start_ns = report.onset_ns + cycle * 100_000_000
        in_cycle = (times >= start_ns) & (times < start_ns + 100_000_000)
        assert 40 < np.ptp(positions[in_cycle]) <= 3000 * (0.050 + braking_s) < 252
