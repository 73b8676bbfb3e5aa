"""Faults of a PCA9685 board mid-trial, on the simulated board (``sim://pca9685?...``): each is
healed or named, and the pins still end at rest, then without pulses."""

from pathlib import Path

import pytest

from pinarray.clock import VirtualClock
from pinarray.hardware.pca9685.registers import FULL_BIT, MODE1, SLEEP, led_register
from pinarray.plan import make_plan
from pinarray.player.rig import Rig
from pinarray.protocol.load import parse_protocol
from pinarray.schedule import compile_trial

from .lab import assert_rest_held_for_the_travel_time

PROTOCOL = Path(__file__).parents[2] / "protocols" / "localisation_pwm.yaml"
SIM = "sim://pca9685?osc_hz=25300000"


def short_protocol(duration_s: str = "0.5"):
    """The seed's PWM protocol with trains of ``duration_s`` seconds."""
    text = PROTOCOL.read_text().replace("duration_s: 10", f"duration_s: {duration_s}")
    return parse_protocol(text, "short.yaml")


def ten_hz_schedule(protocol):
    planned = next(t for t in make_plan(protocol, 0).trials if t.condition.frequency_hz == 10)
    return compile_trial(protocol, planned)


def frame_writes(tmp_path):
    """Message numbers (1 = the bus's first) of the frames' writes in a clean run of the 10 Hz
    trial, read from its ``--i2c-log`` (one line per message, in the order they were carried)."""
    protocol = short_protocol()
    log = tmp_path / "clean.txt"
    with Rig(protocol, None, SIM, VirtualClock(), wire_log=str(log)) as rig:
        rig.present(ten_hz_schedule(protocol))
    first_led, last_led = led_register(0), led_register(15) + 3
    numbers = []
    for number, line in enumerate(log.read_text().splitlines(), start=1):
        t_ns, _address, rw, data, _ack = line.split()
        if rw == "w" and int(t_ns) > 0 and len(data) > 2 and first_led <= int(data[:2], 16) <= last_led:
            numbers.append(number)
    return numbers


def assert_rest_then_full_off(board, protocol, from_ns, to_ns):
    """The board's last word: every channel full off, after rest widths the servos followed."""
    regs = board._regs
    assert not regs[MODE1] & SLEEP
    for channel in range(16):
        assert regs[led_register(channel) + 3] & FULL_BIT, f"channel {channel} not full off"
    rest_ns = protocol.device.calibration(1).rest_steps * 1000
    last = [board.pulses(ch, from_ns, to_ns)[-1] for ch in range(16)]
    assert all(abs(width - rest_ns) < 3_000 for _, width in last)


def test_a_frame_write_the_board_does_not_acknowledge_is_written_again_in_its_period(tmp_path):
    numbers = frame_writes(tmp_path)
    protocol = short_protocol()
    clock = VirtualClock()
    with Rig(protocol, None, SIM + f"&nack_at={numbers[3]}", clock) as rig:
        presentation = rig.present(ten_hz_schedule(protocol))
        report = rig.reports[-1]
    assert presentation.delivery.delivered, presentation.delivery.problem
    assert presentation.delivery.healed >= 1 and report.retries >= 1


def test_a_board_that_lost_power_mid_trial_is_found_the_trial_not_delivered_and_pins_made_safe(
        tmp_path):
    numbers = frame_writes(tmp_path)
    protocol = short_protocol()
    clock = VirtualClock()
    rig = Rig(protocol, None, SIM + f"&power_loss_at={numbers[3]}", clock)
    started = clock.now_ns()
    presentation = rig.present(ten_hz_schedule(protocol))
    board = rig.bus.link.board(0x40)
    assert not presentation.delivery.delivered
    problem = presentation.delivery.problem
    assert "0x40" in problem and "lost power" in problem, problem
    safe = rig.close()
    assert safe.complete
    assert_rest_then_full_off(board, protocol, started, clock.now_ns())


def test_an_adapter_lost_mid_trial_ends_play_with_one_line_naming_the_port_and_status_2(
        capsys, tmp_path):
    from pinarray.cli import main

    numbers = frame_writes(tmp_path)
    protocol_file = tmp_path / "short.yaml"
    protocol_file.write_text(PROTOCOL.read_text().replace("duration_s: 10", "duration_s: 0.5"))
    plan = make_plan(short_protocol(), 0)
    number = next(t.trial for t in plan.trials if t.condition.frequency_hz == 10)
    url = SIM + f"&vanish_after={numbers[3]}"
    status = main(["play", str(protocol_file), "--sim", url, "--seed", "0",
                   "--trial", str(number)])
    err = capsys.readouterr().err
    assert status == 2, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("pinarray: ")
             and "pins after the stop" not in line]
    assert len(lines) == 1 and "vanished" in lines[0] and "sim://pca9685" in lines[0], err


@pytest.mark.parametrize("quarter", [0, 1, 2, 3])
def test_the_safe_stop_holds_rest_widths_for_the_travel_time_from_the_first_rest_pulse(quarter):
    # Wherever in a board period the stop comes: the rest widths take effect only at the next
    # period boundary, and the servos must get them for their whole travel time from there.
    protocol = short_protocol()
    clock = VirtualClock()
    rig = Rig(protocol, None, SIM, clock)
    rig.present(ten_hz_schedule(protocol))
    board = rig.bus.link.board(0x40)
    rig.bus.send_goals(rig.bus.goal_packet({0: 2100}), {0: 2100})  # pin 1 up, as mid-trial
    clock.sleep_until_ns(clock.now_ns() + 5 * round(board.period_ns()))
    clock.sleep_until_ns(clock.now_ns() + round(board.period_ns() * quarter / 4))
    assert rig.close().complete
    assert_rest_held_for_the_travel_time(board, protocol, clock.now_ns())
