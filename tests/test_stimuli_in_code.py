"""Stimuli built in code: a script presents a pattern, frames or a wave without writing a
protocol, read by the protocol's own readers (a train the file would refuse, the code refuses
in the same words), checked on the open array's device before anything moves, delivered and
measured like a protocol's stimulus, and described in full in what it delivered. On the
in-process simulator and through a serial port served by the simulated bus (the player
process driving it), as tests/test_library_paths.py opens both."""

from __future__ import annotations

import math
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pinarray
from pinarray.protocol.stimuli import read_train
from pinarray.protocol.yaml_nodes import Reader
from pinarray.testing import assert_delivered, assert_pin_moved
from tests import test_library_paths as paths

way = paths.way  # each way to the pins in turn: the simulator, and a port served on a pty
realtime = pytest.mark.realtime  # the wall clock and pseudo-terminals: run apart (tests/suite.py)

# A small stroke (12 steps), so that the servos could follow 80 Hz: what refuses 16 pins at
# 80 Hz is then the servo bus alone. A wide tolerance and no stroke judged: these tests are
# about the path, not the timing of a busy machine (tests/test_library_paths.py says why).
RIG = """\
protocol: rig
device:
  delivery_tolerance_ms: 500
  stroke_tolerance_percent: 0
  calibration:
    rest_steps: 2048
    positions: {1.5: 2048, 2.0: 2060}
    limits_steps: [2000, 2200]
stimuli:
  tap: {frequency_hz: 5, duration_s: 0.4}
design: {paradigm: localisation, stimulus: tap, pins: [6], frequencies_hz: [5]}
"""
TAP = pinarray.Train(frequency_hz=5, duration_s=1)
SQUARE = pinarray.Pattern(pins=[6, 7, 10, 11], train=TAP)
# Every pin at 80 Hz, a change every 6.25 ms: each frame's read-back of 16 goals takes 10 ms.
BUS_BOUND = pinarray.Pattern(pins=list(range(1, 17)),
                             train=pinarray.Train(frequency_hz=80, duration_s=0.2,
                                                  pulses_per_cycle=2))
# Faster than a servo can lift a pin and let it down (stroke 12 steps: at most 125 Hz).
TOO_FAST = pinarray.Pattern(pins=[6], train=pinarray.Train(frequency_hz=200, duration_s=0.2,
                                                           pulses_per_cycle=2))


def goal_writes(servos) -> list[int]:
    """Counts, per servo, of the goal positions written to it from now on (from its side)."""
    counts = [0] * 17
    for servo_id, servo in servos.items():
        original = servo.write

        def counted(address, data, now_ns, servo_id=servo_id, original=original):
            if address <= 42 < address + len(data):
                counts[servo_id] += 1
            return original(address, data, now_ns)

        servo.write = counted
    return counts


@realtime
def test_a_pattern_built_in_code_is_delivered_with_its_four_pins_measured(way):
    array = way.open(pinarray.protocol_from_text(RIG, name="rig"))
    delivery = array.present(SQUARE)
    assert_delivered(delivery)
    assert [s.pin for s in delivery.strokes] == [6, 7, 10, 11]
    # Every cycle of each pin accounted for, and each measured one at its full stroke. How many
    # are measured is the machine's: a busy one starves the simulated servos' thread of the
    # samples a cycle needs (this protocol judges no stroke; in virtual time every cycle is
    # measured: test_an_array_opened_without_a_protocol_plays_code_on_the_default_device).
    for stroke in delivery.strokes:
        assert stroke.commanded_steps == 12 and stroke.cycles + stroke.unmeasured_cycles == 5
        assert stroke.cycles == 0 or stroke.achieved_steps == 12, stroke
    assert delivery.stimulus == repr(SQUARE)
    assert delivery.stimulus.startswith("Pattern(pins=[6, 7, 10, 11], train=Train("
                                        "frequency_hz=5, duration_s=1, pulses_per_cycle=10, "
                                        "duty_cycle=0.5, pulse_width_ms={'up': 2, 'down': 1.5}")


