"""A protocol's ``sync:`` section and the command line's scanner options (which win)."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.protocol.imaging import (
    EmulatedTrigger,
    KeyTrigger,
    ScannerSync,
    SerialTrigger,
    SyncError,
    SyncOverrides,
    parse_trigger,
)
from pinarray.protocol.load import parse_protocol
from tests.strategies import unicode_characters
from tests.test_protocol_load import MINIMAL, problems

S = 1_000_000_000


def with_sync(section: str) -> str:
    return MINIMAL + "sync:\n" + section


def test_a_sync_section_gives_the_trigger_dummies_tr_and_locking():
    protocol = parse_protocol(with_sync(
        "  trigger: serial:/dev/ttyACM0\n  dummy_volumes: 4\n  repetition_time_s: 2.5\n"
        "  lock_to_volumes: 3\n  baud_rate: 9600\n  wait_timeout_s: 60\n"), "p.yaml")
    assert protocol.sync == ScannerSync(SerialTrigger("/dev/ttyACM0", "5", 9600), 4,
                                        2_500_000_000, 3, 60 * S)
    assert protocol.sync.describe() == (
        "serial:/dev/ttyACM0:5, 4 dummy volume(s), TR 2.5 s, onsets on volumes 0, 3, 6, ...")


@pytest.mark.parametrize(("section", "expected"), [
    ("  trigger: usb:/dev/x\n",
     "p.yaml:12:12: expected a trigger serial:PATH[:CHAR], key[:CHAR] or emulate:TR, "
     "found 'usb:/dev/x'"),
    ("  trigger: emulate:0.01\n",
     "p.yaml:12:12: expected the emulated TR from 0.1 to 60 s, found 0.01"),
    ("  trigger: key:ab\n",
     "p.yaml:12:12: expected one printable ASCII character for the key trigger (e.g. 5), "
     "found 'ab'"),
    ("  trigger: key\n  lock_to_volumes: 2\n",
     "p.yaml:12:3: locking onsets to volumes needs the TR, to go on when a volume is missing: "
     "give the repetition time (--tr, or repetition_time_s)"),
])
def test_a_bad_sync_section_is_one_located_line(section, expected):
    assert problems(with_sync(section)) == [expected]


def test_the_command_line_wins_over_the_protocol():
    base = ScannerSync(SerialTrigger("/dev/ttyACM0", "5", 9600), 4, 2 * S, 0)
    chosen = SyncOverrides(parse_trigger("serial:/dev/ttyUSB1:t"), dummy_volumes=0).over(base)
    # The converter's baud rate stays the protocol's: the command line cannot give one.
    assert chosen == ScannerSync(SerialTrigger("/dev/ttyUSB1", "t", 9600), 0, 2 * S, 0)
    rehearsal = SyncOverrides(parse_trigger("emulate:1.5")).over(base)
    assert rehearsal.tr_ns == 1_500_000_000  # the emulated TR, not the real scanner's
    assert SyncOverrides().over(None) is None and SyncOverrides().over(base) == base


def test_an_emulated_tr_that_disagrees_with_the_given_tr_is_refused():
    with pytest.raises(SyncError, match=r"emulated trigger's TR \(2 s\) and the repetition time"):
        SyncOverrides(EmulatedTrigger(2 * S), repetition_time_ns=3 * S).over(None)


@given(st.from_regex(r"/dev/[a-z]{1,8}(:[a-z]{2,5})?", fullmatch=True, alphabet=unicode_characters),
       st.sampled_from("5tS0"))
def test_a_serial_trigger_reads_back_what_it_describes(path, character):
    trigger = parse_trigger(f"serial:{path}:{character}")
    assert trigger == SerialTrigger(path, character)
    assert parse_trigger(trigger.describe()) == trigger
    assert parse_trigger(KeyTrigger(character).describe()) == KeyTrigger(character)
