"""The pins' measured motion on the simulated array: what the horns did, and a slow servo caught."""

import subprocess
import sys
from fractions import Fraction

import numpy as np
import pytest

from pinarray.clock import VirtualClock
from pinarray.hardware.feetech.registers import Register
from pinarray.hardware.motion import PinTrace, measure_trial
from pinarray.hardware.sampling import Holds
from pinarray.journal.paths import RunPaths
from pinarray.journal.physio import motion_recording_path, read_motion
from pinarray.journal.records import TrialStatus
from pinarray.journal.rows import read_trials
from pinarray.paradigms.localisation.design import LocalisationCondition
from pinarray.plan import PlannedTrial
from pinarray.player.playback import play_prepared, play_trial, prepare_trial
from pinarray.player.rig import Rig
from pinarray.protocol.load import parse_protocol
from pinarray.schedule import compile_trial
from tests.runs import REPO

from .lab import pulse_train, sim_bus, targets

MS = 1_000_000
SEED = (REPO / "protocols" / "localisation.yaml").read_text()
# The seed's localisation protocol with 1 s trains: 10 cycles at 10 Hz.
# The seed on a 6 mm horn: a stroke of 114 steps, which the simulated servo cannot make in
# full at 10 Hz (it turns back before it arrives).
SHORT = SEED.replace("duration_s: 10\n", "duration_s: 1\n").replace(
    "2.0: 2113", "2.0: 2162").replace("lever_mm: 10\n", "lever_mm: 6\n")


def trial_at_10_hz_on_pin_6():
    return PlannedTrial(1, 1, False, LocalisationCondition("seed_train", 6, Fraction(10)))


def horn_strokes(servo, onset_ns, starts_ns, end_ns):
    """Peak-to-peak of the simulator's own horn over each cycle, sampled every 0.1 ms."""
    peaks = []
    for k, start in enumerate(starts_ns):
        stop = starts_ns[k + 1] if k + 1 < len(starts_ns) else end_ns
        horn = [servo.position_at_ns(onset_ns + t) for t in range(start, stop, 100_000)]
        peaks.append(max(horn) - min(horn))
    return peaks


def test_a_read_of_present_position_answers_where_the_horn_is_when_the_servo_gets_it():
    bus = sim_bus()
    servo = bus.sim.servos[5]
    servo.start_recording()
    bus.write_goals({5: 2250})
    for _ in range(60):
        bus.clock.sleep_until_ns(bus.clock.now_ns() + 2 * MS)
        sent_ns = bus.clock.now_ns()
        heard_ns = sent_ns + bus.wire_ns(bus.read_request_bytes((5,)))
        (steps,) = bus.read_positions((5,), sent_ns + 50 * MS).values()
        assert abs(steps - servo.position_at_ns(heard_ns)) <= 0.5  # the encoder rounds
    assert steps == 2250  # arrived: the last reads find it on its goal
    assert Register.PRESENT_POSITION.address == 56


def test_a_10_hz_localisation_trial_reports_the_stroke_the_simulated_horn_made_within_a_step():
    protocol = parse_protocol(SHORT, "short.yaml")
    schedule = compile_trial(protocol, trial_at_10_hz_on_pin_6())
    with Rig(protocol, None, None, VirtualClock()) as rig:
        servo = rig.bus.sim.servos[6]
        servo.start_recording()
        presentation = rig.present(schedule)
    (stroke,) = presentation.delivery.strokes.pins
    (trace,) = presentation.trace
    assert stroke.pin == 6 and stroke.commanded_steps == 2162 - 2048
    starts = [int(t) for t, p in zip(schedule.targets.time_ns, schedule.targets.position_steps,
                                      strict=True) if p == 2162]
    horn = horn_strokes(servo, presentation.onset_ns, starts, schedule.end_ns)
    assert stroke.cycles == len(horn) == 10
    assert abs(stroke.achieved_steps - min(horn)) <= 1
    assert abs(stroke.median_steps - float(np.median(horn))) <= 1
    # every sample is where the horn was (the encoder rounds to a step)
    onset = presentation.onset_ns
    assert max(abs(p - servo.position_at_ns(onset + int(t)))
               for t, p in zip(trace.time_ns, trace.position_steps, strict=True)) <= 0.5
    # and only the moving pin was asked: the other 15 servos cost nothing
    assert [t.pin for t in presentation.trace] == [6]


