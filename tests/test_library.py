"""pinarray as a library, as a lab's script uses it: a protocol loaded, the array opened, a
stimulus presented now or armed for a time, a whole session run with the script's answers, the
results read back. On the simulated array in virtual time (the ``simulated_array`` fixture is
the package's own pytest plugin, loaded by entry point)."""

import threading
from fractions import Fraction
from pathlib import Path

import pytest

import pinarray
from pinarray.cli import main
from pinarray.testing import (
    assert_delivered,
    assert_every_goal_confirmed,
    assert_left_safe,
    assert_not_delivered,
    assert_pin_moved,
)

LOCALISATION = Path(__file__).resolve().parents[1] / "protocols" / "localisation.yaml"
SECOND_NS = 1_000_000_000

# Two pins, one second each: a whole session in a few hundred milliseconds of virtual time.
TWO_PINS = """\
protocol: twopins
description: Two pins, one second each.
stimuli:
  buzz:
    frequency_hz: 5
    duration_s: 1
    pulse_width_ms: {up: 2.0, down: 1.5}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 6]
  frequencies_hz: [5]
  repetitions: 2
  order: random
  inter_trial_interval_s: 1
"""


@pytest.fixture
def localisation():
    return pinarray.load_protocol(LOCALISATION)


def test_pin_6_at_10_hz_has_every_goal_confirmed_and_moves_its_65_steps(
        simulated_array, localisation):
    array = simulated_array(localisation)
    before_ns = array.now_ns()
    delivery = array.present(pinarray.find_condition(localisation, pin=6, frequency_hz=10))
    assert_delivered(delivery)
    assert_every_goal_confirmed(delivery)
    assert_pin_moved(delivery, pin=6, steps=65)
    assert delivery.onset_ns == before_ns + array.lead_ns  # presented at once: after the lead
    assert delivery.duration_ns == 10 * SECOND_NS
    assert [s.pin for s in delivery.strokes] == [6]


class HeldClock(pinarray.VirtualClock):
    """Virtual time whose waits hold, once `hold` is called, until `release`: a test can see
    what the script sees while a stimulus waits for its onset."""

    def __init__(self):
        super().__init__()
        self.open = threading.Event()
        self.open.set()

    def hold(self):
        self.open.clear()

    def release(self):
        self.open.set()

    def sleep_until_ns(self, deadline_ns):
        self.open.wait()
        super().sleep_until_ns(deadline_ns)

    doze_until_ns = sleep_until_ns


def test_a_stimulus_armed_for_a_time_starts_exactly_then_and_the_script_goes_on_meanwhile(
        simulated_array, localisation):
    clock = HeldClock()
    array = simulated_array(localisation, clock=clock)
    flip_ns = array.now_ns() + SECOND_NS  # the screen flip it should start on
    clock.hold()
    armed = array.arm(pinarray.find_condition(localisation, pin=4, frequency_hz=5), at_ns=flip_ns)
    assert not armed.done  # arm returned while the stimulus waits for its onset
    clock.release()
    delivery = armed.result(timeout_s=60)
    assert armed.done and armed.onset_ns == delivery.onset_ns == flip_ns
    assert_every_goal_confirmed(delivery)
    assert_pin_moved(delivery, pin=4, steps=65)


def test_an_onset_sooner_than_the_lead_is_refused_before_anything_moves(
        simulated_array, localisation):
    array = simulated_array(localisation)
    soon_ns = array.now_ns() + array.lead_ns // 2
    condition = pinarray.find_condition(localisation, pin=6, frequency_hz=3)
    with pytest.raises(pinarray.PinArrayError, match="arm it at least 20 ms ahead"):
        array.arm(condition, at_ns=soon_ns)
    assert_delivered(array.present(condition))  # nothing was left armed


def test_one_stimulus_plays_at_a_time(simulated_array, localisation):
    clock = HeldClock()
    array = simulated_array(localisation, clock=clock)
    condition = pinarray.find_condition(localisation, pin=6, frequency_hz=3)
    clock.hold()
    armed = array.arm(condition, at_ns=array.now_ns() + SECOND_NS)
    with pytest.raises(pinarray.PinArrayError, match="wait for its result or cancel it first"):
        array.present(condition)
    clock.release()
    assert_delivered(armed.result(timeout_s=60))


