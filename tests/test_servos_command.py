"""`pinarray servos ...` as a lab types it, on simulated servos (in-process, virtual time)."""

import io
import re
import sys
from pathlib import Path

import pytest

from pinarray.cli import main
from tests.prompts import interrupted_at_prompt

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
LOCALISATION = PROTOCOLS / "localisation.yaml"
DEMO = PROTOCOLS / "demo.yaml"


def simulated(url: str) -> str:
    """The first line of a command's output on simulated servos."""
    return f"SIMULATED servos ({url}): no real servo is touched\n"


def run(capsys, *argv, stdin: str | None = None, monkeypatch=None):
    """(exit status, stdout, stderr) of one command; ``stdin`` is what the person types."""
    if stdin is not None:
        monkeypatch.setattr(sys, "stdin", io.StringIO(stdin))
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


class Terminal(io.StringIO):
    """Typed answers, from something that says it is a terminal."""

    def isatty(self):
        return True


@pytest.fixture
def protocol(tmp_path):
    path = tmp_path / "localisation.yaml"
    path.write_bytes(LOCALISATION.read_bytes())
    return path


# -- which servos: real ones or simulated ones, never simulated by default ----------------------


@pytest.mark.parametrize("argv", [
    ["servos", "scan"], ["scan"], ["servos", "set-id", "1", "6"], ["servos", "return-delay"],
    ["servos", "torque-off"], ["servos", "rest"], ["servos", "calibrate", "{protocol}", "--pin", "6"],
    ["timing"],
])
def test_a_command_that_changes_or_inspects_servos_asks_for_port_or_sim_instead_of_simulating(
        capsys, protocol, argv):
    before = protocol.read_bytes()
    status, out, err = run(capsys, *(word.format(protocol=protocol) for word in argv))
    assert (status, out) == (2, "")
    assert err.count("\n") == 1 and err.endswith(
        "which servos? add --port PATH for real ones (e.g. --port /dev/ttyUSB0), or --sim to "
        "rehearse on simulated ones\n")
    assert protocol.read_bytes() == before


def test_simulated_servos_are_said_on_the_first_line_above_the_scan_table(capsys):
    status, out, _ = run(capsys, "servos", "scan", "--sim", "sim://?ids=1")
    assert status == 0
    first, header = out.splitlines()[:2]
    assert first == "SIMULATED servos (sim://?ids=1): no real servo is touched"
    assert header.startswith(" id  model")


def test_play_still_rehearses_on_simulated_servos_by_default_and_says_so_first(capsys):
    status, out, _ = run(capsys, "play", str(DEMO), "--trial", "1")
    assert status == 0
    assert out.splitlines()[0].startswith("demo: 1 trial(s) on SIMULATED servos (sim://?ids=1,")


# -- scan --------------------------------------------------------------------------------------


def test_scan_finds_a_lone_new_servo_by_broadcast_ping(capsys):
    status, out, err = run(capsys, "servos", "scan", "--sim", "sim://?ids=1")
    assert status == 0 and err == ""
    assert "  1  777 (STS3215)" in out and "500 us" in out
    assert out.splitlines()[-1] == "1 servo(s) answered a broadcast ping on sim://?ids=1"


def test_scan_of_several_servos_sweeps_every_id_with_progress_on_stderr(capsys):
    status, out, err = run(capsys, "servos", "scan", "--sim", "sim://?ids=2,5,200")
    assert status == 0
    assert out.splitlines()[-1] == (
        "3 servo(s) answered on sim://?ids=2,5,200 (ids 0-252 pinged, up to 2 ms each; answers "
        "to a broadcast ping collided: several servos answer)")
    progress = err.splitlines()
    assert progress[0] == "sweeping: id 31 of 252, found so far: 2, 5"
    assert progress[-1] == "sweeping: id 252 of 252, found so far: 2, 5, 200"


def test_a_scan_under_heavy_loss_says_how_far_looking_again_has_got(capsys):
    # Fourteen servos spread over the ids, 60 % of the instructions lost: the sweep misses
    # most, and looking again lasts longer than the sweep (on main: not a word meanwhile, up
    # to 45 s on a pty).
    url = "sim://?ids=3,9,20,40,55,70,90,110,130,150,170,190,210,240&drop=0.6&seed=1"
    status, out, err = run(capsys, "servos", "scan", "--sim", url, "--timeout-ms", "10")
    assert status == 0
    lines = err.splitlines()
    said = [tuple(map(int, m.groups())) for m in (
        re.fullmatch(r"looking again, up to (\d+) ms each: id \d+ \((\d+) of \d+\), found so "
                     r"far: .*", line) for line in lines) if m]
    assert said and said[0][1] == 1  # a round says where it starts
    for (wait_ms, done), (next_wait_ms, next_done) in zip(said, said[1:], strict=False):
        if next_wait_ms == wait_ms and next_done > done:  # the same round: at most 32 sweep
            assert (next_done - done) * wait_ms <= 32 * 10  # waits without a word
    assert lines[-1].startswith("sweeping: id 252 of 252, found so far: ")  # who, at last
    assert out.splitlines()[-1].startswith(f"{len(lines[-1].split(': ')[-1].split(', '))} ")