def test_a_train_too_fast_for_a_slow_servo_is_recorded_invalid_never_ok(tmp_path):
    slow = SHORT.replace('port: "sim://"', 'port: "sim://?speed=1500"').replace(
        "frequencies_hz: [3, 5, 10]", "frequencies_hz: [10]").replace(
        "pins: [1, 4, 6, 7, 10, 11, 13, 16]", "pins: [6]").replace(
        "practice_trials: 2", "practice_trials: 0")
    assert "speed=1500" in slow and "frequencies_hz: [10]" in slow
    protocol_file = tmp_path / "slow.yaml"
    protocol_file.write_text(slow)
    result = subprocess.run(
        [sys.executable, "-m", "pinarray", "batch", str(protocol_file), "--subject", "S",
         "--observer", "default", "--results", str(tmp_path / "results"), "--seed", "1"],
        capture_output=True, text=True, timeout=300)
    paths = RunPaths(tmp_path / "results", "S", "1", "localisation", 1)
    rows = read_trials(paths.beh_tsv)
    assert rows, result.stderr
    assert all(r.status is TrialStatus.INVALID for r in rows), [r.status for r in rows]
    assert "pin 6 moved" in rows[0].status_reason and "of 114 commanded steps" in rows[0].status_reason
    assert rows[0].stroke.commanded_steps == 114 and rows[0].stroke.achieved_steps < 0.8 * 114
    samples = read_motion(motion_recording_path(paths))
    assert {s.pin for s in samples} == {6} and {s.trial for s in samples} == {rows[0].trial}


def test_sampling_costs_no_verified_goal_on_the_simulator():
    schedule = pulse_train([2, 7, 12], 10, 10, up_steps=2162)
    counts = []
    for sampling in (False, True):
        bus = sim_bus("drop_writes=0.1&seed=3")
        report = play_prepared(bus, prepare_trial(bus, schedule), bus.clock,
                               sample_motion=sampling)
        d = report.delivery
        counts.append((d.scheduled, d.confirmed, d.healed, d.missing, d.worst_lateness_ns))
        assert bool(report.trace) is sampling
        # in the simulator's virtual time every frame goes out on its deadline, sampled or not
        np.testing.assert_array_equal(report.sent_ns, report.scheduled_ns)
    assert counts[0] == counts[1]
    assert counts[0][2] > 0 and counts[0][3] == 0  # some sync writes were lost, and healed


def test_pwm_servos_report_no_position_and_their_trials_record_no_stroke():
    protocol = parse_protocol((REPO / "protocols" / "localisation_pwm.yaml").read_text(),
                              "pwm.yaml")
    planned = PlannedTrial(1, 1, False, LocalisationCondition("seed_train", 6, Fraction(10)))
    with Rig(protocol, None, None, VirtualClock()) as rig:
        presentation = rig.present(compile_trial(protocol, planned))
    assert presentation.trace == () and presentation.delivery.strokes is None


def test_the_stroke_summary_names_the_commanded_and_achieved_steps():
    bus = sim_bus()
    report = play_trial(bus, pulse_train([4], 3, 3, up_steps=2162), bus.clock)
    assert "stroke 114/114 steps" in report.delivery.summary()


def test_a_pin_holding_its_goal_is_sampled_only_as_often_as_its_cycles_need():
    # 3 Hz, 114 steps: the horn arrives within about 60 ms and holds for about 100 ms of
    # every half cycle.
    bus = sim_bus()
    schedule = pulse_train([4], 3, 6, up_steps=2162)
    report = play_prepared(bus, prepare_trial(bus, schedule), bus.clock)
    (trace,) = report.trace
    gaps_ms = np.diff(trace.time_ns) / MS
    trial_s = schedule.end_ns / 1e9
    # fewer than one sample every 4 ms ...
    assert len(trace.time_ns) < 0.75 * trial_s * 1000 / 4
    # ... none more than an eighth of a 333 ms cycle apart (the last cycle runs on to the
    # trial's end, 200 ms later), and every 4 ms while it moves
    last_cycle_ns = 5 * round(1e9 / 3)
    assert gaps_ms[trace.time_ns[1:] <= last_cycle_ns].max() <= 333.4 / 8
    assert gaps_ms.max() <= (schedule.end_ns - last_cycle_ns) / MS / 8
    assert np.median(gaps_ms) == pytest.approx(4, abs=0.1)
    (stroke,) = report.delivery.strokes.pins
    assert stroke.cycles == 6 and stroke.achieved_steps == 114 and stroke.lag_ns is not None


