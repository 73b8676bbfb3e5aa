"""Calibrating a hobby servo's pin on a PCA9685 board: jog its pulse width, write rest and up.

The simulated board (datasheet-faithful, `board_sim`) says what each channel carried while a
person jogged.
"""

import io
import math
import sys
from pathlib import Path

import pytest

from pinarray.cli import main
from pinarray.clock import VirtualClock
from pinarray.hardware.driver import GoalOutOfRange
from pinarray.hardware.pca9685.jog import JOG_SPEED_US_PER_S, PwmJog
from pinarray.player.families import open_board
from pinarray.protocol.load import load_protocol
from tests.prompts import interrupted_at_prompt

PROTOCOL = Path(__file__).parents[2] / "protocols" / "localisation_pwm.yaml"
BUS_SERVOS = Path(__file__).parents[2] / "protocols" / "localisation.yaml"


@pytest.fixture
def protocol(tmp_path):
    copy = tmp_path / "localisation_pwm.yaml"
    copy.write_bytes(PROTOCOL.read_bytes())
    return copy


def run(capsys, monkeypatch, *argv, stdin=""):
    monkeypatch.setattr(sys, "stdin", io.StringIO(stdin))
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_calibrating_a_pwm_pin_writes_rest_us_and_up_into_the_protocol_keeping_its_comments(
        capsys, monkeypatch, protocol):
    before = protocol.read_text()
    status, out, err = run(capsys, monkeypatch, "pwm", "calibrate", str(protocol), "--pin", "6",
                           "--sim", stdin="+50\n\n=1600\nok\n+400\nok\n")
    assert (status, err) == (0, "")
    assert "rest>   1550 us" in out and "up>   2000 us" in out
    assert "pin 6 (channel 5): at rest (1600 us), then no pulses" in out
    assert out.splitlines()[-1].startswith(
        f"{protocol}: device: pins: 6: rest_us 1600, positions {{1.5 ms: 1600, 2 ms: 2000}}; "
        "stroke 400 us (36.0 deg")
    assert protocol.read_text() == before.replace(
        "  delivery_tolerance_ms: 40\n",
        "  delivery_tolerance_ms: 40\n"
        "  pins:\n    6: {rest_us: 1600, positions: {1.5: 1600, 2.0: 2000}}\n")
    calibration = load_protocol(protocol).device.calibration(6)
    assert calibration.rest_steps == 1600 and calibration.positions_by_width_ns[-1][1] == 2000
    assert load_protocol(protocol).device.calibration(7) == \
        load_protocol(PROTOCOL).device.calibration(7)


def test_a_width_the_limits_do_not_hold_widens_limits_us_in_the_pins_entry(
        capsys, monkeypatch, protocol):
    status, out, _ = run(capsys, monkeypatch, "pwm", "calibrate", str(protocol), "--pin", "6",
                         "--sim", stdin="=1300\nok\n=2200\nok\n")
    assert status == 0, out
    assert "limits_us: [1300, 2200]" in protocol.read_text()
    assert "limits_us [1300, 2200] (widened)" in out


@pytest.mark.parametrize("typed, status, said", [
    ("+\nq\n", 0, "nothing written"),
    ("+\nok\n", 2, "input ended before the up position was chosen; nothing written"),
    ("=3000\n=2600\nq\n", 0, "a 3000 us pulse is outside the jog's range 500..2500 us"),
])
def test_a_pwm_calibration_not_finished_leaves_the_file_as_it_was_and_the_pin_at_rest(
        capsys, monkeypatch, protocol, typed, status, said):
    before = protocol.read_bytes()
    got, out, err = run(capsys, monkeypatch, "pwm", "calibrate", str(protocol), "--pin", "6",
                        "--sim", stdin=typed)
    assert got == status and said in out + err
    assert "pin 6 (channel 5): at rest (1500 us), then no pulses" in out
    assert protocol.read_bytes() == before


def test_each_family_calibrates_with_its_own_command_and_says_which(capsys, monkeypatch,
                                                                    protocol):
    status, _, err = run(capsys, monkeypatch, "servos", "calibrate", str(protocol), "--pin", "6",
                         "--sim")
    assert status == 2 and "use `pinarray pwm ...`" in err and len(err.splitlines()) == 1
    status, _, err = run(capsys, monkeypatch, "pwm", "calibrate", str(BUS_SERVOS), "--pin", "6",
                         "--sim")
    assert status == 2 and "use `pinarray servos calibrate`" in err
    status, _, err = run(capsys, monkeypatch, "pwm", "calibrate", str(protocol), "--pin", "6")
    assert status == 2 and "--port PATH" in err and "--sim" in err


def _jog(clock):
    device = load_protocol(PROTOCOL).device
    array = open_board(device, None, None, clock)
    return array, PwmJog(array, 6, clock)


