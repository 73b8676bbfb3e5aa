"""A pin's calibration written into a protocol file: the values change, nothing else does."""

import codecs
import difflib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.cli.calibration_file import new_calibration, plan_calibration, rewrite_calibration
from pinarray.errors import PinArrayError, ProtocolError
from pinarray.protocol import PinCalibration
from pinarray.protocol.load import parse_protocol
from pinarray.text_files import decode_text

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
REST_OF_FILE = """\
stimuli: {buzz: {frequency_hz: 1, duration_s: 1}}   # a slow buzz
design: {paradigm: localisation, stimulus: buzz, pins: [1], frequencies_hz: [1]}
"""
DEVICE = """\
protocol: bench   # name
device:
  calibration:               # every pin
    rest_steps: 2048
    positions:
      1.5: 2048   # down
      1.75: 2100  # half-way
      2.0: 2162   # up
    limits_steps: [2000, 2200]
  pins:                          # ...unless overridden for one pin
    4: {rest_steps: 2050, positions: {1.5: 2050, 1.75: 2105, 2.0: 2160}}   # re-horned
    6:
      rest_steps: 2040   # measured 2024-05-01
      # positions: as every pin
      lever_mm: 5
    7: {lever_mm: 5}
    8: {}
  servo_ids: {16: 20}
""" + REST_OF_FILE


def calibrate(text: str, pin: int, rest: int, up: int, encode=lambda t: t.encode()) -> str:
    """The file after calibrating ``pin``, as text (its original encoding decoded)."""
    data = encode(text)
    protocol = parse_protocol(decode_text(data), "bench.yaml")
    new = plan_calibration(data, protocol, pin, rest, up)
    return rewrite_calibration(data, protocol, new).decode(_encoding(data))


def _encoding(data: bytes) -> str:
    if data.startswith(codecs.BOM_UTF16_LE):
        return "utf-16"
    return "utf-8-sig" if data.startswith(codecs.BOM_UTF8) else "utf-8"


def changed_lines(before: str, after: str) -> tuple[list[str], list[str]]:
    """(lines removed, lines added)."""
    diff = list(difflib.ndiff(before.splitlines(True), after.splitlines(True)))
    return ([d[2:] for d in diff if d.startswith("- ")], [d[2:] for d in diff if d.startswith("+ ")])


def comments(text: str) -> list[str]:
    return [line[line.index("#"):] for line in text.splitlines() if "#" in line]


def calibration(text: str, pin: int) -> PinCalibration:
    return parse_protocol(text, "bench.yaml").device.calibration(pin)


def test_a_pin_with_its_own_flow_entry_gets_new_numbers_in_place():
    after = calibrate(DEVICE, 4, 2000, 2100)
    removed, added = changed_lines(DEVICE, after)
    assert removed == ["    4: {rest_steps: 2050, positions: {1.5: 2050, 1.75: 2105, 2.0: 2160}}"
                       "   # re-horned\n"]
    assert added == ["    4: {rest_steps: 2000, positions: {1.5: 2000, 1.75: 2050, 2.0: 2100}}"
                     "   # re-horned\n"]


def test_a_block_entry_keeps_its_comments_and_gets_the_missing_keys_at_its_indentation():
    after = calibrate(DEVICE, 6, 2010, 2130)
    removed, added = changed_lines(DEVICE, after)
    assert removed == ["      rest_steps: 2040   # measured 2024-05-01\n"]
    assert added == ["      rest_steps: 2010   # measured 2024-05-01\n",
                     "      positions: {1.5: 2010, 1.75: 2065, 2.0: 2130}\n"]
    assert "      # positions: as every pin\n      lever_mm: 5\n" in after
    assert calibration(after, 6) == PinCalibration(
        6, 6, 2010, 2000, 2200, ((1_500_000, 2010), (1_750_000, 2065), (2_000_000, 2130)), 5.0)


@pytest.mark.parametrize("pin, before, after_line", [
    (7, "    7: {lever_mm: 5}\n",
     "    7: {lever_mm: 5, rest_steps: 2030, positions: {1.5: 2030, 1.75: 2076, 2.0: 2130}}\n"),
    (8, "    8: {}\n", "    8: {rest_steps: 2030, positions: {1.5: 2030, 1.75: 2076, 2.0: 2130}}\n"),
])
def test_flow_entries_get_the_missing_keys_inside_their_braces(pin, before, after_line):
    removed, added = changed_lines(DEVICE, calibrate(DEVICE, pin, 2030, 2130))
    assert (removed, added) == ([before], [after_line])


def test_a_pin_with_no_entry_gets_one_after_the_last_pin():
    after = calibrate(DEVICE, 9, 2030, 2130)
    removed, added = changed_lines(DEVICE, after)
    assert removed == []
    assert added == ["    9: {rest_steps: 2030, positions: {1.5: 2030, 1.75: 2076, 2.0: 2130}}\n"]
    assert after.index("    9:") > after.index("    8: {}") and after.index("    9:") < after.index(
        "  servo_ids")


def test_the_seed_protocol_gets_a_pins_section_and_keeps_every_line_and_comment():
    text = (PROTOCOLS / "localisation.yaml").read_text()
    after = calibrate(text, 6, 2040, 2150)
    removed, added = changed_lines(text, after)
    assert removed == []
    assert added == ["  pins:\n", "    6: {rest_steps: 2040, positions: {1.5: 2040, 2.0: 2150}}\n"]
    assert calibration(after, 6).positions_by_width_ns == ((1_500_000, 2040), (2_000_000, 2150))
    assert calibration(after, 7) == calibration(text, 7)