def test_pinarray_scan_is_the_same_command(capsys):
    assert run(capsys, "scan", "--sim", "sim://?ids=1-3", "--ids", "1-4")[1] == run(
        capsys, "servos", "scan", "--sim", "sim://?ids=1-3", "--ids", "1-4")[1]


def test_scan_says_what_to_check_when_nothing_answers_and_fails(capsys):
    # Exit status 2, as the other servos commands when no servo answers (it was 0 on main, as
    # if all was well).
    status, out, err = run(capsys, "servos", "scan", "--sim", "sim://?ids=1&missing=1",
                           "--ids", "1-3")
    assert status == 2 and "0 servo(s) answered" in out
    assert err.splitlines()[-1].startswith(
        "pinarray: nothing answered: check power and cables, and --baud")


def test_one_servo_whose_answers_all_come_garbled_is_said_to_be_there_and_the_scan_fails(capsys):
    # Every status packet damaged (a bad cable): its broadcast answer is garbled bytes, its
    # PINGs fail. On main: "collided: several servos answer", then "nothing answered: check
    # power", exit 0.
    url = "sim://?ids=1&corrupt=1"
    status, out, err = run(capsys, "servos", "scan", "--sim", url)
    assert status == 2
    assert out.splitlines()[-1] == (
        f"0 servo(s) answered on {url} (ids 0-252 pinged, up to 2 ms each; answers to a "
        "broadcast ping came garbled: one servo's answers damaged, or several servos' "
        "colliding)")
    assert err.splitlines()[-1] == (
        "pinarray: no servo answered a PING of its id, though garbled answers came back to the "
        "broadcast ping: a servo is there whose answers arrive damaged; check cables and "
        "connectors, and --baud")
    assert "several servos answer" not in out + err and "nothing answered" not in err


# -- set-id ------------------------------------------------------------------------------------


def test_set_id_renumbers_a_new_servo_and_says_what_it_checked(capsys):
    status, out, err = run(capsys, "servos", "set-id", "1", "7", "--sim", "sim://?ids=1")
    assert (status, err) == (0, "")
    assert out == simulated("sim://?ids=1") + (
                   "servo 1 is now servo 7 (model 777): torque off, LOCK (address 55) = 0, ID "
                   "(EEPROM address 5) = 7, LOCK = 1; it answers at id 7 and nothing answers "
                   "at id 1\n")


def test_set_id_onto_a_taken_id_is_one_line_and_status_2(capsys):
    status, out, err = run(capsys, "servos", "set-id", "1", "2", "--sim")
    assert status == 2 and out == simulated("sim://")
    assert err.startswith("pinarray: set-id: servo id 2 is already taken") and err.count("\n") == 1


# -- return delay ------------------------------------------------------------------------------


def test_return_delay_is_lowered_until_power_off_by_default(capsys):
    status, out, _ = run(capsys, "servos", "return-delay", "--ids", "1-2", "--sim")
    assert status == 0
    assert out.splitlines()[1:] == [
        f"servo {i}: RETURN_DELAY_TIME (address 7) 500 us -> 0 us, until power-off" for i in (1, 2)]


