"""Patterns on the grid as a lab writes them (pins by number, or drawn as the array is felt),
frames of patterns in time, and what the servo bus can carry of them, refused with numbers."""

from fractions import Fraction

from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.hardware.feetech import packets
from pinarray.protocol import PinDrive, ServoSettings, Train
from pinarray.protocol.bus import bus_problem, frames, readback_bytes, write_bytes
from pinarray.protocol.load import parse_protocol
from pinarray.protocol.model import Frames, Pattern
from pinarray.schedule import compile_drives
from tests.test_protocol_load import MINIMAL, problems

STIMULI = """\
protocol: shapes
device:
  servo: {{baud_rate: {baud}, return_delay_us: {delay}}}
  calibration: {{rest_steps: 2048, positions: {{1.5: 2048, 2.0: 2056}}, limits_steps: [2000, 2200]}}
stimuli:
  buzz: {{frequency_hz: {hz}, duration_s: 0.5}}
  {shape}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1]
  frequencies_hz: [5]
"""
L_DRAWN = """\
L:
    pattern: |
      # . . .
      # . . .
      # . . .
      # # # .
    train: buzz"""


def stimuli(shape: str, baud: int = 1_000_000, delay: int = 500, hz: int = 5) -> str:
    return STIMULI.format(shape=shape, baud=baud, delay=delay, hz=hz)


def shape_of(text: str, name: str):
    return parse_protocol(text, "p.yaml").stimulus(name).shape


def test_a_drawn_pattern_is_read_as_the_subject_feels_the_array_top_row_first():
    assert shape_of(stimuli(L_DRAWN), "L").pins == (1, 2, 3, 5, 9, 13)


def test_a_pattern_by_pin_numbers_and_the_same_drawing_are_one_pattern():
    listed = shape_of(stimuli("L: {pattern: [13, 9, 5, 1, 2, 3], train: buzz}"), "L")
    assert listed == shape_of(stimuli(L_DRAWN), "L")


def test_every_raised_pin_moves_with_the_pattern_s_train_at_its_phase():
    shape = shape_of(stimuli("T: {pattern: [13, 14, 15, 10], train: buzz, phase_deg: 90}"), "T")
    assert {d.pin for d in shape.drives()} == {10, 13, 14, 15}
    assert {d.train.phase for d in shape.drives()} == {Fraction(1, 4)}


def test_a_drawing_that_is_not_the_grid_is_refused_at_the_row_that_is_wrong():
    text = stimuli("L:\n    pattern: |\n      # . . .\n      # ? . .\n      # . . .\n"
                   "      # # #\n    train: buzz")
    assert problems(text) == [
        "p.yaml:10:7: expected '#' (raised) or '.' (at rest) in each cell of a drawn pattern, "
        "found '?'"]
    short = text.replace("# ? . .", "# . . .")
    assert problems(short) == [
        "p.yaml:12:7: expected 4 cells in each row of a drawn pattern, found 3 in '# # #'"]


def test_frames_play_their_patterns_one_soa_after_another():
    shape = shape_of(stimuli("row: {pattern: [1, 2, 3, 4], train: buzz}\n"
                             "  top: {pattern: [13, 14, 15, 16], train: buzz}\n"
                             "  wipe: {frames: [row, top], soa_ms: 500}"), "wipe")
    assert isinstance(shape, Frames)
    assert {(d.pin, d.delay_ns) for d in shape.drives()} == {
        *((p, 0) for p in (1, 2, 3, 4)), *((p, 500_000_000) for p in (13, 14, 15, 16))}


def test_frames_that_drive_a_pin_twice_at_once_are_refused():
    found = problems(stimuli("row: {pattern: [1, 2], train: buzz}\n"
                             "  wipe: {frames: [row, row], soa_ms: 100}"))
    assert len(found) == 1 and "found pin 1 driven twice at once" in found[0]


def test_sixteen_pins_at_115200_baud_are_refused_with_the_bus_s_numbers():
    everything = "all: {pattern: [" + ", ".join(map(str, range(1, 17))) + "], train: buzz}"
    (refusal,) = problems(stimuli(everything, baud=115200, hz=40))
    assert refusal.startswith("p.yaml:7:18: the servo bus cannot deliver it: ")
    for said in ("a frame of 16 goal(s) is 56 bytes, 4.86 ms at 115200 baud",
                 "its read-back 152 bytes + 16 x 500 us return delay, 21.19 ms",
                 "26.06 ms a frame, at most 38 frames/s", "12.50 ms apart (80/s)"):
        assert said in refusal
    # The same pattern on a faster bus, or with the servos answering sooner, plays.
    parse_protocol(stimuli(everything, baud=1_000_000, hz=40), "p.yaml")
    parse_protocol(stimuli(everything, baud=115200, delay=0, hz=20), "p.yaml")


def test_a_frame_longer_on_the_wire_than_the_delivery_tolerance_is_refused():
    everything = "all: {pattern: [" + ", ".join(map(str, range(1, 17))) + "], train: buzz}"
    (refusal,) = problems(stimuli(everything, baud=38400, delay=0))
    assert ("a frame of 16 goal(s) at 0.00 ms is 56 bytes, 14.58 ms at 38400 baud: its last "
            "goal would reach its servo later than the delivery tolerance of 10.00 ms") in refusal


def test_the_bus_check_counts_the_packets_the_servo_driver_sends():
    for servos in (1, 4, 16):
        goals = [(servo_id, b"\x00\x08") for servo_id in range(1, servos + 1)]
        assert write_bytes(servos) == len(packets.sync_write(42, 2, goals))
    for servos in (2, 16):
        request = packets.sync_read(42, 2, range(1, servos + 1))
        assert readback_bytes(servos) == len(request) + servos * (packets.STATUS_OVERHEAD_BYTES + 2)


DEVICE = parse_protocol(MINIMAL).device


@settings(max_examples=40, deadline=None)
@given(pins=st.sets(st.integers(1, 16), min_size=1, max_size=6),
       frequency=st.sampled_from([Fraction(3), Fraction(5), Fraction(10), Fraction(7, 3)]),
       phase=st.sampled_from([Fraction(0), Fraction(1, 4), Fraction(3, 10)]),
       delays=st.lists(st.integers(0, 400), min_size=1, max_size=3))
def test_every_frame_the_compiler_sends_is_a_frame_the_bus_check_plays(pins, frequency,
                                                                       phase, delays):
    train = Train(frequency, 300_000_000, phase=phase)
    ordered = sorted(pins)
    drives = [PinDrive(pin, train, delays[i % len(delays)] * 1_000_000)
              for i, pin in enumerate(ordered)]
    checked = {round(time): pins for time, pins in frames(drives)}
    for frame in compile_drives(drives, DEVICE).targets.frames():
        assert frame.time_ns in checked, frame.time_ns
        assert set(frame.pins.tolist()) <= checked[frame.time_ns]


def test_one_pattern_of_a_long_signal_is_judged_on_its_first_and_last_periods_alike():
    pattern = Pattern(tuple(range(1, 17)), Train(Fraction(40), 3600 * 10**9))
    slow_bus = ServoSettings(baud_rate=115200)
    assert "16 x 500 us return delay" in bus_problem(pattern.drives(), slow_bus, 10_000_000)
    assert bus_problem(pattern.drives(), ServoSettings(), 10_000_000) is None
