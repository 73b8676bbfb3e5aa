"""Numbers on the command line, as a hurried user or a fuzzer types them: every command ends in
exit status 0 or 2, errors are one line, and nothing hangs or allocates gigabytes, because
each option refuses what would (`pinarray.cli.common`).

The options are found in the parser itself, so a new numeric option is fuzzed too. Commands
that run quickly run for real; those that drive servos, run sessions or analyse results are
parsed only here (their handlers have tests of their own).
"""

import argparse
import contextlib
import io
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinarray.cli import build_parser, common, main
from tests.commands import pinarray_forked

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
DEMO = str(PROTOCOLS / "demo.yaml")
MOTION = str(PROTOCOLS / "apparent_motion.yaml")
# Options naming files, folders, ports or URLs, and flags: not numbers.
NOT_NUMBERS = {"--out", "--png", "--csv", "--targets", "--results", "--sim", "--port", "--faults",
               "--protocols", "--subject", "--session", "--experimenter", "--observer",
               "--responses", "--interval", "--help", "--version"}


def subcommands(parser: argparse.ArgumentParser, prefix=()):
    """(command words, its parser) for every command and softness model."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name), sub
                yield from subcommands(sub, (*prefix, name))


def numeric_options(parser: argparse.ArgumentParser) -> list[str]:
    return sorted(option for action in parser._actions if action.nargs != 0
                  for option in action.option_strings[:1] if option not in NOT_NUMBERS)


PARSER = build_parser()
COMMANDS = {words: numeric_options(sub) for words, sub in subcommands(PARSER)}
# Run for real: (command words, the arguments they need besides the fuzzed options).
RUN = {
    ("grid",): [],
    ("preview",): [MOTION],
    ("plan",): [MOTION],
    ("compile",): [DEMO, "--out", "-"],
    ("validate",): [DEMO],
    **{("softness", model): [] for model in
       ("hertz", "telescopic", "display", "fit", "track", "forceps")},
}
PARSE_ONLY = {
    ("play",): [DEMO], ("timing",): [], ("scan",): [], ("sim-serve",): [],
    ("batch",): [DEMO, "--subject", "s1", "--observer", "default"],
    ("analyse",): ["results"], ("power",): [DEMO], ("tui",): [],
    ("servos", "scan"): [], ("servos", "set-id"): ["1", "2"], ("servos", "return-delay"): [],
    ("servos", "calibrate"): [DEMO, "--pin", "1"],
    ("servos", "response"): [DEMO, "--pin", "1"], ("servos", "torque-off"): [],
    ("servos", "rest"): [], ("pwm", "calibrate"): [DEMO, "--pin", "1"],
}

numbers = st.one_of(
    st.integers(-3, 64).map(str),  # in range for most options: the handlers run
    st.floats(0.001, 100).map(lambda x: f"{x:.4g}"),
    st.sampled_from(["nan", "-nan", "inf", "-inf", "1e-300", "-1e-300", "1e300", "-1", "0", "-0",
                     "1", "2", "0.5", "1e9", "-1e9", "99999999999999999999", "9" * 5000, "",
                     " 3 ", "0x10", "1_000", "1,2", "3,", ",", "1e", "abc", "2**63", "1/3",
                     str(2**63 - 1), str(2**63), str(-(2**63))]),
    st.integers(-(10**12), 10**12).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.lists(st.integers(-5, 10**5), min_size=1, max_size=4).map(lambda v: ",".join(map(str, v))),
)


def run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as stop:
            status = stop.code
    return status, err.getvalue()


def test_every_command_is_either_run_or_parsed_here():
    assert set(RUN) | set(PARSE_ONLY) | {("softness",), ("servos",), ("pwm",),
                                             ("pwm", "scan")} == set(COMMANDS)  # no numbers


@settings(max_examples=200, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_any_numbers_for_the_options_of_a_command_that_runs_end_in_0_or_2(data):
    words = data.draw(st.sampled_from(sorted(RUN)))
    options = data.draw(st.lists(st.sampled_from(COMMANDS[words]), min_size=1, max_size=3,
                                 unique=True)) if COMMANDS[words] else []
    argv = [*words, *RUN[words]]
    for option in options:
        argv += [f"{option}={data.draw(numbers)}"]
    status, err = run(argv)
    assert status in (0, 2), (argv, err)
    assert "Traceback" not in err
    if status == 2:
        last = err.splitlines()[-1]
        assert last.startswith("pinarray"), (argv, err)  # "pinarray: ..." or argparse's error


@settings(max_examples=150, deadline=None, database=None)
@given(data=st.data())
def test_options_of_commands_that_drive_servos_or_sessions_refuse_what_would_not_end(data):
    words = data.draw(st.sampled_from(sorted(PARSE_ONLY)))
    option = data.draw(st.sampled_from(COMMANDS[words]))
    value = data.draw(numbers)
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            args = PARSER.parse_args([*words, *PARSE_ONLY[words], f"{option}={value}"])
    except SystemExit as stop:
        assert stop.code == 2
        return
    dest = "time_scale" if option == "--speed" else option.lstrip("-").replace("-", "_")
    parsed = getattr(args, dest)
    if option == "--speed":
        assert parsed == 0 or common.MIN_TIME_SCALE <= parsed <= common.MAX_TIME_SCALE
    elif option == "--seed":
        assert 0 <= parsed <= common.MAX_SEED


@pytest.mark.parametrize("value", ["inf", "nan", "1e-300", "-1", "1e300"])
def test_a_time_scale_that_would_never_end_or_mean_nothing_is_refused(value):
    for words, needed in (("play", [DEMO]), ("batch", [DEMO, "--subject", "s", "--observer", "x"]),
                          ("tui", [])):
        for option in ("--speed", "--time-scale"):  # the new name and the old one
            status, err = run([words, *needed, f"{option}={value}"])
            assert status == 2 and "expected 0 (virtual time) or 0.01 to 10000 times real time" in err


def test_a_negative_seed_is_refused_by_every_command_that_takes_one():
    takers = [words for words, options in COMMANDS.items() if "--seed" in options]
    assert len(takers) >= 6
    for words in takers:
        needed = RUN.get(words) or PARSE_ONLY.get(words) or []
        status, err = run([*words, *needed, "--seed=-1"])
        assert status == 2 and "expected a seed from 0 to 2^63-1, found '-1'" in err, words


def test_sizes_that_would_allocate_gigabytes_are_refused():
    for argv in (["preview", MOTION, "--width", "1000000000"],
                 ["softness", "hertz", "--rows", "100000000"],
                 ["softness", "track", "--time-step-ms", "1e-9"],
                 ["analyse", "results", "--bootstrap-resamples", "1000000000"],
                 ["power", DEMO, "--studies", "100000000"],
                 ["grid", "--rows", "64", "--columns", "64", "--table"]):
        status, err = run(argv)
        assert status == 2 and len(err.strip().splitlines()[-1]) < 300, argv


def test_no_help_text_shows_a_doubled_percent_sign():
    for words, sub in subcommands(PARSER):
        assert "%%" not in sub.format_help(), words


# -- servo ids and output paths ----------------------------------------------------------------


def sim_serve(*args: str) -> subprocess.CompletedProcess:
    """``pinarray sim-serve ARGS`` in its own process (forked), expected to refuse at once (a
    server that started instead is stopped by the timeout, which fails the test)."""
    folder = Path(tempfile.mkdtemp(prefix="pinarray-sim-serve-"))
    try:
        return pinarray_forked(folder, "sim-serve", *args, timeout=60)
    finally:
        shutil.rmtree(folder)


@pytest.mark.parametrize("ids", ["", ",", " , "])
def test_sim_serve_of_no_servo_id_is_refused_at_once(ids):
    served = sim_serve("--ids", ids)
    assert (served.returncode, served.stdout) == (2, "")
    assert served.stderr == f"pinarray: --ids: expected at least one servo id 0-252, found {ids!r}\n"


@pytest.mark.parametrize("command", [["servos", "rest"], ["servos", "torque-off"],
                                     ["servos", "return-delay"], ["servos", "scan"], ["scan"]])
@pytest.mark.parametrize("ids", ["", ","])
def test_an_empty_ids_option_is_refused_not_read_as_every_servo(command, ids):
    status, err = run([*command, "--ids", ids])
    assert status == 2
    assert err == f"pinarray: --ids: expected at least one servo id 0-252, found {ids!r}\n"


def test_a_sim_url_of_no_servo_id_is_refused():
    status, err = run(["play", DEMO, "--sim", "sim://?ids="])
    assert status == 2
    assert err == ("pinarray: sim://?ids=: sim URL key ids: expected at least one servo id "
                   "0-252, found ''\n")


@pytest.mark.parametrize("argv", [["preview", MOTION], ["softness", "hertz"]])
def test_a_png_option_naming_a_folder_is_refused_before_anything_is_written(argv, tmp_path):
    folder = tmp_path / "figures"
    folder.mkdir()
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([*argv, "--png", str(folder)])
    assert (status, out.getvalue()) == (2, "")
    assert err.getvalue() == f"pinarray: {folder}: cannot write: it is a folder, expected a file name\n"
    assert sorted(tmp_path.iterdir()) == [folder] and not any(folder.iterdir())


@pytest.mark.parametrize("where", ["folder", "file-as-folder", "no-folder", "kernel-folder"])
def test_sim_serve_refuses_an_arrivals_log_it_could_not_write_before_serving(where, tmp_path):
    (tmp_path / "plain").write_text("")
    path = {"folder": tmp_path, "file-as-folder": tmp_path / "plain" / "log.tsv",
            "no-folder": tmp_path / "gone" / "log.tsv",
            # a folder where nobody, root included, can make a file (permissions do not stop root)
            "kernel-folder": Path("/proc/arrivals.tsv")}[where]
    served = sim_serve("--ids", "1", "--arrivals", str(path))
    assert (served.returncode, served.stdout) == (2, "")
    assert served.stderr.startswith(f"pinarray: --arrivals {path}: ")
    assert len(served.stderr.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain"]


@pytest.mark.parametrize("where", ["folder", "no-folder"])
def test_an_i2c_log_play_could_not_write_is_refused_by_its_option_before_anything_plays(
        where, tmp_path):
    path = tmp_path if where == "folder" else tmp_path / "missing" / "log.txt"
    status, err = run(["play", str(PROTOCOLS / "localisation_pwm.yaml"), "--sim",
                       "sim://pca9685", "--i2c-log", str(path)])
    assert status == 2 and "Traceback" not in err
    assert err.splitlines()[-1].startswith("pinarray play: error: argument --i2c-log: ")
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("option", "value", "expected"), [
    ("--subjects", "2,2", "expected each number once, found 2 more than once in '2,2'"),
    ("--subjects", "2,,4", "expected comma-separated numbers, found an empty one in '2,,4'"),
    ("--subjects", "4,８", "expected a whole number, found '８'"),
    ("--studies", "1_000", "expected a whole number, found '1_000'"),
    ("--seed", "１２", "expected a whole number, found '１２'"),
])
def test_numbers_a_list_repeats_skips_or_writes_in_other_digits_are_refused(option, value,
                                                                              expected):
    status, err = run(["power", DEMO, option, value])
    assert status == 2 and err.splitlines()[-1].endswith(expected)


@pytest.mark.parametrize(("options", "said"), [
    (["--port", "/nowhere/ttyUSB9"], "--port /nowhere/ttyUSB9: no such device (is the adapter plugged in?)"),
    (["--port", "/etc/passwd"], "--port /etc/passwd: not a serial device"),
    (["--port", "."], "--port .: not a serial device"),
    (["--port", "/dev/tty"], "--port /dev/tty: the terminal this command runs in"),
    (["--sim", "bogus://"], "--sim expects a sim:// URL, found 'bogus://'"),
    (["--sim", "sim://?drop=abc"], "sim://?drop=abc: sim URL key drop: expected a number, found 'abc'"),
    (["--sim", "sim://?fidelity=motion&drop=0.1"], "sim URL key fidelity: motion computes"),
    (["--results", DEMO], f"{DEMO}: cannot write there: it is a file, expected a folder"),
    (["--results", f"{DEMO}/results"], f"cannot write there: {DEMO} is a file, not a folder"),
])
def test_the_ui_refuses_a_port_simulator_or_results_folder_that_cannot_work_before_it_opens(
        tmp_path, options, said):
    # As `play` does: one line and exit status 2, not a start screen whose Connect fails.
    done = pinarray_forked(tmp_path / "out", "tui", DEMO, *options, timeout=60)
    assert done.returncode == 2 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith("pinarray: ") and said in line, line


@pytest.mark.parametrize("command", [("play", DEMO), ("scan",), ("servos", "rest"), ("timing", DEMO)])
def test_a_servo_port_that_is_not_there_is_said_once_in_the_lab_s_words(tmp_path, command):
    # An adapter left unplugged: one line naming the port, not pyserial's errno twice over.
    status, err = run([*command, "--port", str(tmp_path / "ttyUSB9")])
    assert status == 2
    assert err.splitlines() == [f"pinarray: cannot open servo port {tmp_path / 'ttyUSB9'}: no such device "
                                "(is the adapter plugged in?)"]


def test_a_servo_port_the_user_may_not_open_says_how_to_be_allowed(monkeypatch):
    # The first day on Linux: the adapter is there, owned by the dialout group. (Tested with
    # pyserial's own error: a test run as root opens any port.)
    import errno

    import serial

    from pinarray.clock import MonotonicClock
    from pinarray.errors import BusError
    from pinarray.hardware.feetech.transport import open_bus

    def refused(url, **settings):
        raise serial.SerialException(errno.EACCES, f"could not open port {url}: [Errno 13] "
                                                   f"Permission denied: '{url}'")

    monkeypatch.setattr(serial, "serial_for_url", refused)
    with pytest.raises(BusError) as error:
        open_bus("/dev/ttyUSB0", clock=MonotonicClock())
    assert str(error.value) == (
        "cannot open servo port /dev/ttyUSB0: permission denied (add your user to the group "
        "that owns the port, e.g. dialout: sudo usermod -aG dialout $USER, then log in again)")


@pytest.mark.parametrize("command", [("tui", DEMO), ("play", DEMO), ("pwm", "scan")])
def test_an_empty_port_an_unset_variable_gives_is_refused_not_taken_for_the_simulator(
        tmp_path, command):
    done = pinarray_forked(tmp_path / "out", *command, "--port", "", timeout=60)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.splitlines()[-1].endswith(
        "argument --port: expected a device such as /dev/ttyUSB0 or /dev/i2c-1, found nothing "
        "(an unset variable?)"), done.stderr
