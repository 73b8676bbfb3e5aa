"""Bad protocol files as a lab (or a fuzzer) makes them: each ends in ``ok`` or in one located
line per problem, exit status 2, never a traceback, never a hang.

The generated cases come from `tests.strategies`: valid documents, mutated in their structure
(values of another shape, tag or size, keys deleted or added, aliases), damaged as text and
saved in various encodings. Time and memory are bounded by construction in the loader (a
size cap, number and nesting limits); nothing here times anything.
"""

import contextlib
import io
import os
import re
import shutil
import subprocess
import tempfile
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinarray.cli import main
from pinarray.errors import PinArrayError
from pinarray.plan import make_plan
from pinarray.protocol.design import MAX_PULSES, MAX_PULSES_PER_TRIAL, MAX_TRIALS
from pinarray.protocol.load import (
    MAX_PROTOCOL_BYTES,
    MAX_TASK_LABEL_CHARS,
    parse_protocol,
    validate_file,
)
from pinarray.protocol.yaml_nodes import MAX_PROBLEMS
from pinarray.protocol.yaml_tree import MAX_ALIASES, MAX_DEPTH
from pinarray.schedule import compile_trial
from tests.commands import pinarray_forked
from tests.lab_protocols import short_copy
from tests.strategies import alias_bomb, protocol_files
from tests.test_protocol_load import MINIMAL, problems

