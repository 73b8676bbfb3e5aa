"""Simulated boards kept in a file (``sim://pca9685?state=FILE``): only a file this simulator
wrote is read or replaced; anything else a person names is refused in one line and left as it
was, and nothing waits on it."""

import contextlib
import os
import pickle
import signal
import stat

import pytest

from pinarray.clock import MonotonicClock
from pinarray.errors import PinArrayError
from pinarray.hardware.pca9685 import board_file
from pinarray.hardware.pca9685 import registers as r
from pinarray.hardware.pca9685.sim import SimI2cLink


@contextlib.contextmanager
def refused_within_seconds(seconds: int):
    """A state file that makes the link wait (a FIFO's open) fails the test instead."""

    def give_up(number, frame):
        raise AssertionError(f"still waiting after {seconds} s")

    previous = signal.signal(signal.SIGALRM, give_up)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


class RunsCode:
    """A pickle that runs code when it is read: it leaves a file behind."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def state_url(path) -> str:
    return f"sim://pca9685?state={path}"


def notes(path):
    path.write_text("lab notes: participant 7 felt pin 10 twice\n")


def fifo(path):
    os.mkfifo(path)


def old_pickle(path):
    path.write_bytes(pickle.dumps((3, {0x40: "not a board"})))


def code_pickle(path):
    path.write_bytes(pickle.dumps(RunsCode(path.parent / "ran")))


def other_json(path):
    path.write_text('{"format": "something else", "boards": []}')


def wrong_values(path):
    path.write_text(board_file.FORMAT.join(['{"format": "', '", "version": 1, "messages": -1, '
                                            '"boards": [{"osc_hz": "fast"}]}']))


@pytest.mark.parametrize("make", [notes, fifo, old_pickle, code_pickle, other_json, wrong_values])
def test_a_file_the_simulator_did_not_write_is_refused_in_one_line_and_left_as_it_was(
        tmp_path, make):
    state = tmp_path / "board"
    make(state)
    before = state.lstat()
    content = None if stat.S_ISFIFO(before.st_mode) else state.read_bytes()
    with refused_within_seconds(5), pytest.raises(PinArrayError) as refused:
        SimI2cLink(state_url(state), MonotonicClock())
    message = str(refused.value)
    assert "\n" not in message and str(state) in message and "left as it is" in message
    after = state.lstat()
    assert stat.S_IFMT(after.st_mode) == stat.S_IFMT(before.st_mode)
    assert content is None or state.read_bytes() == content
    assert not (tmp_path / "ran").exists(), "reading the state file ran its code"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board"]  # no lock, no temporary


def test_a_device_named_as_the_state_file_is_refused_without_being_opened(tmp_path):
    # Named through a link in tmp_path: should the refusal ever break, the link is what gets
    # replaced, never the machine's /dev/full.
    state = tmp_path / "board"
    state.symlink_to("/dev/full")
    with refused_within_seconds(5), pytest.raises(PinArrayError, match="character device"):
        SimI2cLink(state_url(state), MonotonicClock())
    assert os.readlink(state) == "/dev/full" and stat.S_ISCHR(os.stat("/dev/full").st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board"]


def test_the_boards_come_back_from_their_file_as_they_were_left(tmp_path):
    url = state_url(tmp_path / "board") + "&osc_hz=25300000"
    first = SimI2cLink(url, MonotonicClock())
    first.write(0x40, bytes([r.MODE1, r.SLEEP | r.AI]))
    first.write(0x40, bytes([r.PRE_SCALE, 60]))
    first.write(0x40, bytes([r.MODE1, r.AI]))
    first.write(0x40, bytes([r.led_register(3)]) + r.LedBlock.pulse(100, 300).encode())
    left = first.board(0x40)
    first.close()
    again = SimI2cLink(url, MonotonicClock())
    try:
        board = again.board(0x40)
        assert board.parts() == left.parts()
        assert again.write_read(0x40, bytes([r.PRE_SCALE]), 1) == bytes([60])
    finally:
        again.close()
    data = (tmp_path / "board").read_bytes()
    assert data.startswith(b'{"format":"pinarray simulated PCA9685 boards"')


@pytest.mark.parametrize("command", ["batch", "tui"])
def test_a_board_kept_in_a_file_asks_for_real_time_in_words_that_fit_the_command_line(
        tmp_path, capsys, command):
    from pathlib import Path

    from pinarray.cli import main

    protocol = Path(__file__).parents[2] / "protocols" / "localisation_pwm.yaml"
    words = [command, str(protocol), "--sim", state_url(tmp_path / "board"), "--speed", "2",
             "--results", str(tmp_path / "results")]
    if command == "batch":
        words += ["--subject", "01", "--observer", "default"]
    assert main(words) == 2
    assert "--speed must be 1" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("command", [["pwm", "scan"], ["play", "localisation_pwm.yaml"]])
def test_play_and_pwm_scan_refuse_a_fifo_named_as_the_state_file_at_once(tmp_path, capsys,
                                                                         command):
    from pathlib import Path

    from pinarray.cli import main

    state = tmp_path / "board"
    os.mkfifo(state)
    words = [str(Path(__file__).parents[2] / "protocols" / word) if word.endswith(".yaml")
             else word for word in command]
    with refused_within_seconds(10):  # it used to wait on the FIFO, deaf to SIGTERM
        status = main([*words, "--sim", state_url(state)])
    assert status == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "found a FIFO (named pipe)" in err
    assert stat.S_ISFIFO(state.lstat().st_mode)