@realtime
@pytest.mark.parametrize(("stimulus", "because"), [
    (BUS_BOUND, "present: Pattern: pins: the servo bus cannot deliver it: "),
    (TOO_FAST, "present: Pattern: pins: pin 6 cannot follow 200 Hz"),
], ids=["the bus cannot carry it", "the servos cannot follow it"])
def test_a_stimulus_the_array_cannot_play_is_refused_before_anything_moves(way, stimulus,
                                                                          because):
    array = way.open(pinarray.protocol_from_text(RIG, name="rig"))
    written = goal_writes(way.servos(array))
    for call in (array.present, array.arm, array.prepare):
        with pytest.raises(pinarray.PinArrayError) as refused:
            call(stimulus)
        message = str(refused.value).replace("present:", f"{call.__name__}:")
        assert message.startswith(because.replace("present:", f"{call.__name__}:"))
        assert "\n" not in message
    assert sum(written) == 0  # not a goal reached any servo
    assert "open, idle" in repr(array)


# pinarray's default device (STS3215 servos at their datasheet speed, the seed's 114-step
# stroke), written as a protocol with no device section: the analytic check lets one pin
# follow up to 13.16 Hz, but the simulated servos also limit acceleration and lag.
DEFAULT_DEVICE = """\
protocol: default-device
stimuli:
  tap: {frequency_hz: 5, duration_s: 0.4}
design: {paradigm: localisation, stimulus: tap, pins: [6], frequencies_hz: [5]}
"""
# RIG's 12-step stroke, its stroke judged (the default tolerance): fast trains of many pins
# leave the verifier too few samples between frames to measure a cycle.
SMALL_STROKE = RIG.replace("  delivery_tolerance_ms: 500\n  stroke_tolerance_percent: 0\n", "")


def pattern(pins, frequency_hz, duration_s=0.5):
    return pinarray.Pattern(pins=list(pins), train=pinarray.Train(frequency_hz=frequency_hz,
                                                                  duration_s=duration_s))


@realtime
@pytest.mark.parametrize(("device", "stimulus", "because"), [
    (DEFAULT_DEVICE, pattern([6], 10, 1), r"pin 6 moved \d+ of 114 commanded steps"),
    (SMALL_STROKE, pattern(range(1, 17), 20), r"pin 1's stroke not measured in"),
    (SMALL_STROKE, pattern(range(1, 5), 40), r"pin 1's stroke not measured in"),
], ids=["the default servos cannot lift a pin at 10 Hz", "16 pins at 20 Hz are not measured",
        "4 pins at 40 Hz are not measured"])
def test_a_stimulus_the_simulated_servos_would_not_deliver_is_refused_before_anything_moves(
        way, device, stimulus, because):
    array = way.open(pinarray.protocol_from_text(device, name="rig"))
    written = goal_writes(way.servos(array))
    for call in (array.prepare, array.arm, array.present):
        with pytest.raises(pinarray.PinArrayError) as refused:
            call(stimulus)
        message = str(refused.value)
        assert message.startswith(f"{call.__name__}: Pattern: played as a run plays it, on "
                                  "simulated STS3215 servos")
        assert re.search(because, message) and "\n" not in message, message
    assert sum(written) == 0  # not a goal reached any servo
    assert "open, idle" in repr(array)


@pytest.mark.parametrize("pins", [[6], [6, 7, 10, 11]])
def test_what_the_default_device_refuses_is_what_it_would_not_deliver(pins):
    # Across the frequencies where the servos stop keeping up: every stimulus accepted is
    # delivered, and the faster ones are refused before they play.
    outcomes = {}
    with pinarray.open_array() as array:
        for frequency_hz in range(6, 14):
            try:
                delivery = array.present(pattern(pins, frequency_hz, 1))
            except pinarray.PinArrayError:
                outcomes[frequency_hz] = "refused"
            else:
                assert_delivered(delivery)
                outcomes[frequency_hz] = "delivered"
    assert outcomes[6] == "delivered" and outcomes[13] == "refused", outcomes


def test_an_array_opened_without_a_protocol_plays_code_on_the_default_device():
    with pinarray.open_array() as array:
        assert array.simulated and array.protocol.device.grid.pin_count == 16
        delivery = array.present(SQUARE)
    assert_delivered(delivery)
    for pin in (6, 7, 10, 11):
        assert_pin_moved(delivery, pin=pin, steps=114)  # the seed's calibration: 2048 to 2162
        assert delivery.stroke(pin).cycles == 5  # every cycle measured