REPO = Path(__file__).resolve().parent.parent
FUZZ = settings(max_examples=250, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def run(*argv: str) -> tuple[int, str, str]:
    """``pinarray ARGV`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main(list(argv))
        except SystemExit as stop:  # argparse
            status = stop.code
    return status, out.getvalue(), err.getvalue()


def assert_located_lines(lines: list[str], path: str) -> None:
    """Each line one problem, starting with the file and, where known, line:col."""
    assert 1 <= len(lines) <= MAX_PROBLEMS + 1
    for line in lines:
        assert re.match(rf"{re.escape(path)}(:\d+:\d+)?: \S", line), line
        assert "\n" not in line and "Traceback" not in line and len(line) < 600, line


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz") / "p.yaml"


@FUZZ
@given(data=protocol_files())
def test_any_protocol_file_is_accepted_or_refused_one_located_line_per_problem(data, scratch):
    scratch.write_bytes(data)
    protocol, lines = validate_file(scratch)
    if lines:
        assert protocol is None
        assert_located_lines(lines, str(scratch))
        return
    # What validate accepts can be planned and compiled: bounded, and any refusal is one line.
    try:
        plan = make_plan(protocol)
        compile_trial(protocol, plan.trials[0])
    except PinArrayError as problem:
        assert "\n" not in str(problem)


# What the command adds to the check above (its exit status, "ok", warnings on stderr) needs
# fewer documents: each costs the whole command (its parser built, its output written).
@settings(FUZZ, max_examples=60)
@given(data=protocol_files())
def test_validate_exits_0_or_2_and_prints_only_ok_or_located_lines(data, scratch):
    scratch.write_bytes(data)
    status, out, err = run("validate", str(scratch))
    if status == 0:
        assert out.startswith(f"{scratch}: ok")
        # A valid protocol may still be warned about (a duration cue), one located line each.
        assert all(line.startswith(f"{scratch}: warning: ") for line in err.splitlines())
    else:
        assert status == 2 and out == ""
        assert_located_lines(err.splitlines(), str(scratch))


number_texts = st.one_of(
    st.text(alphabet="0123456789eE+-._/: x", max_size=45),
    st.integers(-(10**15), 10**15).map(lambda e: f"1e{e}"),
    st.tuples(st.integers(0, 10**50), st.integers(-(10**15), 10**15)).map(
        lambda m_e: f"{m_e[0]}.5e{m_e[1]}"),
    st.fractions().map(str),
)


@settings(max_examples=300, deadline=None, database=None)
@given(text=number_texts, quoted=st.booleans())
def test_a_number_of_any_size_is_read_exactly_or_refused_at_its_position(text, quoted):
    value = f'"{text}"' if quoted else text or "''"
    try:
        protocol = parse_protocol(MINIMAL.replace("frequency_hz: 5\n", f"frequency_hz: {value}\n"),
                                  "p.yaml")
    except PinArrayError as problem:
        assert_located_lines(str(problem).splitlines(), "p.yaml")
    else:
        assert 0 < protocol.stimulus("buzz").train.frequency_hz <= 1000


def test_a_billion_digit_exponent_is_refused_before_any_arithmetic():
    (line,) = problems(MINIMAL.replace("duration_s: 1\n", "duration_s: 1e1000000000\n"))
    assert line.startswith("p.yaml:5:17: expected a number of s for the signal length in at most")
    (line,) = problems(MINIMAL.replace("duration_s: 1\n", 'duration_s: "1e-1000000000"\n'))
    assert line.startswith("p.yaml:5:17:") and "exponent within ±100" in line


def test_a_huge_exponent_in_an_error_message_is_no_overflow():
    (line,) = problems(MINIMAL.replace("frequency_hz: 5\n", "frequency_hz: 1e90\n"))
    assert line == "p.yaml:4:19: expected the frequency of at most 1000 Hz, found 1e+90"


@pytest.mark.parametrize("tagged", ["!!bool maybe", "!!timestamp nope", "!!int 5.5", "!!null 3",
                                    "!!binary AAAA", "!foo 5", "!!set {a: 1}"])
def test_a_tag_that_does_not_fit_its_value_is_one_located_line(tagged):
    lines = problems(MINIMAL.replace("frequency_hz: 5\n", f"frequency_hz: {tagged}\n"))
    assert lines[0].startswith("p.yaml:4:19: expected ")


def test_a_mapping_where_a_pin_or_frequency_belongs_is_located():
    (line,) = problems(MINIMAL.replace("pins: [1, 2]", "pins: [1, {a: 1}]"))
    assert line == "p.yaml:9:13: expected a single value, found a mapping"
    (line,) = problems(MINIMAL.replace("frequencies_hz: [5]", "frequencies_hz: [[5]]"))
    assert line == "p.yaml:10:20: expected a single value, found a list"


def test_an_alias_bomb_is_refused_at_the_alias_past_the_limit():
    (line,) = problems(alias_bomb(levels=12, width=9))
    assert line == f"p.yaml:13:18: malformed YAML: more than {MAX_ALIASES} aliases"


def test_aliases_within_the_limit_are_read_one_level_at_a_time():
    # 9 levels of 9: expanded, 9^9 items; read, one problem per misplaced key or value.
    lines = problems(alias_bomb(levels=9, width=9))
    assert len(lines) == 13 and lines[-1] == ("p.yaml:10:5: expected a mapping for the design, "
                                              "found a list")


def test_an_anchor_used_inside_itself_is_refused():
    (line,) = problems("protocol: &a [*a]\n")
    assert line.startswith("p.yaml:1:15: malformed YAML: alias *a names no finished anchor")


def test_nesting_deeper_than_the_limit_is_refused_without_a_crash():
    # libyaml's composer recurses in C: 100 000 brackets would crash the interpreter.
    (line,) = problems("protocol: " + "[" * 100_000 + "]" * 100_000 + "\n")
    # the top-level mapping is the first level
    assert line == f"p.yaml:1:{10 + MAX_DEPTH}: malformed YAML: more than {MAX_DEPTH} levels of nesting"


def test_thousands_of_problems_list_the_first_hundred_and_count_the_rest():
    text = MINIMAL.replace("pins: [1, 2]", "pins: [" + ", ".join(["99"] * 300) + "]")
    lines = problems(text)
    assert len(lines) == MAX_PROBLEMS + 1
    assert lines[-1] == "p.yaml: 200 more problem(s) not listed; fix these first"


@pytest.mark.parametrize("text, expected", [
    ("device:\n  grid: [4, 4\n", "p.yaml:3:1: malformed YAML: expected ',' or ']', found the end of "
                                  "the file"),
    ("protocol: a: b\n", "p.yaml:1:12: malformed YAML: expected one 'key: value' per line, found "
                         "a second ':' (quote a value that holds ': ')"),
    ("protocol:\n\tname: x\n", "p.yaml:2:1: malformed YAML: expected a YAML value or the end of "
                              "one, found a tab (YAML indents with spaces)"),
    ("protocol: 'x\n", "p.yaml:2:1: malformed YAML: expected the closing quote, found the end of "
                       "the file"),
    ("protocol: [1, 2]]\n", "p.yaml:1:17: malformed YAML: expected a key, found ']'"),
])
def test_broken_yaml_says_what_was_expected_and_what_was_found_there(text, expected):
    (line,) = problems(text)
    assert line == expected


def test_a_second_document_in_the_file_is_refused():
    (line,) = problems(MINIMAL + "---\nprotocol: again\n")
    assert line == "p.yaml:11:1: malformed YAML: expected a single document, found a second one"


# -- files that are not text protocols ---------------------------------------------------------


def validate_lines(path: Path) -> list[str]:
    status, out, err = run("validate", str(path))
    assert status == 2 and out == ""
    return err.splitlines()


def test_a_protocol_saved_as_utf16_or_with_a_bom_validates(tmp_path):
    for encoding in ("utf-16", "utf-8-sig", "utf-32"):
        path = tmp_path / f"{encoding}.yaml"
        path.write_bytes(MINIMAL.replace("\n", "\r\n").encode(encoding))
        status, out, _ = run("validate", str(path))
        assert status == 0 and out.startswith(f"{path}: ok")


def test_crlf_line_ends_give_the_same_protocol_and_checksum(tmp_path):
    unix, windows = tmp_path / "unix.yaml", tmp_path / "windows.yaml"
    unix.write_bytes(MINIMAL.encode())
    windows.write_bytes(MINIMAL.replace("\n", "\r\n").encode())
    assert validate_file(unix)[0].sha256 == validate_file(windows)[0].sha256


def test_utf16_without_a_byte_order_mark_is_refused_at_the_first_nul(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_bytes(MINIMAL.encode("utf-16-le"))
    (line,) = validate_lines(path)
    assert line.startswith(f"{path}:1:2: expected UTF-8 text, found a NUL byte (a binary file, or "
                           "UTF-16 without a byte-order mark?")


def test_a_latin1_accent_is_refused_at_its_line_and_column(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_bytes(MINIMAL.replace("protocol: mini", "protocol: mini # café").encode("latin-1"))
    (line,) = validate_lines(path)
    assert line == f"{path}:1:21: expected UTF-8 text, found byte 0xe9 (save the file as UTF-8)"


def test_a_control_character_is_refused_where_it_is(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(MINIMAL.replace("stimulus: buzz", "stimulus: bu\x07zz"))
    (line,) = validate_lines(path)
    assert line == f"{path}:8:15: expected text, found the control character U+0007"


def test_a_folder_an_endless_device_and_a_large_file_are_one_line_each(tmp_path):
    large = tmp_path / "large.yaml"
    large.write_bytes(b"# padding\n" * (MAX_PROTOCOL_BYTES // 10 + 1))
    status, out, err = run("validate", str(tmp_path), "/dev/zero", str(large), "nowhere.yaml",
                           "protocols/demo.yaml")
    assert status == 2
    assert err.splitlines() == [
        f"{tmp_path}: expected a protocol file, found a folder",
        "/dev/zero: expected a protocol file, found a character device",
        f"{large}: expected a protocol file of at most 1,024 KiB, found 1,048,580 bytes",
        "nowhere.yaml: no such protocol file",
    ]
    assert out.startswith("protocols/demo.yaml: ok")  # the files after them are still checked


@contextlib.contextmanager
def fifo_with_a_writer(path: Path) -> Iterator[Path]:
    """A FIFO at ``path`` whose writer stays open and never writes."""
    os.mkfifo(path)
    writer = os.open(path, os.O_RDWR)  # O_RDWR: opening does not wait for a reader
    try:
        yield path
    finally:
        os.close(writer)


def pinarray_process(*argv: str) -> subprocess.CompletedProcess:
    """``pinarray ARGV`` in a process of its own (forked), where a hang fails the test: the
    timeout is a generous bound on a hang, not a timing check."""
    folder = Path(tempfile.mkdtemp(prefix="pinarray-fifo-"))
    try:
        return pinarray_forked(folder, *argv, timeout=60, cwd=REPO)
    finally:
        shutil.rmtree(folder)


def test_a_fifo_is_refused_at_once_whether_or_not_anyone_writes_to_it(tmp_path):
    silent = tmp_path / "silent.yaml"
    os.mkfifo(silent)
    with fifo_with_a_writer(tmp_path / "open.yaml") as held_open:
        result = pinarray_process("validate", str(silent), str(held_open), "protocols/demo.yaml")
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f"{silent}: expected a protocol file, found a FIFO (named pipe)",
        f"{held_open}: expected a protocol file, found a FIFO (named pipe)",
    ]
    assert result.stdout.startswith("protocols/demo.yaml: ok")


def test_an_answer_sheet_that_is_a_fifo_is_refused_before_any_run(tmp_path):
    with fifo_with_a_writer(tmp_path / "answers.csv") as sheet:
        result = pinarray_process("batch", "protocols/apparent_motion.yaml", "--subject", "01",
                                  "--responses", str(sheet), "--results", str(tmp_path / "out"))
    assert result.returncode == 2
    assert result.stderr == (f"pinarray: {sheet}: expected a responses file, found a FIFO "
                             "(named pipe)\n")
    assert not (tmp_path / "out").exists()


# -- designs too large to plan, compile or hold ------------------------------------------------


def test_a_design_of_more_trials_than_the_limit_is_refused_at_the_design():
    text = MINIMAL.replace("frequencies_hz: [5]", "frequencies_hz: [5]\n  repetitions: 1000\n"
                           "  blocks: 11")
    (line,) = problems(text)
    assert line == (f"p.yaml:7:3: expected a design of at most {MAX_TRIALS:,} trials, found "
                    "22,000 (2 conditions x 1000 repetitions x 11 blocks + 0 practice)")


def test_pins_times_frequencies_past_the_limit_are_refused_before_each_is_checked():
    text = MINIMAL.replace("pins: [1, 2]", "pins: [" + ", ".join(map(str, range(1, 17))) + "]")
    text = text.replace("frequencies_hz: [5]", "frequencies_hz: [" + ", ".join(["5"] * 1300) + "]")
    (line,) = problems(text)
    assert line.startswith("p.yaml:10:19: expected at most 20,000 conditions (pins x frequencies)")


def test_a_trial_of_more_pulses_than_the_limit_is_refused_at_its_frequency():
    text = ("device:\n  feasibility: scale\n" + MINIMAL).replace("duration_s: 1", "duration_s: 20000")
    (line,) = problems(text)
    assert line.startswith(f"p.yaml:12:20: expected at most {MAX_PULSES_PER_TRIAL:,} pulses in "
                           "one trial, found 1,000,001")


def test_a_plan_of_more_pulses_than_the_limit_is_refused_at_the_design():
    text = MINIMAL.replace("duration_s: 1", "duration_s: 10000").replace(
        "frequencies_hz: [5]", "frequencies_hz: [5]\n  repetitions: 101")
    (line,) = problems(text)
    assert line.startswith(f"p.yaml:7:3: expected a design of at most {MAX_PULSES:,} pulses in all")


def test_a_calibration_of_too_many_positions_is_refused():
    positions = ", ".join(f"{1 + i / 100}: 2048" for i in range(65))
    lines = problems("device:\n  calibration:\n    positions: {" + positions + "}\n" + MINIMAL)
    assert lines[0].startswith("p.yaml:3:16: expected at most 64 calibrated positions, found 65")


def test_every_seed_protocol_still_validates():
    for path in sorted(Path(__file__).resolve().parent.parent.joinpath("protocols").glob("*.yaml")):
        assert validate_file(path)[1] == []


def test_broken_pins_are_no_repeated_pins():
    lines = problems(textwrap.dedent(MINIMAL).replace("pins: [1, 2]", "pins: [1, x, y]"))
    assert lines == ["p.yaml:9:13: expected a whole number for a pin number, found 'x'",
                     "p.yaml:9:16: expected a whole number for a pin number, found 'y'"]


def test_a_design_whose_every_pin_is_wrong_is_no_index_error_in_the_ordering_check():
    text = MINIMAL.replace("pins: [1, 2]", "pins: [{a: 1}, 17]").replace(
        "frequencies_hz: [5]", "frequencies_hz: [5]\n  constraints: {no_repeat: [pin]}")
    assert problems(text) == ["p.yaml:9:10: expected a single value, found a mapping",
                              "p.yaml:9:18: expected a pin from 1 to 16 on the 4x4 grid, found 17"]


def test_a_wave_on_a_row_of_one_pin_is_refused():
    text = """\
    protocol: m
    device: {grid: {rows: 4, columns: 1}}
    stimuli:
      tap: {frequency_hz: 5, duration_s: 0.4}
      still: {wave: none, row: 1, train: tap}
    design: {paradigm: apparent_motion, configurations: [still]}
    """
    (line,) = problems(text)
    assert line == "p.yaml:5:28: expected a row of at least 2 pins for a wave, found 1"


# YAML 1.1 reads these as numbers other than the decimal they look like (or a YAML 1.2 reader
# and the lab would take them for): 1:00 is 60, 0x10 is 16, 017 is 15, 1_000 is 1000.
NOT_DECIMAL = ["1:00", "0x10", "017", "1_000", "0b101", "-0x1", "+017", "00", "1:30"]


@pytest.mark.parametrize("written", NOT_DECIMAL)
def test_a_whole_number_not_written_in_decimal_is_refused_at_its_value(written):
    (line,) = problems(MINIMAL + f"  repetitions: {written}\n")
    assert line == f"p.yaml:11:16: expected a decimal number, found {written!r}"


@pytest.mark.parametrize("written", [*NOT_DECIMAL, "1:30.5", "1_0.5", "!!int 0x10",
                                     "!!float 1:30.5"])
def test_a_number_not_written_in_decimal_is_refused_at_its_value(written):
    (line,) = problems(MINIMAL.replace("frequency_hz: 5\n", f"frequency_hz: {written}\n"))
    assert line == f"p.yaml:4:19: expected a decimal number, found {written.split()[-1]!r}"


def test_an_octal_number_in_the_yaml_1_2_style_is_refused_as_no_number():
    (line,) = problems(MINIMAL + "  repetitions: 0o17\n")
    assert line == "p.yaml:11:16: expected a whole number for repetitions, found '0o17'"


@pytest.mark.parametrize("written", ["5", "+5", "5.0", "5.", "05.0", "0.5e1", "50e-1", ".5e1",
                                     "5e0", "'5'", "10/2"])
def test_decimal_numbers_are_read_as_written(written):
    protocol = parse_protocol(MINIMAL.replace("frequency_hz: 5\n", f"frequency_hz: {written}\n")
                              + "  repetitions: +3\n", "p.yaml")
    assert protocol.stimulus("buzz").train.frequency_hz == 5
    assert protocol.design.repetitions == 3


def test_softness_samples_that_are_a_fifo_are_refused_at_once(tmp_path):
    with fifo_with_a_writer(tmp_path / "samples.csv") as samples:
        result = pinarray_process("softness", "fit", "--csv", str(samples))
    assert result.returncode == 2
    assert result.stderr == f"pinarray: {samples}: expected a samples file, found a FIFO (named pipe)\n"


def test_analyse_names_what_it_was_given_when_that_is_no_results_file(tmp_path):
    with fifo_with_a_writer(tmp_path / "beh.tsv") as fifo:
        result = pinarray_process("analyse", str(fifo), "--out", str(tmp_path / "out"))
    assert result.returncode == 2
    assert result.stderr == (f"pinarray: {fifo}: expected a results file or folder, found a FIFO "
                             "(named pipe)\n")
    assert not (tmp_path / "out").exists()


# -- times finer than a nanosecond ----------------------------------------------------------------

# Times inside the core are whole nanoseconds. A time written finer was rounded without a word:
# SOAs of ±0.0000001 ms both became 0, one stimulus, every row `soa 0` (issue 46's re-run).
FINER_THAN_A_NANOSECOND = {
    "an SOA of the temporal order": (
        "toj.yaml", "soas_ms: [-120, -60, -30, -15, 15, 30, 60, 120]", "soas_ms: [30, 30.0000001]",
        "30.0000001]", "expected an SOA in whole nanoseconds, found 30.0000001 ms"),
    "a wave's SOA": (
        "apparent_motion.yaml", "soa_ms: 200\n", "soa_ms: 200.0000001\n", "200.0000001",
        "expected the SOA in whole nanoseconds, found 200.0000001 ms"),
    "an adapted SOA": (
        "staircase_motion.yaml", "values: {from: 20, to: 300, step: 20}",
        "values: [20, 20.0000001, 40]", "20.0000001",
        "expected each SOA in whole nanoseconds, found 20.0000001 ms"),
    "the frames' SOA": (
        "shapes.yaml", "  across:", "  wipe: {frames: [rising, falling], soa_ms: 0.0000001}\n"
        "  across:", "0.0000001", "expected the frames' SOA in whole nanoseconds, found 1e-07 ms"),
    "the gap between two intervals": (
        "flutter_2ifc.yaml", "interval_gap_ms: 500", "interval_gap_ms: 500.0000001",
        "500.0000001", "expected the gap between the intervals in whole nanoseconds, found "
        "500.0000001 ms"),
    "the inter-trial interval": (
        "toj.yaml", "inter_trial_interval_s: 1.5", "inter_trial_interval_s: 1.5000000001",
        "1.5000000001", "expected the inter-trial interval in whole nanoseconds, found "
        "1.5000000001 s"),
    "the delivery tolerance": (
        "toj.yaml", "  calibration:", "  delivery_tolerance_ms: 0.0000001\n  calibration:",
        "0.0000001", "expected the delivery tolerance in whole nanoseconds, found 1e-07 ms"),
}


@pytest.mark.parametrize("case", FINER_THAN_A_NANOSECOND)
def test_a_time_finer_than_a_nanosecond_is_refused_where_it_is_written(case):
    name, old, new, at, said = FINER_THAN_A_NANOSECOND[case]
    text = (REPO / "protocols" / name).read_text()
    assert text.count(old) >= 1
    text = text.replace(old, new, 1)
    (line,) = problems(text)
    row = next(n for n, written in enumerate(text.splitlines(), start=1) if at in written)
    column = text.splitlines()[row - 1].index(at) + 1
    assert line == f"p.yaml:{row}:{column}: {said}"


def test_two_soas_a_nanosecond_would_make_one_are_refused_by_validate(tmp_path):
    path = tmp_path / "toj.yaml"
    path.write_text((REPO / "protocols" / "toj.yaml").read_text().replace(
        "soas_ms: [-120, -60, -30, -15, 15, 30, 60, 120]", "soas_ms: [-0.0000001, 0.0000001]"))
    (line,) = validate_lines(path)
    assert line == f"{path}:26:13: expected an SOA in whole nanoseconds, found -1e-07 ms"


# -- names a run's files cannot carry -------------------------------------------------------------

NAME_RULE = ("expected a protocol name of ASCII letters and digits (they make the BIDS task label "
             "in its runs' file names) and ASCII spaces and punctuation (dropped from it)")

# The protocol's name is its runs' task label, in every file name: validate refuses what no run
# could write (a 300-character name passed, and batch then failed with "File name too long",
# leaving a dataset's first files behind: issue 46's re-run).
@pytest.mark.parametrize(("name", "said"), [
    ("t" * (MAX_TASK_LABEL_CHARS + 1),
     f"expected a protocol name of at most {MAX_TASK_LABEL_CHARS} letters and digits (its runs' "
     f"task label, in file names of at most 255 bytes), found {MAX_TASK_LABEL_CHARS + 1}"),
    ("café", f"{NAME_RULE}, found 'café': U+00E9 (LATIN SMALL LETTER E WITH ACUTE) is none "
             "of them"),
    ("'!!!'", f"{NAME_RULE}, found '!!!': no letter nor digit"),
    # Issue 46's fourth pass: these were dropped from the task label without a word.
    ("toj\u0301", f"{NAME_RULE}, found 'toj\u0301': U+0301 (COMBINING ACUTE ACCENT) "
                   "is none of them"),
    ("toj \U0001F642", f"{NAME_RULE}, found 'toj \U0001F642': U+1F642 (SLIGHTLY "
                        "SMILING FACE) is none of them"),
    ("'to\u200bj'", f"{NAME_RULE}, found 'to\\u200bj': U+200B (ZERO WIDTH SPACE) is "
                     "none of them"),
    ('"to\\0j"', f"{NAME_RULE}, found 'to\\x00j': U+0000 (a control character) is none "
                   "of them"),
    ('"to\\tj"', f"{NAME_RULE}, found 'to\\tj': U+0009 (a control character) is none of "
                   "them"),
    ('"to\\nj"', f"{NAME_RULE}, found 'to\\nj': U+000A (a control character) is none of "
                   "them"),
], ids=["one letter too long", "not ASCII", "no letter nor digit", "combining accent",
       "emoji", "zero-width space", "NUL", "tab", "newline"])
def test_a_protocol_name_no_run_could_carry_in_its_file_names_is_refused_by_validate(
        tmp_path, name, said):
    path = short_copy("toj", tmp_path, ("protocol: toj", f"protocol: {name}"))
    (line,) = validate_lines(path)
    assert line == f"{path}:5:11: {said}"


def test_the_longest_task_label_validate_accepts_is_one_a_run_writes(tmp_path):
    path = short_copy("toj", tmp_path, ("protocol: toj", "protocol: " + "t" * MAX_TASK_LABEL_CHARS))
    status, _, err = run("batch", str(path), "--subject", "1", "--observer", "default",
                         "--seed", "1", "--results", str(tmp_path / "results"))
    assert status == 0, err
    (sidecar,) = (tmp_path / "results").rglob("*_recording-motion_physio.json")
    # written under a temporary name 14 bytes longer: the longest a run's file has
    assert len(sidecar.name) + 14 == 255


def test_batch_refuses_labels_too_long_for_a_file_name_before_writing_anything(tmp_path):
    path = short_copy("toj", tmp_path, ("protocol: toj", "protocol: " + "t" * MAX_TASK_LABEL_CHARS))
    results = tmp_path / "results"
    status, out, err = run("batch", str(path), "--subject", "12", "--observer", "default",
                           "--results", str(results))
    assert (status, out) == (2, "")
    assert err == (f"pinarray: expected labels that fit a file name of at most 255 bytes, found "
                   f"the subject label of 2 characters, the session's of 1 and the task's of "
                   f"{MAX_TASK_LABEL_CHARS}: the run's longest file name would be 256 bytes; "
                   f"shorten the subject label or the protocol's name\n")
    assert not results.exists()  # not even the dataset's first files
    # A subject label too long for any protocol: the same, in a dataset that has runs already.
    run("batch", str(short_copy("toj", tmp_path)), "--subject", "1", "--observer", "default",
        "--results", str(results))
    before = {p: p.read_bytes() for p in results.rglob("*") if p.is_file()}
    status, _, err = run("batch", str(short_copy("toj", tmp_path)), "--subject", "a" * 300,
                         "--observer", "default", "--results", str(results))
    assert status == 2 and "the subject label of 300 characters" in err
    assert {p: p.read_bytes() for p in results.rglob("*") if p.is_file()} == before