@pytest.mark.parametrize("rate_hz, up_steps", [(3, 2162), (5, 2113), (2, 2300)])
def test_the_samples_held_back_would_not_have_changed_the_pins_measured_motion(rate_hz, up_steps):
    """Where the trace skips (a pin holding its goal), the simulator's horn at every 0.5 ms
    put back into the trace changes no stroke, no lag and no short cycle."""
    bus = sim_bus()
    servo = bus.sim.servos[4]
    servo.start_recording()
    schedule = pulse_train([4], rate_hz, 5, up_steps=up_steps)
    trial = prepare_trial(bus, schedule)
    report = play_prepared(bus, trial, bus.clock)
    (trace,) = report.trace
    skipped = [t for start, stop in zip(trace.time_ns[:-1], trace.time_ns[1:], strict=True)
               if stop - start > 4 * MS + MS // 2
               for t in range(int(start) + MS // 2, int(stop), MS // 2)]
    assert skipped, "nothing was held back"
    times = np.concatenate((trace.time_ns, np.array(skipped, dtype=np.int64)))
    horn = [servo.position_at_ns(report.onset_ns + int(t)) for t in skipped]
    positions = np.concatenate((trace.position_steps, np.rint(horn).astype(np.int32)))
    order = np.argsort(times, kind="stable")
    dense = PinTrace(trace.pin, trace.servo_id, times[order], positions[order])
    assert measure_trial([dense], trial.changes, trial.end_ns) == report.delivery.strokes


@pytest.mark.parametrize("query", ["return_delay_us=250", "baud=115200&return_delay_us=2"])
def test_a_read_is_answered_the_moment_its_last_byte_arrives_in_virtual_time(query):
    # No polling: a request costs its bytes on the wire and the servo's return delay, exactly.
    bus = sim_bus(query)
    start_ns = bus.clock.now_ns()
    bus.read_positions((5,), start_ns + 50 * MS)
    request, reply = bus.read_request_bytes((5,)), 6 + 2
    return_delay_ns = bus.sim.servos[5].return_delay_ns
    assert bus.clock.now_ns() - start_ns == bus.wire_ns(request + reply) + return_delay_ns


class PolledOnly:
    """The simulated port without `readable_at_ns`: its reader polls, as for a pyserial URL."""

    def __init__(self, port):
        self._port = port

    def __getattr__(self, name):
        if name == "readable_at_ns":
            raise AttributeError(name)
        return getattr(self._port, name)


@pytest.mark.parametrize("query", ["", "drop_writes=0.1&seed=4", "late=0.05&late_ms=3&seed=2"])
def test_waiting_for_the_ports_bytes_or_polling_for_them_delivers_and_measures_the_same(query):
    reports = []
    for polled in (False, True):
        bus = sim_bus(query)
        if polled:
            bus.link.wire.port = PolledOnly(bus.link.wire.port)
            bus.link.wire._readable_at_ns = None
        reports.append(play_prepared(bus, prepare_trial(bus, pulse_train([4, 9], 5, 4, 2162)),
                                     bus.clock))
    waited, polled = reports
    assert waited.delivery.missing == polled.delivery.missing == 0
    assert (waited.delivery.confirmed, waited.delivery.healed) == (
        polled.delivery.confirmed, polled.delivery.healed)
    for a, b in zip(waited.delivery.strokes.pins, polled.delivery.strokes.pins, strict=True):
        assert (a.commanded_steps, a.achieved_steps, a.cycles, a.short_cycles) == (
            b.commanded_steps, b.achieved_steps, b.cycles, b.short_cycles)
        # polling every 20 us finds a reply up to 20 us after it arrived; waiting, at once
        assert abs(a.lag_ns - b.lag_ns) <= 20_000


def up_then_short_down(pins, period_ms=300, up_ms=260, cycles=4, up_steps=2300):
    """Up for most of each cycle, briefly down: a stroke a slow servo cannot make down."""
    changes = [(k * period_ms * MS + at_ms * MS, pin, goal) for k in range(cycles)
               for pin in pins for at_ms, goal in ((0, up_steps), (up_ms, 2048))]
    return targets(changes, cycles * period_ms * MS + 200 * MS)


@pytest.mark.parametrize("query, schedule", [
    ("", pulse_train(range(1, 17), 2, 4, up_steps=2162)),
    ("", up_then_short_down(range(1, 17))),
    ("baud=115200", pulse_train(range(1, 17), 2, 4, up_steps=2162)),
    ("baud=57600", pulse_train(range(1, 9), 2, 4, up_steps=2162)),
], ids=["16-pins-2Hz", "16-pins-short-down", "16-pins-115200", "8-pins-57600"])
def test_holding_samples_back_measures_what_sampling_every_period_measures(query, schedule,
                                                                          monkeypatch):
    """Sixteen pins on the factory return delay, or a slow bus: a sample of them all and the
    read-back after a change take tens of ms, which the samples held back must leave room
    for (else a cycle goes unjudged, or a short one is missed and the trial passes)."""
    measured = []
    for every_period in (False, True):
        if every_period:
            monkeypatch.setattr(Holds, "next_sample_ns", lambda self, last_ns, sample_ns, after_ns:
                                last_ns + max(self.period_ns, sample_ns))
        bus = sim_bus(query)
        report = play_prepared(bus, prepare_trial(bus, schedule), bus.clock)
        measured.append((report.delivery.strokes, sum(len(t.time_ns) for t in report.trace)))
    (held_back, fewer), (every, more) = measured
    assert held_back == every
    assert fewer <= more  # equal where the bus leaves no room to hold any back (115200 baud)
