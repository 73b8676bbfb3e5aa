"""Protocol files as a lab member writes them: what is accepted, and every mistake located."""

import subprocess
import sys
import textwrap
from fractions import Fraction
from pathlib import Path

import pytest

from pinarray.errors import ProtocolErrors
from pinarray.protocol import WaveKind
from pinarray.protocol.load import load_protocol, parse_protocol
from tests.commands import pinarray_here

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"

MINIMAL = """\
protocol: mini
stimuli:
  buzz:
    frequency_hz: 5
    duration_s: 1
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 2]
  frequencies_hz: [5]
"""


def problems(text: str) -> list[str]:
    with pytest.raises(ProtocolErrors) as caught:
        parse_protocol(textwrap.dedent(text), "p.yaml")
    return [e.located() for e in caught.value.errors]


def test_the_seed_localisation_protocol_is_8_pins_by_3_frequencies_of_10_s():
    protocol = load_protocol(PROTOCOLS / "localisation.yaml")
    design = protocol.design
    assert design.paradigm.name == "localisation"
    assert {c.pin for c in design.conditions} == {1, 4, 6, 7, 10, 11, 13, 16}
    assert {c.frequency_hz for c in design.conditions} == {3, 5, 10}
    train = protocol.stimulus("seed_train").train
    # "5 pulses of 1.5 ms and five pulses of 2 ms" per cycle, 10 s
    assert (train.pulses_per_cycle, train.up_pulses) == (10, 5)
    assert (train.up_width_ns, train.down_width_ns) == (2_000_000, 1_500_000)
    assert train.duration_ns == 10_000_000_000
    assert len(protocol.sha256) == 64


def test_the_seed_apparent_motion_protocol_has_three_configurations_on_one_row():
    protocol = load_protocol(PROTOCOLS / "apparent_motion.yaml")
    directions = [c.kind for c in protocol.design.conditions]
    assert directions == [WaveKind.RIGHTWARDS, WaveKind.LEFTWARDS, WaveKind.NONE]
    assert {c.row for c in protocol.design.conditions} == {2}
    assert protocol.design.blocks == 2 and protocol.design.repetitions == 2
    # one SOA for all three, so that none lasts longer than another (no duration cue)
    assert {protocol.stimulus(c.stimulus).wave.soa_ns for c in protocol.design.conditions} == {
        200_000_000}


def test_the_demo_touches_all_16_pins_in_under_a_minute():
    protocol = load_protocol(PROTOCOLS / "demo.yaml")
    design = protocol.design
    pins = [c.pin for c in design.conditions]
    assert sorted(pins) == list(range(1, 17))
    total_ns = sum(
        protocol.stimulus(c.stimulus).train.duration_ns + design.inter_trial_interval_ns
        for c in design.conditions
    )
    assert total_ns < 60 * 10**9


def test_defaults_give_pin_n_to_servo_n_and_the_seed_pulse_widths():
    protocol = parse_protocol(MINIMAL)
    assert [c.servo_id for c in protocol.device.pins] == list(range(1, 17))
    train = protocol.stimulus("buzz").train
    assert train.frequency_hz == 5 and train.duty_cycle == Fraction(1, 2)


def test_decimals_are_exact_and_fractions_are_accepted():
    protocol = parse_protocol(
        MINIMAL.replace("frequency_hz: 5", 'frequency_hz: "1/3"').replace(
            "duration_s: 1", "duration_s: 30"
        )
    )
    assert protocol.stimulus("buzz").train.frequency_hz == Fraction(1, 3)
    protocol = parse_protocol(
        MINIMAL.replace("frequency_hz: 5", "frequency_hz: 0.1").replace(
            "duration_s: 1", "duration_s: 20"
        )
    )
    assert protocol.stimulus("buzz").train.frequency_hz == Fraction(1, 10)