def test_a_protocol_without_a_device_section_gets_one_and_its_limits_follow_the_positions():
    text = "protocol: bare   # nothing calibrated yet\n" + REST_OF_FILE
    after = calibrate(text, 3, 2000, 2100)
    assert changed_lines(text, after) == (
        [], ["device:\n", "  pins:\n", "    3: {rest_steps: 2000, positions: {1.5: 2000, 2.0: 2100}}\n"])
    assert (calibration(after, 3).min_steps, calibration(after, 3).max_steps) == (2000, 2100)


def test_limits_the_file_gives_are_widened_only_as_far_as_the_new_positions_need():
    after = calibrate(DEVICE, 4, 1990, 2100)
    assert "4: {rest_steps: 1990, positions: {1.5: 1990, 1.75: 2045, 2.0: 2100}, " \
           "limits_steps: [1990, 2200]}" in after
    after = calibrate(DEVICE, 6, 2010, 2250)
    assert "      limits_steps: [2000, 2250]\n" in after
    assert calibration(after, 5) == calibration(DEVICE, 5)


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_line_ends_of_the_file_are_kept(newline):
    text = DEVICE.replace("\n", newline)
    after = calibrate(text, 9, 2030, 2130)
    assert after.count(newline) == text.count(newline) + 1
    if newline == "\r":
        assert "\n" not in after
    else:
        assert after.replace("\r\n", "").count("\n") == 0


@pytest.mark.parametrize("encode", [
    lambda t: codecs.BOM_UTF8 + t.encode(),
    lambda t: t.encode("utf-16"),  # with its byte-order mark, as Windows Notepad saves it
])
def test_byte_order_mark_and_encoding_are_kept(encode):
    text = DEVICE.replace("# name", "# réglé à 20 °C")
    data = encode(text)
    protocol = parse_protocol(decode_text(data), "bench.yaml")
    edited = rewrite_calibration(data, protocol, plan_calibration(data, protocol, 4, 2000, 2100))
    assert edited[:2] == data[:2]
    after = edited.decode(_encoding(data))
    assert "# réglé à 20 °C" in after and "rest_steps: 2000" in after


def test_a_calibration_shared_through_an_alias_is_not_edited_behind_the_other_pins_back():
    text = DEVICE.replace("    7: {lever_mm: 5}", "    7: &same {lever_mm: 5}\n    9: *same")
    with pytest.raises(ProtocolError) as caught:
        calibrate(text, 7, 2030, 2130)
    assert caught.value.line == 16 and "YAML alias" in str(caught.value)


def test_positions_the_stimuli_cannot_follow_are_refused_with_the_reason():
    text = (PROTOCOLS / "localisation.yaml").read_text()
    with pytest.raises(PinArrayError, match="not written: with pin 7 at rest 1990 and up 2400 "
                                            "steps the protocol would be invalid: pin 7 cannot "
                                            "follow"):
        calibrate(text, 7, 1990, 2400)


# -- the new calibration's numbers ------------------------------------------------------------

OLD = PinCalibration(4, 4, 2048, 2000, 2200,
                     ((1_500_000, 2048), (1_600_000, 2080), (1_750_000, 2100), (2_000_000, 2162)))


@settings(max_examples=300, deadline=None)
@given(rest=st.integers(0, 4095), up=st.integers(0, 4095), limits_given=st.booleans())
def test_rest_and_up_land_on_the_narrowest_and_widest_widths_and_the_rest_keep_their_place(
        rest, up, limits_given):
    if rest == up:
        with pytest.raises(PinArrayError, match="would not move"):
            new_calibration(OLD, rest, up, limits_given)
        return
    new = new_calibration(OLD, rest, up, limits_given)
    steps = [p for _, p in new.positions]
    assert [w for w, _ in new.positions] == [w for w, _ in OLD.positions_by_width_ns]
    assert (steps[0], steps[-1], new.rest_steps) == (rest, up, rest)
    assert steps == sorted(steps) or steps == sorted(steps, reverse=True)  # still in order
    low, high = new.limits_steps
    assert low <= min(steps) and max(steps) <= high
    if limits_given:
        assert low <= OLD.min_steps and OLD.max_steps <= high
        assert new.limits_widened == ((low, high) != (OLD.min_steps, OLD.max_steps))
    else:
        assert (low, high) == (min(steps), max(steps)) and not new.limits_widened


@settings(max_examples=60, deadline=None)
@given(pin=st.sampled_from([1, 4, 6, 7, 8, 9, 16]), rest=st.integers(1900, 2100),
       stroke=st.integers(20, 150))
def test_any_calibration_reads_back_exactly_and_keeps_every_comment(pin, rest, stroke):
    after = calibrate(DEVICE, pin, rest, rest + stroke)
    assert comments(after) == comments(DEVICE)
    # Each file read once, every pin's calibration taken from it.
    device_after, device_before = (parse_protocol(text, "bench.yaml").device
                                   for text in (after, DEVICE))
    got = device_after.calibration(pin)
    assert (got.rest_steps, got.positions_by_width_ns[-1][1]) == (rest, rest + stroke)
    others = [p for p in range(1, 17) if p != pin]
    assert [device_after.calibration(p) for p in others] == [
        device_before.calibration(p) for p in others]