def test_real_servos_need_the_protocol_that_calibrates_them():
    with pytest.raises(pinarray.PinArrayError, match=r"^open_array: /dev/ttyUSB0: real servos "
                                                     r"need the protocol that calibrates them"):
        pinarray.open_array(port="/dev/ttyUSB0")
    with pytest.raises(pinarray.PinArrayError, match="its device is STS servos"):
        pinarray.open_array(sim="sim://pca9685")


def test_frames_and_waves_play_their_pins_in_time():
    short = pinarray.Train(frequency_hz=5, duration_s=0.4)
    bottom, top = (pinarray.Pattern(pins=pins, train=short) for pins in ([1, 2], [13, 14]))
    stimuli = {
        pinarray.Frames(frames=[bottom, top], soa_ms=400): [1, 2, 13, 14],
        pinarray.Wave("rightwards", row=2, train=short, soa_ms=100): [5, 6, 7, 8],
        pinarray.Wave("none", row=1, pins=[1, 2, 3], train=short, soa_ms=400): [1, 2, 3],
        pinarray.Wave("upwards", pins=[4, 8, 12], train=short, soa_ms=200): [4, 8, 12],
        pinarray.Wave("sequence", pins=[1, 6, 11, 16], direction="up-right", train=short,
                      soa_ms=200): [1, 6, 11, 16],
        pinarray.Pattern(pins="# . . .\n# . . .\n# . . .\n# # # #", train=short):
            [1, 2, 3, 4, 5, 9, 13],
    }
    with pinarray.open_array() as array:
        for stimulus, pins in stimuli.items():
            delivery = array.present(stimulus)
            assert_delivered(delivery)
            assert sorted(s.pin for s in delivery.strokes) == pins, stimulus
            assert delivery.stimulus == repr(stimulus)
        frames = next(iter(stimuli))
        assert array.present(frames).duration_ns == 800_000_000  # the second frame's end


def test_a_stimulus_built_in_code_is_read_on_the_arrays_own_grid_and_calibration():
    with pinarray.open_array() as array:
        for stimulus, because in (
            (pinarray.Pattern(pins=[6, 17], train=TAP),
             "present: Pattern: pins[1]: expected a pin from 1 to 16 on the 4x4 grid, found 17"),
            (pinarray.Pattern(pins=[6, 6], train=TAP),
             "present: Pattern: pins: expected each pin of a pattern once, found 6 more than "
             "once"),
            (pinarray.Frames(frames=[SQUARE, SQUARE], soa_ms=100),
             "present: Frames: soa_ms: expected one train at a time on each pin, found pin 6 "
             "driven twice at once"),
            (pinarray.Wave("rightwarsd", row=2, train=TAP),
             "present: Wave: wave: expected the wave to be one of rightwards"),
            (pinarray.Wave("upwards", pins=[2, 7], train=TAP),
             "present: Wave: pins: expected the pins of an upwards wave to go up one column"),
            (pinarray.Pattern(pins=list(range(1, 17)),
                              train=pinarray.Train(frequency_hz=40, duration_s=1)),
             "present: Pattern: pins: pin 1 cannot follow 40 Hz (datasheet figures)"),
        ):
            with pytest.raises(pinarray.PinArrayError) as refused:
                array.present(stimulus)
            assert str(refused.value).startswith(because)
        with pytest.raises(pinarray.PinArrayError, match="a Train plays on pins"):
            array.present(TAP)  # type: ignore[arg-type]


def test_a_stimulus_built_in_code_arms_and_starts_on_a_cue():
    with pinarray.open_array() as array:
        armed = array.arm(SQUARE)
        armed.start()
        delivery = armed.result(timeout_s=30)
    assert delivery.delivered and delivery.stimulus == repr(SQUARE)


def test_a_protocols_condition_is_described_in_its_delivery_as_its_paradigm_names_it():
    protocol = pinarray.protocol_from_text(RIG, name="rig")
    with pinarray.open_array(protocol) as array:
        delivery = array.present(pinarray.find_condition(protocol, pin=6))
    assert delivery.stimulus == "tap on pin 6 at 5 Hz"


# -- the door: wrong arguments are one-line errors naming them --------------------------------

GOOD = {"frequency_hz": 5, "duration_s": 1}