def test_a_quoted_number_is_read_as_the_number_it_writes_whole_or_not():
    # A spreadsheet or a colleague may quote any number: "1/3" is read exactly, and so is a
    # quoted count (hostile pass on issue 45, finding 11d: pitch_mm: "2" was read, but
    # repetitions: "10" refused).
    plain = parse_protocol(MINIMAL + "  repetitions: 10\n  seed: 7\n", "p.yaml")
    quoted = parse_protocol(MINIMAL.replace("pins: [1, 2]", "pins: ['1', \"2\"]")
                            .replace("[5]", "['5']") + "  repetitions: \"10\"\n  seed: ' 7'\n",
                            "p.yaml")
    assert quoted.design == plain.design and quoted.design.repetitions == 10
    assert problems(MINIMAL + "  repetitions: '10.5'\n  blocks: '1_0'\n") == [
        "p.yaml:11:16: expected a whole number for repetitions, found '10.5'",
        "p.yaml:12:11: expected a whole number for blocks, found '1_0'"]


def test_a_phase_beyond_360_degrees_wraps_onto_the_cycle():
    protocol = parse_protocol(MINIMAL.replace("duration_s: 1", "duration_s: 1\n    phase_deg: 450"))
    assert protocol.stimulus("buzz").train.phase == Fraction(1, 4)


@pytest.mark.parametrize(
    ("old", "new", "where", "message"),
    [
        (
            "frequency_hz: 5\n",
            "frequncy_hz: 5\n",
            "4:5",
            "expected a key of the pulse train, found 'frequncy_hz'; did you mean "
            "'frequency_hz'?",
        ),
        ("frequency_hz: 5\n", "frequency_hz: .nan\n", "4:19", "expected a finite number of Hz"),
        ("frequency_hz: 5\n", "frequency_hz: -.inf\n", "4:19", "expected a finite number of Hz"),
        (
            "frequency_hz: 5\n",
            "frequency_hz: 0\n",
            "4:19",
            "expected the frequency more than 0 Hz, found 0",
        ),
        (
            "duration_s: 1\n",
            "duration_s: -2\n",
            "5:17",
            "expected the signal length more than 0 s, found -2",
        ),
        ("duration_s: 1\n", "duration_s: 1e9\n", "5:17", "at most 172800 s"),
        (
            "duration_s: 1\n",
            "duration_s: ten\n",
            "5:17",
            "expected a number of s for the signal length, found 'ten'",
        ),
        (
            "pins: [1, 2]",
            "pins: [1, 99]",
            "9:13",
            "expected a pin from 1 to 16 on the 4x4 grid, found 99",
        ),
        (
            "stimulus: buzz",
            "stimulus: bzz",
            "8:13",
            "expected the name of a pulse train, found 'bzz'; did you mean 'buzz'?",
        ),
        (
            "paradigm: localisation",
            "paradigm: localization",
            "7:13",
            "did you mean 'localisation'?",
        ),
        (
            "duration_s: 1\n",
            "duration_s: 1\n    duty_cycle: 0.33\n",
            "6:17",
            "whole number of the 10 pulses",
        ),
        (
            "duration_s: 1\n",
            "duration_s: 1\n    duty_cycle: 1\n",
            "6:17",
            "strictly between 0 and 1",
        ),
        (
            "duration_s: 1\n",
            "duration_s: 1\n    pulse_width_ms: {up: 30, down: 1.5}\n",
            "6:21",
            "expected pulse widths within the pulse period, found the up pulse of 30 ms, which "
            "does not fit the 20 ms period",
        ),
        ("pins: [1, 2]", "pins: 1", "9:9", "expected a list for the pins, found '1'"),
    ],
)
def test_each_mistake_is_reported_at_its_line_and_column(old, new, where, message):
    assert old in MINIMAL
    (line,) = problems(MINIMAL.replace(old, new, 1))
    assert line.startswith(f"p.yaml:{where}: ")
    assert message in line


def test_all_problems_of_a_file_are_reported_together():
    text = MINIMAL.replace("frequency_hz: 5\n", "frequency_hz: .nan\n", 1).replace(
        "pins: [1, 2]", "pins: [1, 17]"
    )
    lines = problems(text)
    assert [line.split(": ")[0] for line in lines] == ["p.yaml:4:19", "p.yaml:9:13"]