def test_a_stimulus_the_protocol_does_not_hold_is_refused_naming_what_it_holds(
        simulated_array, localisation):
    array = simulated_array(localisation)
    with pytest.raises(pinarray.PinArrayError,
                       match="seed_train on pin 2 at 10 Hz is not a condition of the protocol"):
        array.present(pinarray.LocalisationCondition("seed_train", 2, Fraction(10)))


def test_finding_a_condition_names_the_candidates_when_the_filters_leave_several_or_none(
        localisation):
    with pytest.raises(pinarray.PinArrayError, match="3 conditions have pin 6 .*at 3 Hz"):
        pinarray.find_condition(localisation, pin=6)
    with pytest.raises(pinarray.PinArrayError, match="no condition of the design has pin 2"):
        pinarray.find_condition(localisation, pin=2)
    assert pinarray.find_condition(localisation, pin=6, frequency_hz=5.0).frequency_hz == 5


def test_goal_writes_lost_on_the_wire_are_written_again_and_every_goal_is_confirmed(
        simulated_array, localisation):
    array = simulated_array(localisation, "sim://?drop_writes=0.2&seed=3")
    delivery = array.present(pinarray.find_condition(localisation, pin=6, frequency_hz=5))
    assert_every_goal_confirmed(delivery)
    assert delivery.record.healed > 0


def test_a_slow_servo_falls_short_at_10_hz_and_the_stimulus_is_not_delivered_as_specified(
        simulated_array, localisation):
    array = simulated_array(localisation, "sim://?speed=1500")
    delivery = array.present(pinarray.find_condition(localisation, pin=6, frequency_hz=10))
    assert_every_goal_confirmed(delivery)  # every goal reached the servo; the pin did not
    assert_not_delivered(delivery, because="pin 6 moved")
    assert delivery.stroke(6).achieved_steps < 65


def test_an_adapter_pulled_out_mid_stimulus_is_a_bus_error_after_which_the_array_closes(
        simulated_array, localisation):
    array = simulated_array(localisation, "sim://?vanish_after=400")
    with pytest.raises(pinarray.PinArrayError, match="playback stopped at frame"):
        array.present(pinarray.find_condition(localisation, pin=6, frequency_hz=10))
    assert array.close().port_lost


def test_leaving_the_block_on_an_error_rests_the_pins_and_releases_torque(localisation):
    with pytest.raises(RuntimeError, match="a bug in the script"), \
            pinarray.open_array(localisation) as array:
        array.present(pinarray.find_condition(localisation, pin=6, frequency_hz=3))
        raise RuntimeError("a bug in the script")
    assert_left_safe(array)
    assert sorted(array.close().released_ids) == list(range(1, 17))
    with pytest.raises(pinarray.PinArrayError, match="the array is closed"):
        array.present(pinarray.find_condition(localisation, pin=6, frequency_hz=3))


def test_a_session_run_from_a_script_writes_what_pinarray_batch_writes(tmp_path):
    protocol_file = tmp_path / "twopins.yaml"
    protocol_file.write_text(TWO_PINS)
    protocol = pinarray.load_protocol(protocol_file)
    asked = []

    def observer_noting_each_question(question):
        asked.append(question)
        return answer(question)

    answer = pinarray.simulated_observer(protocol, seed=7)
    run = pinarray.run_session(protocol, observer_noting_each_question, subject="01",
                               results=tmp_path / "script", seed=7)
    assert main(["batch", str(protocol_file), "--subject", "01", "--observer", "default",
                 "--seed", "7", "--results", str(tmp_path / "batch")]) == 0

    by_batch = pinarray.read_results(tmp_path / "batch")
    assert [r.status for r in (run, *by_batch)] == ["completed", "completed"]
    assert run.paths.beh_tsv.read_text() == by_batch[0].paths.beh_tsv.read_text()
    assert run.paths.events_tsv.read_text() == by_batch[0].paths.events_tsv.read_text()
    assert [q.trial.trial for q in asked] == [1, 2, 3, 4]
    assert {q.adapted_value for q in asked} == {None}  # a fixed design
    assert [r.pin for r in run.records] == [q.trial.condition.pin for q in asked]


def test_a_protocol_with_problems_raises_them_all_located(tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text(TWO_PINS.replace("pins: [1, 6]", "pins: [1, 99]").replace(
        "frequency_hz: 5\n", "frequency_hz: -5\n", 1))
    with pytest.raises(pinarray.ProtocolErrors) as problems:
        pinarray.load_protocol(broken)
    assert len(problems.value.errors) >= 2
    assert all(str(e).startswith(f"{broken}:") for e in problems.value.errors)