def test_a_jog_ramps_the_width_period_by_period_on_the_pins_channel_alone_then_stops_pulses():
    clock = VirtualClock()
    array, jog = _jog(clock)
    board = array.link.board(0x40)
    started = clock.now_ns()
    assert jog.start().held
    reading = jog.move_to(2100)
    assert reading == type(reading)(2100, True)
    jogged = clock.now_ns()
    jog.release(1500)  # to rest at once: down, away from the finger
    ended = clock.now_ns()
    widths_us = [width / 1000 for _, width in board.pulses(5, started, jogged)]
    period_s = 1 / 50
    tick_us = 1e6 * period_s / 4096 * 1.02  # the prescale rounds the 50 Hz; osc 25.3 MHz
    assert widths_us[0] == pytest.approx(1500, abs=tick_us)
    assert max(widths_us) == pytest.approx(2100, abs=tick_us)
    steps = [abs(b - a) for a, b in zip(widths_us, widths_us[1:], strict=False)]
    assert max(steps) <= JOG_SPEED_US_PER_S * period_s * 1.05 + tick_us  # never a jump
    rested = [width / 1000 for _, width in board.pulses(5, jogged, ended)]
    assert rested[-1] == pytest.approx(1500, abs=tick_us)  # rest, held, then nothing
    assert len(rested) * period_s >= 0.1  # held for its travel time at least
    assert not board.pulses(5, ended, ended + 10**9)
    assert all(not board.pulses(ch, started, ended) for ch in range(16) if ch != 5)


def test_a_jog_goal_outside_the_hobby_range_is_refused_before_anything_is_sent():
    clock = VirtualClock()
    array, jog = _jog(clock)
    jog.start()
    sent = array.counters.frames
    with pytest.raises(GoalOutOfRange, match="pin 6 .channel 5.: a 400 us pulse is outside"):
        jog.move_to(400)
    assert array.counters.frames == sent and jog.goal_us == 1500


def test_ctrl_c_at_the_pwm_jog_prompt_rests_the_pin_stops_pulses_and_writes_nothing(protocol):
    before = protocol.read_bytes()
    status, out, err = interrupted_at_prompt(
        ["pwm", "calibrate", str(protocol), "--pin", "6", "--sim"], b"rest> ")
    assert status == 130, err
    assert b"pin 6 (channel 5): at rest (1500 us), then no pulses" in out
    assert err.decode().strip().splitlines() == ["pinarray: calibration stopped by SIGINT"]
    assert protocol.read_bytes() == before


def test_ok_is_refused_while_the_board_does_not_hold_the_width_and_a_board_that_lost_power_restarts(
        capsys, monkeypatch, protocol):
    # power lost while the jog starts: the board is back to its reset state, no pulses
    status, out, _ = run(capsys, monkeypatch, "pwm", "calibrate", str(protocol), "--pin", "6",
                         "--sim", "sim://pca9685?power_loss_at=12",
                         stdin="ok\n=1600\nok\n+300\nok\n")
    assert status == 0
    assert "(the board does NOT hold it: check its power)" in out.splitlines()[1]
    assert "rest>   the board does not hold 1500 us: check its power" in out
    assert "rest>   1600 us\n" in out  # started again, then ramped: held
    assert "6: {rest_us: 1600, positions: {1.5: 1600, 2.0: 1900}}" in protocol.read_text()


def test_the_jog_never_asks_for_a_pulse_longer_than_the_boards_period(capsys, monkeypatch,
                                                                     tmp_path):
    fast = tmp_path / "fast.yaml"  # 400 Hz: a 2.43 ms period holds the seed's widths
    fast.write_text(PROTOCOL.read_text().replace("    osc_hz: 25300000\n",
                                                 "    osc_hz: 25300000\n    pwm_hz: 400\n"))
    status, out, err = run(capsys, monkeypatch, "pwm", "calibrate", str(fast), "--pin", "6",
                           "--sim", stdin="=2500\nq\n")
    assert (status, err) == (0, "")
    prescale = round(25_300_000 / (4096 * 400)) - 1  # the datasheet's formula: 14
    period_us = 4096 * (prescale + 1) / 25_300_000 * 1e6  # 2428.5 us
    widest = math.ceil(period_us * 4095 / 4096) - 1  # one count short of full on
    assert f"the jog allows 500..{widest} us" in out
    assert f"a 2500 us pulse is outside the jog's range 500..{widest} us" in out


def test_a_board_rate_too_fast_for_the_pins_widths_is_refused_by_validate(capsys, tmp_path):
    fast = tmp_path / "fast.yaml"
    fast.write_text(PROTOCOL.read_text().replace("    osc_hz: 25300000\n",
                                                 "    osc_hz: 25300000\n    pwm_hz: 1000\n"))
    assert main(["validate", str(fast)]) == 2
    err = capsys.readouterr().err
    assert err == (f"{fast}: device: board: pwm_hz 1000 gives a period of 0.971 ms, too short "
                   "for the widths of pins 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, "
                   "16 (their rest or limits_us); lower pwm_hz\n")