def test_malformed_yaml_and_duplicate_keys_are_located():
    (line,) = problems("protocol: x\nstimuli: [1,\n")
    assert line.startswith("p.yaml:3:1: malformed YAML")
    lines = problems(MINIMAL.replace("protocol: mini\n", "protocol: mini\nprotocol: again\n"))
    assert lines[0] == ("p.yaml:2:1: expected each key once in the protocol, found 'protocol' "
                        "again (first at line 1)")
    lines = problems(MINIMAL.replace("  paradigm:", "  blocks: 2\n  blocks: 3\n  paradigm:"))
    assert lines == ["p.yaml:8:3: expected each key once in the design, found 'blocks' again "
                     "(first at line 7)"]


def test_a_servo_response_file_beside_the_protocols_is_said_to_be_one_not_a_broken_protocol():
    # `servos response` writes PROTOCOL_response_pinN.yaml beside the protocol: a lab's
    # `pinarray validate protocols/*.yaml` then meets it.
    response = ("# pinarray servos response: pin 6\npin: 6\nservo: STS3215\nspeed_steps_per_s: 3000\n"
                "cycles: 10\npoints:\n  - {frequency_hz: 10.0, stroke_commanded_steps: 65}\n")
    assert problems(response) == [
        "p.yaml:2:1: expected a protocol (protocol:, stimuli:, design:), found a servo response file "
        "(`pinarray servos response` writes it; a protocol names it under device: response)"]


def test_a_tab_indenting_a_line_is_said_once_as_the_tab_it_is():
    (line,) = problems("protocol: x\n\tstimuli:\n")
    assert line == "p.yaml:2:1: malformed YAML: expected spaces to indent, found a tab (YAML indents with spaces)"


@pytest.mark.parametrize(("text", "found"), [
    ("", "an empty file"), ("\n  \n", "an empty file"),
    ("# nothing yet\n\n", "only comments and blank lines")])
def test_an_empty_file_is_a_clear_error_at_its_first_line(text, found):
    (line,) = problems(text)
    assert line == ("p.yaml:1:1: expected a protocol mapping (protocol:, stimuli:, design:), "
                    f"found {found}")


def test_a_stroke_the_servo_cannot_follow_is_refused_with_what_is_achievable():
    text = MINIMAL.replace("frequencies_hz: [5]", "frequencies_hz: [5, 40]").replace(
        "duration_s: 1", "duration_s: 1\n    pulse_width_ms: {up: 2.0, down: 1.5}"
    )
    (line,) = problems(text)
    assert line.startswith("p.yaml:11:")  # the 40 Hz entry
    assert "pin 1 cannot follow 40 Hz" in line
    assert "needs at most 13.16 Hz" in line  # 114 steps at 3000 steps/s: 38 ms per half-cycle
    assert "only 38 steps" in line  # 12.5 ms x 3000 steps/s = 37.5 steps


def test_a_protocol_may_ask_for_infeasible_strokes_to_be_scaled_instead():
    text = ("device:\n  feasibility: scale\n" + MINIMAL).replace(
        "frequencies_hz: [5]", "frequencies_hz: [40]"
    )
    protocol = parse_protocol(text)
    assert protocol.device.scale_infeasible


def test_an_impossible_ordering_constraint_is_reported_at_validation():
    text = MINIMAL.replace("pins: [1, 2]", "pins: [1]").replace(
        "frequencies_hz: [5]", "frequencies_hz: [3, 5]\n  constraints:\n    no_repeat: [pin]"
    )
    (line,) = problems(text)
    assert line.startswith("p.yaml:12:")
    assert ("expected order constraints a shuffle can meet, found pin 1 on 2 of the 2 trials "
            "shuffled together: with runs of at most 1, the other 0 can separate at most 1") in line


def test_a_no_wave_needs_a_central_pin():
    text = """\
    protocol: m
    stimuli:
      tap: {frequency_hz: 5, duration_s: 0.4}
      still: {wave: none, row: 1, train: tap}
    design: {paradigm: apparent_motion, configurations: [still]}
    """
    (line,) = problems(text)
    assert "expected an odd number of pins, found 4" in line and line.startswith("p.yaml:4:")


