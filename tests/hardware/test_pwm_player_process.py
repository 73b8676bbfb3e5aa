"""`pinarray play` on a simulated PCA9685 board, killed or signalled at any moment: the board is
left with every channel at its rest width for the servos' travel time, then full off.

The simulated board lives in a state file (``sim://pca9685?state=FILE``), written through after
every message, so it outlives the program as a real board does: `play` hands it to a player
process as it would a real i2c-dev bus, and what the board was last told is read from the
file after the program ended, however it ended. (A replay of the ``--i2c-log`` proves less:
the log is written by the very process that is killed, and holds messages back between trials.)
"""

import ctypes
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pinarray.clock import MonotonicClock
from pinarray.hardware.pca9685.registers import FULL_BIT, led_register
from pinarray.hardware.pca9685.sim import SimI2cLink
from pinarray.protocol.load import load_protocol

from .lab import assert_rest_held_for_the_travel_time

# Player processes on the wall clock: run apart from the CPU-bound tests (tests/suite.py).
pytestmark = [pytest.mark.realtime, pytest.mark.xdist_group("pwm player process")]

PROTOCOL = Path(__file__).parents[2] / "protocols" / "localisation_pwm.yaml"
PR_SET_CHILD_SUBREAPER = 36
# Its first trial plays at 3 Hz, the board at 30 Hz: not the 50 Hz at which play holds rest,
# so a safe stop that assumes its own rate writes widths the servos must not get.
SEED = 1


@pytest.fixture(scope="module", autouse=True)
def adopt_orphans():
    """A player process whose `play` was killed becomes this test's child, to be waited for."""
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)


def protocol_file(tmp_path, duration_s="1.5"):
    """The seed's PWM protocol, its trains ``duration_s`` long, little time between trials."""
    text = PROTOCOL.read_text().replace("duration_s: 10", f"duration_s: {duration_s}")
    text = text.replace("inter_trial_interval_s: 3", "inter_trial_interval_s: 0.2")
    path = tmp_path / "short.yaml"
    path.write_text(text)
    return path


def board_url(tmp_path, extra=""):
    return f"sim://pca9685?osc_hz=25300000&state={tmp_path / 'board'}{extra}"


def play(tmp_path, extra="", *, trial=None):
    command = [sys.executable, "-m", "pinarray", "play", str(protocol_file(tmp_path)),
               "--sim", board_url(tmp_path, extra), "--seed", str(SEED)]
    if trial is not None:
        command += ["--trial", str(trial)]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})


def test_the_first_trial_plays_the_board_at_another_rate_than_the_one_rest_is_held_at(tmp_path):
    from pinarray.plan import make_plan
    from pinarray.player.families import pwm_setup

    protocol = load_protocol(protocol_file(tmp_path))
    first = make_plan(protocol, SEED).trials[0]
    assert first.condition.frequency_hz * 10 != pwm_setup(protocol.device).pwm_hz


def wait_for_first_trial(process):
    line = process.stdout.readline()
    assert "played by a player process" in line, line + process.stderr.read()
    time.sleep(0.5)  # well inside the first 1.5 s train


def player_processes():
    """This test's children that are player processes (adopted, or started by it)."""
    found = []
    for task in os.listdir("/proc/self/task"):
        children = Path(f"/proc/self/task/{task}/children").read_text().split()
        for pid in map(int, children):
            try:
                command = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                continue
            if b"pinarray.player.child" in command:
                found.append(pid)
    return found


def wait_for_player_processes(timeout_s=30.0):
    """Every player process left behind has made the pins safe and exited."""
    deadline = time.monotonic() + timeout_s
    for pid in player_processes():
        while os.waitpid(pid, os.WNOHANG) == (0, 0):
            assert time.monotonic() < deadline, f"player process {pid} did not end"
            time.sleep(0.02)


def last_word(tmp_path):
    """The simulated board as the programs left it, read from its state file."""
    link = SimI2cLink(board_url(tmp_path), MonotonicClock())
    try:
        return link.board(0x40)
    finally:
        link.close()


def assert_rest_then_full_off(board, protocol):
    """Every channel full off, after carrying its rest width for the servos' travel time."""
    for channel in range(16):
        assert board._regs[led_register(channel) + 3] & FULL_BIT, f"channel {channel} pulses"
    assert_rest_held_for_the_travel_time(board, protocol, time.monotonic_ns())


@pytest.mark.parametrize("sent", ["SIGTERM", "SIGINT", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGPIPE"])
def test_every_signal_to_play_mid_trial_rests_every_channel_then_switches_it_full_off(
        tmp_path, sent):
    process = play(tmp_path)
    wait_for_first_trial(process)
    number = getattr(signal, sent)
    process.send_signal(number)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + number, stderr
    assert f"stopped by {sent}" in stderr and "Traceback" not in stderr
    wait_for_player_processes()
    assert_rest_then_full_off(last_word(tmp_path), load_protocol(protocol_file(tmp_path)))


def test_a_killed_play_leaves_its_player_process_to_rest_the_pins_and_switch_them_off(tmp_path):
    process = play(tmp_path)
    wait_for_first_trial(process)
    process.kill()
    process.communicate(timeout=30)
    assert player_processes(), "no player process outlived play"
    wait_for_player_processes()
    assert_rest_then_full_off(last_word(tmp_path), load_protocol(protocol_file(tmp_path)))


def test_a_killed_player_process_is_noticed_and_play_rests_the_pins_itself(tmp_path):
    process = play(tmp_path)
    wait_for_first_trial(process)
    (child,) = [int(pid) for pid in
                Path(f"/proc/{process.pid}/task/{process.pid}/children").read_text().split()]
    os.kill(child, signal.SIGKILL)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 2, stderr
    assert "killed by signal 9" in stderr and "Traceback" not in stderr
    assert_rest_then_full_off(last_word(tmp_path), load_protocol(protocol_file(tmp_path)))


# The board's messages, numbered from 1 as it hears them from both processes: play connects
# (1-2: MODE1 read), starts its player process, holds rest (3-8: SLEEP, MODE2, PRE_SCALE, every
# channel, wake, RESTART), checks rest (9-11); the player process then begins the trial (12-17:
# the same sequence at the trial's rate, RESTART timed to end at onset).
MOMENTS = {
    "before connecting": 1,
    "between connecting and holding rest": 3,
    "as play puts the board to sleep": 4,
    "as play writes the prescale": 5,
    "as play wakes the board": 7,
    "as play restarts the counter": 8,
    "as the player process puts the board to sleep": 12,
    "as the player process writes the prescale": 14,
    "as the player process wakes the board": 16,
    "as the player process restarts the counter at onset": 17,
}


@pytest.mark.parametrize("moment", list(MOMENTS))
def test_a_kill_at_any_moment_of_start_up_leaves_the_board_untouched_or_full_off(
        tmp_path, moment):
    number = MOMENTS[moment]
    process = play(tmp_path, f"&kill_at={number}", trial=1)
    _, stderr = process.communicate(timeout=60)
    killed_player = number >= 12
    if killed_player:  # play noticed and made the pins safe itself
        assert process.returncode == 2 and "killed by signal 9" in stderr, stderr
    else:
        assert process.returncode == -signal.SIGKILL, stderr
    wait_for_player_processes()
    assert_rest_then_full_off(last_word(tmp_path), load_protocol(protocol_file(tmp_path)))