def test_saving_the_return_delay_asks_first(capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdin", Terminal("y\n"))
    status, out, _ = run(capsys, "servos", "return-delay", "--ids", "3", "--us", "20", "--save",
                         "--sim")
    assert status == 0
    assert "Save RETURN_DELAY_TIME (EEPROM address 7) = 20 us in the EEPROM of servo(s) 3" in out
    assert out.endswith("servo 3: RETURN_DELAY_TIME (address 7) 500 us -> 20 us, saved in EEPROM\n")


def test_saving_the_return_delay_declined_or_unconfirmed_writes_nothing(capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdin", Terminal("n\n"))
    status, out, err = run(capsys, "servos", "return-delay", "--ids", "3", "--save", "--sim")
    assert status == 2 and "RETURN_DELAY_TIME" not in out.split("?")[-1]
    assert err == "pinarray: return-delay --save not confirmed: nothing written\n"
    status, _, err = run(capsys, "servos", "return-delay", "--save", "--sim", stdin="y\n",
                         monkeypatch=monkeypatch)
    assert status == 2 and "confirm it with --yes (there is no terminal" in err
    assert run(capsys, "servos", "return-delay", "--ids", "3", "--save", "--yes", "--sim")[0] == 0


def test_return_delay_names_the_servos_that_did_not_take_it(capsys):
    status, out, err = run(capsys, "servos", "return-delay", "--sim", "sim://?missing=2,9",
                           "--ids", "1-3,9")
    assert status == 2 and [line.split(":")[0] for line in out.splitlines()[1:]] == [
        "servo 1", "servo 3"]
    assert err.startswith("pinarray: return-delay: no success on servo id(s) 2, 9 (first: "
                          "servo 2: reading RETURN_DELAY_TIME (address 7) failed")


# -- torque off, rest --------------------------------------------------------------------------


def test_torque_off_and_rest_say_which_servos_answered(capsys):
    status, out, err = run(capsys, "servos", "torque-off", str(LOCALISATION),
                           "--sim", "sim://?missing=4")
    assert (status, err) == (0, "")
    assert out.splitlines()[1:] == [
        "torque off on servo(s) 1-3, 5-16",
        "no answer from servo(s) 4 (not connected?): left as they are"]
    status, out, err = run(capsys, "servos", "rest", "--ids", "2,3", "--sim")
    assert (status, err) == (0, "")
    assert out.splitlines()[1:] == ["at rest: servo(s) 2-3; torque off: servo(s) 2-3"]


@pytest.mark.parametrize("command, done", [
    ("return-delay", "servo 6: RETURN_DELAY_TIME (address 7) 500 us -> 0 us, until power-off"),
    ("torque-off", "torque off on servo(s) 6"),
    ("rest", "at rest: servo(s) 6; torque off: servo(s) 6"),
])
def test_with_one_servo_connected_a_command_acts_on_it_and_names_those_not_connected(
        capsys, command, done):
    status, out, err = run(capsys, "servos", command, "--sim", "sim://?ids=6")
    assert (status, err) == (0, "")
    assert out.splitlines() == [
        "SIMULATED servos (sim://?ids=6): no real servo is touched", done,
        "no answer from servo(s) 1-5, 7-16 (not connected?): left as they are"]


def test_servos_named_by_ids_must_answer(capsys):
    status, out, err = run(capsys, "servos", "torque-off", "--ids", "5-6",
                           "--sim", "sim://?ids=6")
    assert status == 2 and out.splitlines()[1:] == ["torque off on servo(s) 6"]
    assert err.startswith("pinarray: torque-off (TORQUE_ENABLE, address 40): no success on "
                          "servo id(s) 5 (first: servo 5: writing TORQUE_ENABLE")


def test_a_servo_that_answers_but_does_not_take_the_command_is_still_an_error(capsys):
    status, out, err = run(capsys, "servos", "torque-off", "--sim",
                           "sim://?ids=5,6&drop_writes=1")
    assert status == 2
    assert out.splitlines()[1:] == [
        "torque off: no servo acknowledged",
        "no answer from servo(s) 1-4, 7-16 (not connected?): left as they are"]
    assert err.startswith("pinarray: torque-off (TORQUE_ENABLE, address 40): no success on "
                          "servo id(s) 5, 6 ") and err.count("\n") == 1


@pytest.mark.parametrize("command, what", [
    ("return-delay", "return-delay"), ("torque-off", "torque-off (TORQUE_ENABLE, address 40)"),
    ("rest", "rest")])
def test_when_no_servo_answers_at_all_the_command_fails_saying_what_to_check(
        capsys, command, what):
    url = "sim://?ids=30"
    status, out, err = run(capsys, "servos", command, "--sim", url)
    assert (status, out) == (2, simulated(url))
    assert err == (f"pinarray: {what}: no servo answered on {url} (servo id(s) 1-16): check "
                   "power, cables and --baud\n")


def test_ids_outside_the_device_are_refused_before_the_bus_is_opened(capsys):
    status, _, err = run(capsys, "servos", "rest", str(LOCALISATION), "--ids", "16-17")
    assert status == 2
    assert err == ("pinarray: --ids: servo id(s) 17 are not part of the device of "
                   f"{LOCALISATION} (its servos: 1-16)\n")


# -- calibrate ---------------------------------------------------------------------------------


def test_calibrating_a_pin_writes_rest_and_up_into_the_protocol_keeping_its_comments(
        capsys, monkeypatch, protocol):
    before = protocol.read_text()
    status, out, err = run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim",
                           stdin="-\n-10\nok\n=2150\n+5\nok\n", monkeypatch=monkeypatch)
    assert (status, err) == (0, "")
    assert "rest>   goal 2038, at 2038 steps" in out and "up>   goal 2155, at 2155 steps" in out
    assert "pin 6 (servo 6): at rest (2028 steps), torque off" in out
    assert out.splitlines()[-1].startswith(
        f"{protocol}: device: pins: 6: rest_steps 2028, positions {{1.5 ms: 2028, 2 ms: 2155}}; "
        "stroke 127 steps (11.2 deg")
    after = protocol.read_text()
    assert after == before.replace(
        "    lever_mm: 10\n",
        "    lever_mm: 10\n  pins:\n    6: {rest_steps: 2028, positions: {1.5: 2028, 2.0: 2155}}\n")


def test_calibrating_again_changes_the_numbers_in_place(capsys, monkeypatch, protocol):
    run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim",
        stdin="ok\n+100\nok\n", monkeypatch=monkeypatch)
    once = protocol.read_text()
    status, out, _ = run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim",
                         stdin="+4\nok\n+100\nok\n", monkeypatch=monkeypatch)
    assert status == 0 and "calibrated rest 2048, up 2148" in out
    assert protocol.read_text() == once.replace(
        "6: {rest_steps: 2048, positions: {1.5: 2048, 2.0: 2148}}",
        "6: {rest_steps: 2052, positions: {1.5: 2052, 2.0: 2152}}")


