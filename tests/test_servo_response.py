"""`pinarray servos response`: what one servo really does, and feasibility that follows it."""

import math
import tempfile
from fractions import Fraction
from pathlib import Path

import pytest

from pinarray.cli import main
from pinarray.protocol.feasibility import check_train
from pinarray.protocol.load import load_protocol
from pinarray.protocol.model import Train
from pinarray.protocol.response import (
    MeasuredResponse,
    ResponsePoint,
    read_response,
    response_text,
)
from pinarray.protocol.yaml_nodes import Reader

SEED = Path(__file__).resolve().parent.parent / "protocols" / "localisation.yaml"

# The seed's protocol on a 6 mm horn: 1 mm of travel is 114 steps, more than the simulated
# STS3215 makes in the 50 ms half-cycle of 10 Hz, though the datasheet speed allows it.
SHORT_HORN = SEED.read_text().replace("2.0: 2113", "2.0: 2162").replace("lever_mm: 10\n", "lever_mm: 6\n")

RESPONSE = """\
pin: 4
servo: STS3215
port: "sim://"
cycles: 10
speed_steps_per_s: 3000
acceleration: 0
duty_cycle: 1/2
points:
  - {frequency_hz: 5, stroke_commanded_steps: 114, stroke_achieved_steps: 114, stroke_median_steps: 114, lag_ms: 52, cycles_short: 0}
  - {frequency_hz: 10, stroke_commanded_steps: 114, stroke_achieved_steps: 80, stroke_median_steps: 81, cycles_short: 10}
"""


