"""The seed's own rig: hobby servos on a PCA9685 board play the localisation train as pulses.

Each pulse of the schedule is one period of the board, counted from the trial's onset; the
simulated board (datasheet-faithful, `board_sim`) says what its pins really carried.
"""

from fractions import Fraction
from pathlib import Path

import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.pca9685.registers import COUNTS, period_ns
from pinarray.plan import make_plan
from pinarray.player.rig import Rig
from pinarray.protocol.load import load_protocol, parse_protocol
from pinarray.schedule import compile_trial

PROTOCOL = Path(__file__).parents[2] / "protocols" / "localisation_pwm.yaml"


def _trial(protocol, frequency_hz):
    plan = make_plan(protocol, 0)
    return next(t for t in plan.trials if t.condition.frequency_hz == frequency_hz)


def _board_pulses(rig, pin, onset_ns, end_ns):
    channel = protocol_channel(rig, pin)
    board = rig.bus.link.board(rig.bus.setup.address)
    return board.pulses(channel, onset_ns, onset_ns + end_ns)


def protocol_channel(rig, pin):
    return next(s.servo_id for s in rig.setup.servos if s.pin == pin)


@pytest.mark.parametrize("frequency_hz", [3, 5, 10])
def test_every_pulse_of_the_train_leaves_the_board_in_its_own_period_at_its_width(frequency_hz):
    protocol = load_protocol(PROTOCOL)
    planned = _trial(protocol, frequency_hz)
    schedule = compile_trial(protocol, planned)
    with Rig(protocol, None, "sim://pca9685?osc_hz=25300000", VirtualClock()) as rig:
        presentation = rig.present(schedule)
        pin = planned.condition.pin
        # the board's periods are 0.4 % long: its last pulses of the train leave after end_ns
        carried = _board_pulses(rig, pin, presentation.onset_ns, schedule.end_ns * 101 // 100)
        trial = rig.reports[-1]
    assert presentation.delivery.delivered, presentation.delivery.problem
    mine = schedule.pulses.pin == pin
    scheduled_widths = schedule.pulses.width_ns[mine]
    assert len(carried) >= len(scheduled_widths)
    rate = Fraction(frequency_hz * 10)
    prescale = round(Fraction(25_300_000) / (COUNTS * rate)) - 1
    period = period_ns(25_300_000, prescale)
    tick = period / COUNTS
    calibration = protocol.device.calibration(pin)
    for k, ((start, width), nominal) in enumerate(zip(carried, scheduled_widths, strict=False)):
        # in its own period of the board, counted from onset
        assert k * period - 1 < start - presentation.onset_ns < (k + 1) * period  # floored ns
        wanted_ns = calibration.position_for_width(int(nominal)) * 1000
        assert abs(width - wanted_ns) <= tick / 2 + 1, (k, width, wanted_ns)
    assert trial.delivery.confirmed == trial.delivery.scheduled


def test_a_board_whose_period_drifts_past_the_tolerance_is_refused_up_front_with_what_to_change(
        tmp_path, capsys):
    from pinarray.cli import main

    text = PROTOCOL.read_text().replace("delivery_tolerance_ms: 40", "delivery_tolerance_ms: 10")
    strict = tmp_path / "strict.yaml"
    strict.write_text(text)
    # before the port is opened: one that vanishes at its first message would say so instead
    with pytest.raises(PinArrayError, match=r"strict.yaml: seed_train at 5 Hz on pins 1, 4, 6, 7, "
                       r"10, 11, 13, 16: .*37\.6 ms from the schedule.*at most 2\.6 s fit.*"
                       r"and 1 more stimulus: `pinarray validate` lists them"):
        Rig(parse_protocol(text, str(strict)), None, "sim://pca9685?vanish_after=0",
            VirtualClock())
    assert main(["validate", str(strict)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert [line.split(": refusing to play: ")[0] for line in err.splitlines()] == [
        f"{strict}: seed_train at {hz} Hz on pins 1, 4, 6, 7, 10, 11, 13, 16" for hz in (5, 10)]
    assert main(["validate", str(PROTOCOL)]) == 0  # 40 ms holds the seed's 10 s trains


def test_idle_pins_hold_rest_and_after_the_stop_no_channel_carries_pulses():
    protocol = load_protocol(PROTOCOL)
    planned = _trial(protocol, 10)
    schedule = compile_trial(protocol, planned)
    clock = VirtualClock()
    rig = Rig(protocol, None, None, clock)
    presentation = rig.present(schedule)
    idle = next(p for p in range(1, 17) if p != planned.condition.pin)
    held = _board_pulses(rig, idle, presentation.onset_ns, schedule.end_ns)
    widths = {w for _, w in held}
    assert len(held) >= 996 and all(abs(w - 1_500_000) < 3_000 for w in widths)
    board = rig.bus.link.board(rig.bus.setup.address)
    safe = rig.close()
    assert safe.complete
    after = clock.now_ns()
    assert all(board.pulses(ch, after, after + 1_000_000_000) == [] for ch in range(16))


def test_a_scan_lists_each_board_on_the_bus_asleep_as_it_powers_up_and_leaves_all_call_alone(
        capsys):
    from pinarray.cli import main

    assert main(["pwm", "scan", "--sim", "sim://pca9685?address=0x40,0x7f"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("SIMULATED")
    assert [line[:4] for line in lines[1:3]] == ["0x40", "0x7f"]
    assert "asleep" in lines[1] and "prescale 30" in lines[1]
    assert lines[-1].startswith("2 board(s) answer")


def test_a_scan_of_a_bus_without_boards_says_what_to_check_and_exits_2_as_servos_scan_does(
        capsys):
    from pinarray.cli import main

    assert main(["pwm", "scan", "--sim", "sim://pca9685?nack=1"]) == 2  # nobody acknowledges
    assert "check power, SDA/SCL" in capsys.readouterr().out
    assert main(["pwm", "scan", "--port", "/nonexistent/i2c-9"]) == 2
    assert "i2c-9" in capsys.readouterr().err


def _decode_log(lines, channel):
    """From a logic analyser's view alone: the prescale and the RESTART that start the trial's
    counter, and the width (counts) the channel's registers hold for each period after it.

    The board's registers are kept as the writes leave them (auto-increment from the first
    byte's register), so a write of only a channel's OFF counts keeps the ON count before it.
    """
    prescale, restart_ns, width, changes = None, None, None, []
    registers = bytearray(256)
    first = 0x06 + 4 * channel
    for line in lines:
        t_ns, address, rw, data, ack = line.split()
        raw = bytes.fromhex(data)
        if rw != "w" or ack != "ack" or address != "0x40" or not raw:
            continue
        t = int(t_ns)
        register, values = raw[0], raw[1:]
        registers[register:register + len(values)] = values
        if register == 0xFE and values and t < 0:
            prescale = values[0]
        elif register == 0x00 and values and values[0] & 0x80 and t <= 1_000_000:
            restart_ns = t  # the counter's period 0 begins here
        if 0x06 <= register < first + 4 and register + len(values) > first:
            on_l, on_h, off_l, off_h = registers[first:first + 4]
            counts = ((off_h & 0x0F) << 8 | off_l) - ((on_h & 0x0F) << 8 | on_l)
            if restart_ns is None:
                width = counts % 4096  # in place before the counter starts
            else:
                changes.append((t, counts % 4096))
    return prescale, restart_ns, width, changes


def test_the_i2c_log_shows_each_pulse_of_the_schedule_on_its_channel_to_the_count_and_period(
        tmp_path, capsys):
    from pinarray.cli import main

    log = tmp_path / "log.txt"
    protocol = load_protocol(PROTOCOL)
    plan = make_plan(protocol, 7)
    number = next(t.trial for t in plan.trials if t.condition.frequency_hz == 10)
    assert main(["play", str(PROTOCOL), "--sim", "sim://pca9685?osc_hz=25300000",
                 "--seed", "7", "--trial", str(number), "--i2c-log", str(log)]) == 0
    planned = plan.trial(number)
    pin = planned.condition.pin
    schedule = compile_trial(protocol, planned)
    prescale, restart_ns, width, changes = _decode_log(log.read_text().splitlines(), pin - 1)
    assert prescale == 61 and abs(restart_ns) < 1_000_000
    period = Fraction(4096 * (prescale + 1) * 10**9, 25_300_000)
    tick = period / 4096
    mine = schedule.pulses.pin == pin
    for k, nominal in enumerate(schedule.pulses.width_ns[mine].tolist()):
        begins = restart_ns + k * period
        while changes and changes[0][0] < begins:  # written in an earlier period: latched
            width = changes.pop(0)[1]
        wanted_us = protocol.device.calibration(pin).position_for_width(nominal)
        assert abs(width * tick - wanted_us * 1000) <= tick / 2, (k, width, wanted_us)


def test_a_one_pin_train_changes_only_the_off_count_each_period_four_bytes_on_the_wire():
    """The bus's minimum for a new width: address, register pointer, OFF_L, OFF_H. The ON
    count (the pin's phase) goes to the board with the first registers and holds."""
    protocol = load_protocol(PROTOCOL)
    schedule = compile_trial(protocol, _trial(protocol, 10))
    with Rig(protocol, None, "sim://pca9685?osc_hz=25300000", VirtualClock()) as rig:
        trial = rig.bus.prepare(schedule.targets, schedule.pulses)
        channel = protocol_channel(rig, _trial(protocol, 10).condition.pin)
    assert trial.frames and {frame.packet[0] for frame in trial.frames} == {0x06 + 4 * channel + 2}
    assert {1 + len(frame.packet) for frame in trial.frames} == {4}  # with the address byte


def test_play_on_the_simulated_board_says_how_far_each_simulated_servo_swung(capsys):
    from pinarray.cli import main

    protocol = load_protocol(PROTOCOL)
    planned = _trial(protocol, 10)
    assert main(["play", str(PROTOCOL), "--sim", "--seed", "0", "--trial", str(planned.trial),
                 "--time-scale", "0"]) == 0  # virtual time: the swing is the servo model's
    out = capsys.readouterr().out
    # 20000 us/s: 500 us in 25 ms, inside the 50 ms of five pulses up
    assert (f"simulated hobby servos (20000 us/s): swung pin {planned.condition.pin} 500 of "
            "500 us\n") in out


def test_a_simulated_hobby_servo_too_slow_for_the_train_swings_short():
    from pinarray.hardware.pca9685.servo_sim import HobbyServo, swing_us

    # the seed's 10 Hz cycle: five 2 ms pulses, five 1.5 ms, 10 ms apart
    pulses = [(k * 10_000_000, (2000 if (k // 5) % 2 == 0 else 1500) * 1000) for k in range(40)]
    low, high = swing_us(HobbyServo(speed_us_per_s=Fraction(6667)), pulses, Fraction(1500))
    assert low == 1500 and 300 < high - low < 340  # 6667 us/s for ~50 ms: a third short
    low, high = swing_us(HobbyServo(speed_us_per_s=Fraction(20000)), pulses, Fraction(1500))
    assert (low, high) == (1500, 2000)