@pytest.mark.parametrize(("build", "named"), [
    (lambda: pinarray.Train(frequency_hz="5", duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(frequency_hz=math.nan, duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(frequency_hz=math.inf, duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(frequency_hz=True, duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(frequency_hz=None, duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(frequency_hz=5, duration_s=-1), "duration_s"),
    (lambda: pinarray.Train(frequency_hz=5, duration_s=0), "duration_s"),
    (lambda: pinarray.Train(frequency_hz=-5, duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(**GOOD, pulses_per_cycle=10.0), "pulses_per_cycle"),
    (lambda: pinarray.Train(**GOOD, pulses_per_cycle=False), "pulses_per_cycle"),
    (lambda: pinarray.Train(**GOOD, duty_cycle=1), "duty_cycle"),
    (lambda: pinarray.Train(**GOOD, duty_cycle=0.33), "duty_cycle"),
    (lambda: pinarray.Train(**GOOD, pulse_width_ms=2), "pulse_width_ms"),
    (lambda: pinarray.Train(**GOOD, pulse_width_ms={"up": 2}), "pulse_width_ms"),
    (lambda: pinarray.Train(**GOOD, pulse_width_ms={"up": 2, "down": "1.5"}),
     "pulse_width_ms['down']"),
    (lambda: pinarray.Train(**GOOD, pulse_width_ms={"up": 30, "down": 1.5}), "pulse_width_ms"),
    (lambda: pinarray.Train(**GOOD, phase_deg=-90), "phase_deg"),
    (lambda: pinarray.Pattern(pins=6, train=TAP), "pins"),
    (lambda: pinarray.Pattern(pins=[6, "7"], train=TAP), "pins[1]"),
    (lambda: pinarray.Pattern(pins=[6, True], train=TAP), "pins[1]"),
    (lambda: pinarray.Pattern(pins=[6], train={"frequency_hz": 5}), "train"),
    (lambda: pinarray.Pattern(pins=[6], train=TAP, phase_deg=math.nan), "phase_deg"),
    (lambda: pinarray.Frames(frames=SQUARE, soa_ms=100), "frames"),
    (lambda: pinarray.Frames(frames=[SQUARE, TAP], soa_ms=100), "frames[1]"),
    (lambda: pinarray.Frames(frames=[SQUARE, SQUARE], soa_ms="100"), "soa_ms"),
    (lambda: pinarray.Wave(5, row=1, train=TAP), "wave"),
    (lambda: pinarray.Wave("rightwards", row=1.0, train=TAP), "row"),
    (lambda: pinarray.Wave("sequence", pins=[1, 2], direction=5, train=TAP), "direction"),
    (lambda: pinarray.Wave("rightwards", row=1, train=TAP, soa_ms=-math.inf), "soa_ms"),
    # Past 4300 digits Python will not write an int as text: refused before it is.
    (lambda: pinarray.Train(frequency_hz=10**5000, duration_s=1), "frequency_hz"),
    (lambda: pinarray.Train(**GOOD, pulses_per_cycle=10**5000), "pulses_per_cycle"),
    (lambda: pinarray.Train(frequency_hz=Fraction(10**5000, 3), duration_s=1), "frequency_hz"),
    (lambda: pinarray.Pattern(pins=[10**5000], train=TAP), "pins[0]"),
    (lambda: pinarray.Frames(frames=[SQUARE, SQUARE], soa_ms=10**5000), "soa_ms"),
    (lambda: pinarray.Wave("rightwards", row=10**5000, train=TAP), "row"),
], ids=lambda value: value if isinstance(value, str) else "")
def test_a_wrong_argument_is_a_one_line_error_naming_it(build, named):
    with pytest.raises(pinarray.PinArrayError) as refused:
        build()
    message = str(refused.value)
    assert "\n" not in message and f": {named}: " in message, message
    assert message.startswith(("pinarray.Train: ", "pinarray.Pattern: ", "pinarray.Frames: ",
                               "pinarray.Wave: "))


def test_numpy_scalars_and_arrays_are_numbers_and_pins_as_their_python_kin():
    train = pinarray.Train(frequency_hz=np.float64(2.5), duration_s=np.int64(2),
                           pulses_per_cycle=np.int32(10), duty_cycle=np.float32(0.5))
    assert train == pinarray.Train(frequency_hz=Fraction(5, 2), duration_s=2)
    assert pinarray.Pattern(pins=np.array([6, 7]), train=train).pins == (6, 7)


# -- one reader: the code reads a train exactly as a protocol file does ----------------------

NUMBERS = st.one_of(st.integers(-5, 1200), st.fractions(max_denominator=12).filter(
    lambda f: -5 <= f <= 1200), st.floats(-5, 1200, allow_nan=False, allow_infinity=False))


@settings(max_examples=150, deadline=None)
@given(frequency_hz=NUMBERS, duration_s=NUMBERS, pulses_per_cycle=st.integers(-1, 30),
       duty_cycle=NUMBERS, up_ms=NUMBERS, phase_deg=NUMBERS)
def test_a_train_built_in_code_is_the_train_a_protocol_file_writes_with_those_values(
        frequency_hz, duration_s, pulses_per_cycle, duty_cycle, up_ms, phase_deg):
    values = {"frequency_hz": frequency_hz, "duration_s": duration_s,
              "pulses_per_cycle": pulses_per_cycle, "duty_cycle": duty_cycle,
              "pulse_width_ms": {"up": up_ms, "down": 1.5}, "phase_deg": phase_deg}

    def written(value):
        if isinstance(value, dict):
            return "{" + ", ".join(f"{k}: {written(v)}" for k, v in value.items()) + "}"
        if isinstance(value, Fraction):
            return f"{value.numerator}/{value.denominator}"
        return repr(value)

    reader = Reader("train.yaml")
    text = "\n".join(f"{key}: {written(value)}" for key, value in values.items())
    from_file = reader.attempt(lambda: read_train(reader, reader.compose(text)), None)
    file_problems = [e.message for e in reader.errors]
    try:
        built = pinarray.Train(**values)
    except pinarray.PinArrayError as problem:
        said = str(problem).split(": ", 2)[2].split(" (and ")[0]
        assert said in file_problems
    else:
        assert file_problems == [] and built._train == from_file


# -- a protocol written in a script ------------------------------------------------------------

def test_a_protocol_from_text_is_the_protocol_its_file_holds(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text(RIG)
    from_file = pinarray.load_protocol(path)
    from_text = pinarray.protocol_from_text(RIG.replace("\n", "\r\n"), name="rig")
    assert from_text.source == "rig" and from_text.sha256 == from_file.sha256
    assert (from_text.device, from_text.stimuli, from_text.design.conditions) == \
        (from_file.device, from_file.stimuli, from_file.design.conditions)


def test_a_protocol_from_text_locates_its_problems_at_name_line_col():
    with pytest.raises(pinarray.ProtocolErrors) as problems:
        pinarray.protocol_from_text(RIG.replace("duration_s: 0.4", "duration_s: -1"),
                                    name="in my script")
    assert str(problems.value).startswith("in my script:10:38: expected the signal length "
                                          "more than 0 s, found -1")
    for text, name in ((5, "x"), (RIG, ""), (RIG, "two\nlines"), ("x" * (1 << 20 + 1), "x")):
        with pytest.raises(pinarray.PinArrayError, match="^protocol_from_text: (text|name): "):
            pinarray.protocol_from_text(text, name=name)


def test_a_value_refused_for_its_digits_is_shown_with_the_digits_that_refuse_it():
    # A float32's 0.3 is 0.30000001192092896: not 3 of 10 pulses, and the message says so.
    with pytest.raises(pinarray.PinArrayError) as refused:
        pinarray.Train(**GOOD, duty_cycle=np.float32(0.3))
    assert str(refused.value).endswith("found 0.30000001192092896 (3.0000001192092896 pulses)")
    with pinarray.open_array() as array, pytest.raises(pinarray.PinArrayError) as refused:
        array.present(pinarray.Pattern(pins=[6], train=pinarray.Train(
            **GOOD, pulse_width_ms={"up": 2.000001, "down": 1.5})))
    assert str(refused.value).endswith("pin 6: expected a pulse width it is calibrated for "
                                       "(1.5 ms, 2 ms), found 2.000001 ms")


def test_a_stimulus_too_long_for_one_trial_says_what_a_script_can_do_instead():
    with pinarray.open_array() as array, pytest.raises(pinarray.PinArrayError) as refused:
        array.present(pattern([6], 5, 172800))
    assert "--allow-long" not in str(refused.value)
    assert str(refused.value).endswith("shorten the signal, or present it as several shorter "
                                       "stimuli, one after another")