def test_validate_prints_ok_or_located_lines_and_exits_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(MINIMAL.replace("pins: [1, 2]", "pins: [1, 17]"))
    result = subprocess.run(
        [sys.executable, "-m", "pinarray", "validate", str(PROTOCOLS / "demo.yaml"), str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stdout.startswith(f"{PROTOCOLS / 'demo.yaml'}: ok")
    assert result.stderr == f"{bad}:9:13: expected a pin from 1 to 16 on the 4x4 grid, found 17\n"


# That validate loads neither the UI nor plotting (nor any heavy library it does not need) is
# checked in fresh processes by tests/test_startup.py and tests/test_compile_outputs.py.


def test_a_missing_file_is_one_line():
    result = pinarray_here("validate", "nowhere.yaml")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "nowhere.yaml: no such protocol file" in result.stderr


def test_compile_writes_every_pulse_of_every_trial_numbered_as_in_the_plan(tmp_path):
    import csv

    from pinarray.cli import main
    from pinarray.plan import make_plan

    out = tmp_path / "pulses.csv"
    assert main(["compile", str(PROTOCOLS / "demo.yaml"), "--seed", "4", "--out", str(out)]) == 0
    with out.open() as stream:
        rows = list(csv.reader(stream))
    assert rows[0] == ["trial", "pin", "start_ns", "width_ns"]
    plan = make_plan(load_protocol(PROTOCOLS / "demo.yaml"), 4)
    pins_by_trial = {int(r[0]): int(r[1]) for r in rows[1:]}
    assert pins_by_trial == {t.trial: t.condition.pin for t in plan.trials}
    assert len(rows) - 1 == 16 * 100  # 2 s x 5 Hz x 10 pulses per pin


def test_preview_draws_a_text_timeline_and_a_png(tmp_path, capsys):
    from pinarray.cli import main

    png = tmp_path / "t.png"
    assert (
        main(
            [
                "preview",
                str(PROTOCOLS / "apparent_motion.yaml"),
                "--trial",
                "2",
                "--seed",
                "1",
                "--png",
                str(png),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "pin  5 |" in out and "pin  7 |" in out and "#" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


DEVICE = """\
device:
  calibration:
    rest_steps: 2048
    positions: {1.5: 2048, 2.0: 2162}
    limits_steps: [2000, 2200]
  pins:
    4: {positions: {1.5: 2048, 2.0: 2150}}
  servo_ids: {16: 20}
"""


def test_per_pin_calibration_and_servo_ids_override_the_shared_ones():
    device = parse_protocol(DEVICE + MINIMAL).device
    assert device.calibration(4).position_for_width(2_000_000) == 2150
    assert device.calibration(3).position_for_width(2_000_000) == 2162
    assert (device.calibration(16).servo_id, device.calibration(15).servo_id) == (20, 15)
    assert (device.calibration(1).min_steps, device.calibration(1).max_steps) == (2000, 2200)


def test_without_limits_a_pin_may_only_reach_its_calibrated_positions():
    device = parse_protocol(MINIMAL).device
    assert (device.calibration(7).min_steps, device.calibration(7).max_steps) == (2048, 2162)


def test_calibration_outside_the_limits_and_shared_servo_ids_are_refused():
    lines = problems(
        DEVICE.replace("2.0: 2150", "2.0: 2300").replace("{16: 20}", "{16: 3}") + MINIMAL
    )
    assert (
        lines[0].startswith("p.yaml:7:")
        and "pin 4: expected its position within its limits [2000, 2200] steps, found 2300"
        in lines[0]
    )
    assert (
        lines[1].startswith("p.yaml:8:")
        and "expected one pin for each servo id, found 3 driving both pin 3 and pin 16" in lines[1]
    )


def test_wave_pins_get_the_same_checks_as_a_localisation_train():
    text = """\
    protocol: m
    stimuli:
      tap: {frequency_hz: 40, duration_s: 0.4}
      right: {wave: rightwards, row: 1, train: tap}
    design: {paradigm: apparent_motion, configurations: [right]}
    """
    (line,) = problems(text)
    assert line.startswith("p.yaml:4:") and "pin 1 cannot follow 40 Hz" in line


def test_a_wave_without_an_soa_gets_the_tactile_brush_one():
    text = textwrap.dedent("""\
    protocol: m
    stimuli:
      tap: {frequency_hz: 5, duration_s: 0.4}
      right: {wave: rightwards, row: 1, pins: [1, 2, 3], train: tap}
    design: {paradigm: apparent_motion, configurations: [right]}
    """)
    # 0.32 x 400 ms + 47.3 ms
    assert parse_protocol(text, "p.yaml").stimulus("right").wave.soa_ns == 175_300_000


def test_a_no_wave_whose_centre_taps_overlap_is_refused_at_validation():
    text = """\
    protocol: m
    stimuli:
      tap: {frequency_hz: 5, duration_s: 0.4}
      still: {wave: none, row: 1, pins: [1, 2, 3], train: tap, soa_ms: 100}
    design: {paradigm: apparent_motion, configurations: [still]}
    """
    (line,) = problems(text)
    assert line.startswith("p.yaml:4:") and ("expected one train at a time on each pin, found "
                                             "pin 2 driven twice at once") in line


def test_yaml_tags_and_impossible_dates_are_located_errors_not_tracebacks():
    (line,) = problems(MINIMAL.replace("frequency_hz: 5\n", "frequency_hz: !!python/name:os.system 5\n"))
    assert line.startswith("p.yaml:4:19: expected a plain value")
    (line,) = problems(MINIMAL.replace("duration_s: 1\n", "duration_s: 2024-13-45\n"))
    assert line.startswith("p.yaml:5:17: expected a plain value")


def seed_localisation_with(*edits: tuple[str, str]) -> str:
    """protocols/localisation.yaml with each (old, new) edit made (each old text is there)."""
    text = (PROTOCOLS / "localisation.yaml").read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    return text


def test_every_independent_problem_is_reported_in_one_pass():
    # A misspelt key in the train, a duty cycle of 0.55, a stimulus name mistyped and an
    # interval written "2s": each was hidden behind the one before it.
    text = seed_localisation_with(("    duration_s: 10", "    duraton_s: 10"),
                                  ("    duty_cycle: 0.5 ", "    duty_cycle: 0.55"),
                                  ("  stimulus: seed_train", "  stimulus: seed_trian"),
                                  ("  inter_trial_interval_s: 3", "  inter_trial_interval_s: 2s"))
    found = problems(text)
    assert len(found) == 4, found
    assert ("expected a key of the pulse train, found 'duraton_s'; did you mean 'duration_s'?"
            in found[0])
    assert "duty cycle that is a whole number of the 10 pulses per cycle, found 0.55" in found[1]
    # Its train is broken, yet still the name meant:
    assert "found 'seed_trian'; did you mean 'seed_train'?" in found[2]
    assert "found '2s'" in found[3]


def test_a_typo_in_the_device_section_does_not_hide_the_designs_problems():
    text = seed_localisation_with(("    baud_rate: 1000000", "    baud_rat: 1000000"),
                                  ("  repetitions: 1", "  repetitions: 0"),
                                  ("13, 16]", "13, 17]"))
    found = problems(text)
    assert [line.split(": ", 1)[1] for line in found] == [
        "expected a key of the servo section, found 'baud_rat'; did you mean 'baud_rate'?",
        "expected a pin from 1 to 16 on the 4x4 grid, found 17",
        "expected repetitions of at least 1, found 0"]


def test_a_constraint_on_an_attribute_the_paradigms_trials_lack_is_refused_with_theirs():
    text = seed_localisation_with(("no_repeat: [pin]", "no_repeat: [direction]"))
    (line,) = problems(text)
    assert line.endswith("expected an attribute localisation trials have (pin, frequency_hz, "
                         "stimulus), found 'direction'")


def test_a_misspelt_servo_key_is_reported_alone_not_with_problems_of_the_default_it_left():
    # Misspelt, the servo's speed falls back to the default: whether pins can follow 20 Hz is
    # not judged on a speed nobody wrote (the design's other problems still are).
    text = seed_localisation_with(("    speed_steps_per_s: 3000", "    sped_steps_per_s: 3000"),
                                  ("frequencies_hz: [3, 5, 10]", "frequencies_hz: [3, 5, 10, 20]"),
                                  ("  repetitions: 1", "  repetitions: 0"))
    found = [line.split(": ", 1)[1] for line in problems(text)]
    assert found == ["expected a key of the servo section, found 'sped_steps_per_s'; did you "
                     "mean 'speed_steps_per_s'?", "expected repetitions of at least 1, found 0"]