@pytest.mark.parametrize("typed, status, said", [
    ("+\nq\n", 0, "nothing written"),
    ("+\nok\n", 2, "input ended before the up position was chosen; nothing written"),
    ("=1990\nok\n=2400\nok\n", 2, "the protocol would be invalid: pin 6 cannot follow 5 Hz "
                                  "(datasheet figures): its stroke of 410 steps"),
])
def test_a_calibration_not_finished_or_not_valid_leaves_the_file_as_it_was(
        capsys, monkeypatch, protocol, typed, status, said):
    before = protocol.read_bytes()
    got, out, err = run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim",
                        stdin=typed, monkeypatch=monkeypatch)
    assert got == status and said in out + err
    assert "pin 6 (servo 6): at rest (2048 steps), torque off" in out
    assert protocol.read_bytes() == before
    assert not [p for p in protocol.parent.iterdir() if p.name != protocol.name]  # no leftovers


def test_jog_mistakes_are_explained_and_the_servos_limits_kept(capsys, monkeypatch, protocol):
    status, out, _ = run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim",
                         stdin="up a bit\n=5000\n\n?\nq\n", monkeypatch=monkeypatch)
    assert status == 0
    assert "expected +, -, +N, -N, =N, ok or q, found 'up a bit'" in out
    assert ("pin 6 (servo 6): GOAL_POSITION 5000 steps is outside the servo's angle limits "
            "0..4095 (MIN/MAX_ANGLE_LIMIT, EEPROM addresses 9, 11)") in out
    assert "goal 2048, at 2048 steps" in out and "ok: this is it" in out


def test_up_must_differ_from_rest(capsys, monkeypatch, protocol):
    _, out, _ = run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim",
                    stdin="ok\nok\n+50\nok\n", monkeypatch=monkeypatch)
    assert "up must differ from rest (2048 steps): jog further" in out
    assert "6: {rest_steps: 2048, positions: {1.5: 2048, 2.0: 2098}}" in protocol.read_text()


class EditedMeanwhile(io.StringIO):
    """Typed answers; someone saves the protocol in an editor before the last one."""

    def __init__(self, text, path):
        super().__init__(text)
        self.path = path

    def readline(self, *args):
        line = super().readline(*args)
        if self.tell() == len(self.getvalue()):
            self.path.write_text(self.path.read_text() + "# saved from an editor\n")
        return line


def test_a_protocol_changed_on_disk_meanwhile_is_not_overwritten(capsys, monkeypatch, protocol):
    monkeypatch.setattr(sys, "stdin", EditedMeanwhile("ok\n+50\nok\n", protocol))
    status, _, err = run(capsys, "servos", "calibrate", str(protocol), "--pin", "6", "--sim")
    assert status == 2 and "changed on disk since it was read" in err
    assert protocol.read_text().endswith("# saved from an editor\n")


def test_calibrate_refuses_a_pin_off_the_grid_and_a_broken_protocol(capsys, tmp_path, protocol):
    status, _, err = run(capsys, "servos", "calibrate", str(protocol), "--pin", "17")
    assert status == 2 and "expected a pin from 1 to 16" in err
    broken = tmp_path / "broken.yaml"
    broken.write_text("protocol: x\nstimuli: [\n")
    status, _, err = run(capsys, "servos", "calibrate", str(broken), "--pin", "1")
    assert status == 2 and err.startswith(f"pinarray: {broken}:3:1: malformed YAML")


def test_ctrl_c_at_the_jog_prompt_rests_the_pin_and_writes_nothing(protocol):
    before = protocol.read_bytes()
    status, out, err = interrupted_at_prompt(
        ["servos", "calibrate", str(protocol), "--pin", "6", "--sim"], b"rest> ")
    assert status == 130, err
    assert b"pin 6 (servo 6): at rest (2048 steps), torque off" in out
    assert err.decode().strip().splitlines() == ["pinarray: calibration stopped by SIGINT"]
    assert protocol.read_bytes() == before