def run(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def measured(points, duty=Fraction(1, 2)) -> MeasuredResponse:
    return MeasuredResponse("r.yaml", 4, "STS3215", "sim://", 3000, 0, duty,
                            tuple(ResponsePoint(f, c, a, a, None, 0) for f, c, a in points), 10)


def test_between_two_measured_frequencies_the_reach_is_interpolated_and_nothing_faster_is_judged():
    response = measured([(5, 100, 100), (10, 100, 60)])  # half-cycles of 100 and 50 ms
    assert response.reach_steps(0.100) == 100
    assert response.reach_steps(0.050) == 60
    assert response.reach_steps(0.075) == pytest.approx(80)
    assert response.reach_steps(1.0) == 100  # slower than the slowest measured: no worse
    assert response.reach_steps(0.049) is None  # faster than anything measured
    assert response.shortest_half_cycle_s(80) == pytest.approx(0.075)
    assert response.shortest_half_cycle_s(101) == math.inf


def test_a_stroke_short_by_one_encoder_step_counts_as_achieved_in_full():
    assert measured([(10, 100, 99)]).reach_steps(0.05) == 100
    assert measured([(10, 100, 98)]).reach_steps(0.05) == 98


def test_a_stroke_made_in_full_is_within_reach_though_a_larger_one_fell_further_short():
    # Measured on the simulated STS3215 at 15 Hz: 32 steps in full, 49 fell to 21 in its worst
    # cycle. A 32-step train at 15 Hz is followed; the reach is not the short stroke's 21.
    response = measured([(15, 16, 16), (15, 32, 32), (15, 49, 21), (15, 65, 24)])
    assert response.reach_steps(1 / 30) == 32
    assert measured([(15, 49, 21), (15, 65, 24)]).reach_steps(1 / 30) == 21


def _with_response(tmp_path, points, protocol=None):
    """The short-horn seed naming a response of ``points`` (frequency, commanded, achieved)."""
    lines = "".join(f"  - {{frequency_hz: {f}, stroke_commanded_steps: {c}, stroke_achieved_"
                    f"steps: {a}, stroke_median_steps: {a}, cycles_short: 0}}\n"
                    for f, c, a in points)
    (tmp_path / "r.yaml").write_text(RESPONSE.split("points:")[0] + "points:\n" + lines)
    text = (protocol or SHORT_HORN).replace("  port: \"sim://\"\n",
                                            "  port: \"sim://\"\n  response: r.yaml\n")
    (tmp_path / "p.yaml").write_text(text)
    return tmp_path / "p.yaml", text


@pytest.mark.parametrize("feasibility", ["refuse", "scale"])
def test_a_train_faster_than_every_one_measured_is_refused_not_scaled_to_nothing(
        tmp_path, capsys, feasibility):
    protocol, text = _with_response(tmp_path, [(1, 114, 114), (5, 114, 114)])
    if feasibility == "scale":
        protocol.write_text(text.replace("  response: r.yaml\n",
                                         "  response: r.yaml\n  feasibility: scale\n"))
    status, out, err = run(capsys, "validate", protocol)
    assert (status, out) == (2, "") and err.count("\n") == 1
    line = protocol.read_text().splitlines().index("  frequencies_hz: [3, 5, 10]") + 1
    assert err.startswith(f"{protocol}:{line}:")
    assert ("pin 1: 10 Hz is faster than every train of the measured response of pin 4 (r.yaml):"
            " its shorter half-cycle of 50.0 ms is below the 100.0 ms measured") in err


def test_a_stroke_larger_than_every_one_measured_is_refused_asking_for_a_measurement(
        tmp_path, capsys):
    # 114 steps, 92 of them needed (80 %), against a measurement of 65-step trains only.
    protocol, _ = _with_response(tmp_path, [(1, 65, 65), (20, 65, 65)])
    status, out, err = run(capsys, "validate", protocol)
    assert (status, out) == (2, "") and err.count("\n") == 1
    assert ("pin 1: a stroke of 114 steps is larger than every stroke of the measured response "
            "of pin 4 (r.yaml) (largest 65 steps); measure it (`pinarray servos response "
            "--strokes`)") in err


def test_a_response_measured_on_the_simulator_is_refused_for_a_protocol_on_real_servos(
        tmp_path, capsys):
    protocol, text = _with_response(tmp_path, [(1, 114, 114), (20, 114, 114)])
    (tmp_path / "r.yaml").write_text((tmp_path / "r.yaml").read_text().replace(
        'port: "sim://"', 'port: "sim://?speed=1500"'))
    protocol.write_text(text.replace('port: "sim://"', 'port: "/dev/ttyUSB0"'))
    status, out, err = run(capsys, "validate", protocol)
    assert (status, out) == (2, "")
    assert ("expected a response measured on the servos of /dev/ttyUSB0, found one measured on "
            "the simulator (sim://?speed=1500, r.yaml)") in err


def test_two_points_for_one_frequency_and_stroke_are_refused_at_the_second(tmp_path, capsys):
    protocol, _ = _with_response(tmp_path, [(5, 16, 16), (5, 32, 32), (5, 16, 4)])
    status, out, err = run(capsys, "validate", protocol)
    assert (status, out) == (2, "")
    assert err.startswith(f"{tmp_path / 'r.yaml'}:11:5: expected one point per frequency and "
                          "stroke, found a second at 5 Hz and 16 steps")


def test_a_response_file_that_is_not_text_is_refused_where_it_is_not(tmp_path, capsys):
    protocol, _ = _with_response(tmp_path, [(5, 16, 16)])
    (tmp_path / "r.yaml").write_bytes(b"pin: 4\nservo: \x00STS3215\n")
    status, out, err = run(capsys, "validate", protocol)
    assert (status, out) == (2, "") and err.count("\n") == 1
    assert err.startswith(f"{tmp_path / 'r.yaml'}:2:")
    assert err.count("expected") == 1


def test_a_measured_frequency_of_a_third_of_a_hertz_is_read_back_as_it_was():
    third = measured([(1 / 3, 100, 100), (10, 100, 60)])
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "r.yaml"
        path.write_text(response_text(third, "now"))
        reader = Reader("p.yaml")
        again = read_response(path, reader, reader.compose("response: r.yaml\n"))
    assert again.points == third.points


def test_a_train_of_another_duty_cycle_is_judged_by_its_shorter_half_cycle(tmp_path):
    (tmp_path / "r.yaml").write_text(RESPONSE)
    (tmp_path / "p.yaml").write_text(SHORT_HORN.replace("frequencies_hz: [3, 5, 10]",
                                                        "frequencies_hz: [3, 5]").replace(
        "  port: \"sim://\"\n", "  port: \"sim://\"\n  response: r.yaml\n"))
    device = load_protocol(tmp_path / "p.yaml").device
    # 5 Hz at a duty cycle of 1/4: its shorter half-cycle is 50 ms, as 10 Hz's at 1/2.
    quarter = Train(Fraction(5), 10**9, pulses_per_cycle=4, up_pulses=1)
    result = check_train(quarter, device.calibration(4), device)
    assert result.reachable_steps == 80 and not result.feasible
    assert result.needed_steps == math.ceil(114 * Fraction(8, 10))


def test_the_datasheet_lets_a_10_hz_train_of_114_steps_pass_but_validate_plays_it_and_refuses(
        tmp_path, capsys):
    # The datasheet's figures (speed, acceleration unlimited) reach 114 steps in 50 ms; a
    # servo that accelerates and has backlash, as the simulated one does, falls short, and
    # `pinarray batch` would fail the trial: validate says so where the 10 Hz is written.
    (tmp_path / "p.yaml").write_text(SHORT_HORN)
    device = load_protocol(tmp_path / "p.yaml").device
    assert check_train(Train(Fraction(10), 10**9), device.calibration(1), device).feasible
    status, out, err = run(capsys, "validate", tmp_path / "p.yaml")
    line = SHORT_HORN.splitlines().index("  frequencies_hz: [3, 5, 10]") + 1
    assert (status, out) == (2, "")
    assert err.startswith(f"{tmp_path / 'p.yaml'}:{line}:26: played as a run plays it, on "
                          "simulated STS3215 servos (1000000 baud, 3000 steps/s, return delay "
                          "500 us), it was not delivered in 3 attempts: pin 1 moved ")
    assert "of 114 commanded steps" in err and err.count("\n") == 1
    # Without it, it passes, and says which basis the closed-form check used.
    (tmp_path / "p.yaml").write_text(SHORT_HORN.replace("[3, 5, 10]", "[3, 5]"))
    status, out, err = run(capsys, "validate", tmp_path / "p.yaml")
    assert status == 0, err
    assert f"{tmp_path / 'p.yaml'}: feasibility: datasheet figures (3000 steps/s, acceleration " \
           "unlimited)\n" in out


def test_a_measured_response_named_by_the_protocol_refuses_the_train_the_servo_did_not_follow(
        tmp_path, capsys):
    (tmp_path / "r.yaml").write_text(RESPONSE)
    text = SHORT_HORN.replace("  port: \"sim://\"\n", "  port: \"sim://\"\n  response: r.yaml\n")
    (tmp_path / "p.yaml").write_text(text)
    status, out, err = run(capsys, "validate", tmp_path / "p.yaml")
    assert (status, out) == (2, "")
    line = text.splitlines().index("  frequencies_hz: [3, 5, 10]") + 1
    assert err.startswith(f"{tmp_path / 'p.yaml'}:{line}:")
    assert "pin 1 cannot follow 10 Hz (measured response of pin 4 (r.yaml))" in err
    assert "only 80 steps" in err and "needs, to move 92 of them (the stroke tolerance), at most 7.39 Hz" in err
    # Without the 10 Hz condition it passes, and says which basis it used.
    (tmp_path / "p.yaml").write_text(text.replace("[3, 5, 10]", "[3, 5]"))
    status, out, err = run(capsys, "validate", tmp_path / "p.yaml")
    assert status == 0, err
    assert "feasibility: measured response of pin 4 (r.yaml)" in out


@pytest.mark.parametrize(("change", "where", "expected"), [
    (("stroke_achieved_steps: 80", "stroke_achieved_steps: lots"), 10,
     "expected a whole number for a stroke (steps), found"),
    (("duty_cycle: 1/2\n", ""), 1, "expected a 'duty_cycle' key in the servo response, found none"),
    (("points:", "ponts:"), 8,
     "expected a key of the servo response, found 'ponts'; did you mean 'points'?"),
    (("pin: 4", "pin: 99"), 1, "expected a pin from 1 to 16 (the protocol's grid), found 99"),
    (("stroke_achieved_steps: 80", "stroke_achieved_steps: 800"), 10,
     "expected a stroke achieved of at most 125 steps (114 commanded, and a tenth of it for an "
     "overshoot), found 800"),
    (("", ""), 1, "expected a servo response (`pinarray servos response` writes one), found an "
     "empty file"),
])
def test_a_broken_response_file_is_refused_with_its_own_line_and_column(tmp_path, capsys, change,
                                                                        where, expected):
    (tmp_path / "r.yaml").write_text(RESPONSE.replace(*change) if change[0] else "")
    (tmp_path / "p.yaml").write_text(SHORT_HORN.replace("  port: \"sim://\"\n",
                                                        "  port: \"sim://\"\n  response: r.yaml\n"))
    status, out, err = run(capsys, "validate", tmp_path / "p.yaml")
    assert (status, out) == (2, "")
    located = f"{tmp_path / 'r.yaml'}:{where}:" if where else f"{tmp_path / 'r.yaml'}: "
    assert located in err and expected in err
    assert "Traceback" not in err


@pytest.mark.parametrize(("response", "expected"), [
    (None, "no such servo response file ("),
    (RESPONSE.replace("speed_steps_per_s: 3000", "speed_steps_per_s: 1500"),
     "expected a response measured at the protocol's speed 3000 steps/s and acceleration 0, "
     "found one at 1500 steps/s and acceleration 0 (r.yaml): measure it again"),
    (RESPONSE.replace("servo: STS3215", "servo: STS3250"),
     "expected a response measured on STS3215 servos, found one of STS3250 (r.yaml)"),
])
def test_a_response_that_is_missing_or_was_measured_otherwise_is_refused_where_the_protocol_names_it(
        tmp_path, capsys, response, expected):
    if response is not None:
        (tmp_path / "r.yaml").write_text(response)
    text = SHORT_HORN.replace("  port: \"sim://\"\n", "  port: \"sim://\"\n  response: r.yaml\n")
    (tmp_path / "p.yaml").write_text(text)
    status, out, err = run(capsys, "validate", tmp_path / "p.yaml")
    line = text.splitlines().index("  response: r.yaml") + 1
    assert (status, out) == (2, "")
    assert err.startswith(f"{tmp_path / 'p.yaml'}:{line}:13: {expected}")


def test_servos_response_measures_the_simulated_servo_and_feasibility_then_follows_it(
        tmp_path, capsys):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(SHORT_HORN.replace("frequencies_hz: [3, 5, 10]", "frequencies_hz: [3, 5]"))
    status, out, err = run(capsys, "servos", "response", protocol, "--pin", 4, "--sim",
                           "--frequencies", "3,10", "--strokes", "57,114", "--cycles", 4)
    assert status == 0, err
    written = tmp_path / "p_response_pin4.yaml"
    assert f"wrote {written} and {written.with_suffix('.png')}, {written.with_suffix('.pdf')}" in out
    assert "to follow it: device: response: p_response_pin4.yaml" in out
    rows = [r for r in map(str.split, out.splitlines()) if len(r) == 7 and r[1].isdigit()]
    table = {(float(r[0]), int(r[1])): (int(r[2]), r[5]) for r in rows}
    assert set(table) == {(3.0, 57), (3.0, 114), (10.0, 57), (10.0, 114)}
    assert table[(3.0, 114)][0] == 114 and table[(10.0, 57)][0] == 57  # in time: in full
    # At 10 Hz the simulated servo turns back before it arrives: the datasheet says it would not.
    assert table[(10.0, 114)][0] < 0.8 * 114
    # Named in the protocol, the measurement refuses 10 Hz before anything plays.
    protocol.write_text(SHORT_HORN.replace("  port: \"sim://\"\n",
                                           "  port: \"sim://\"\n  response: p_response_pin4.yaml\n"))
    status, out, err = run(capsys, "validate", protocol)
    assert status == 2 and "cannot follow 10 Hz (measured response of pin 4" in err


def test_servos_response_refuses_strokes_past_the_pins_limits_before_anything_moves(tmp_path,
                                                                                   capsys):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(SEED.read_text())
    status, out, err = run(capsys, "servos", "response", protocol, "--pin", 4, "--sim",
                           "--strokes", "500")
    assert status == 2 and err.count("\n") == 1
    assert ("pin 4: expected a stroke within its calibrated limits 2000..2200, found 500 steps, "
            "which lifts it to 2548") in err
    assert not (tmp_path / "p_response_pin4.yaml").exists()


@pytest.mark.parametrize(("option", "value"), [("--frequencies", "3,fast"), ("--strokes", "0"),
                                               ("--frequencies", "2000")])
def test_servos_response_refuses_a_bad_list_on_one_line(tmp_path, capsys, option, value):
    status, out, err = run(capsys, "servos", "response", SEED, "--pin", 4, "--sim", option, value)
    assert status == 2 and err.count("\n") == 1 and err.startswith(f"pinarray: {option}: expected")


@pytest.mark.parametrize("value", ["1e-400", "1e-99999999999", "１０", "1_0", "3,5,3"])
def test_servos_response_refuses_frequencies_written_past_a_protocols_rules_on_one_line(
        capsys, value):
    status, out, err = run(capsys, "servos", "response", SEED, "--pin", 4, "--sim",
                           "--frequencies", value)
    assert (status, out) == (2, "")
    assert err.count("\n") == 1 and err.startswith("pinarray: --frequencies: ")


@pytest.mark.parametrize(("options", "lowest"), [
    (["--frequencies", "0.001"], "0.001 Hz"),
    (["--frequencies", "0.1,5", "--cycles", "1000"], "0.1 Hz"),
])
def test_servos_response_refuses_trains_that_would_play_for_hours_with_the_estimate_and_what_to_change(
        tmp_path, capsys, options, lowest):
    status, out, err = run(capsys, "servos", "response", SEED, "--pin", 4, "--sim", *options)
    assert (status, out) == (2, "")
    assert err.count("\n") == 1 and "would play for about" in err and lowest in err
    assert "at most 1 h: raise the lowest --frequencies, or play fewer --cycles or --strokes" in err


@pytest.mark.parametrize("taken", ["r.yaml", "r.png", "r.pdf"])
def test_servos_response_refuses_an_output_it_could_not_write_before_measuring(
        tmp_path, capsys, taken):
    (tmp_path / taken).mkdir()
    status, out, err = run(capsys, "servos", "response", SEED, "--pin", 4, "--sim",
                           "--frequencies", "5", "--strokes", "65", "--out", tmp_path / "r.yaml")
    assert (status, out) == (2, "")  # nothing played: no table
    assert err == f"pinarray: {tmp_path / taken}: cannot write: it is a folder, expected a file name\n"


def test_servos_response_says_hobby_pwm_servos_report_no_position_and_moves_nothing(capsys):
    pwm = SEED.with_name("localisation_pwm.yaml")
    status, out, err = run(capsys, "servos", "response", pwm, "--pin", 1, "--sim")
    assert (status, out) == (2, "")
    assert err == ("pinarray: servos response: hobby servos on a PWM board do not report their "
                   "position; it measures bus servos\n")


def test_servos_response_refuses_an_out_file_the_figure_would_overwrite(tmp_path, capsys):
    status, out, err = run(capsys, "servos", "response", SEED, "--pin", 4, "--sim",
                           "--out", tmp_path / "r.png")
    assert (status, out) == (2, "")
    assert err == f"pinarray: --out: expected a response file ending in .yaml, found {tmp_path / 'r.png'}\n"
    assert list(tmp_path.iterdir()) == []


def test_a_rig_other_than_the_one_measured_is_warned_of(tmp_path):
    from pinarray.clock import VirtualClock
    from pinarray.player.rig import Rig

    protocol, _ = _with_response(tmp_path, [(1, 114, 114), (20, 114, 114)])
    (tmp_path / "r.yaml").write_text((tmp_path / "r.yaml").read_text().replace(
        'port: "sim://"', 'port: "/dev/ttyUSB0"'))
    rig = Rig(load_protocol(protocol), None, "sim://", VirtualClock())
    try:
        assert ("feasibility follows the measured response of pin 4 (r.yaml), measured on "
                "/dev/ttyUSB0, not on the simulator (sim://") in "\n".join(rig.warnings)
    finally:
        rig.close()
