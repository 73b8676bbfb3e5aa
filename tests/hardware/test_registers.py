"""The control table and its encodings, as the servo stores them."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray.hardware.feetech.registers import (
    Register,
    StatusError,
    checksum,
    decode_load,
    decode_position,
    encode_position,
    encode_sign_magnitude,
)


def test_register_table_matches_the_reference_addresses():
    assert (Register.GOAL_POSITION.address, Register.GOAL_POSITION.size) == (42, 2)
    assert (Register.PRESENT_LOAD.address, Register.PRESENT_TEMPERATURE.address) == (60, 63)
    assert Register.RETURN_DELAY_TIME.in_eeprom and not Register.TORQUE_ENABLE.in_eeprom


def test_negative_positions_set_bit_15_and_keep_the_magnitude():
    assert encode_position(-5) == 0x8005
    assert decode_position(0x8005) == -5
    assert encode_position(4095) == 4095


def test_load_uses_sign_bit_10():
    assert decode_load(0x400 | 300) == -300
    assert decode_load(300) == 300


@given(st.integers(-(2**15) + 1, 2**15 - 1))
def test_position_encoding_round_trips(position_steps):
    raw = encode_position(position_steps)
    assert 0 <= raw < 2**16
    assert decode_position(raw) == position_steps


@given(st.integers(-(2**10) + 1, 2**10 - 1))
def test_load_encoding_round_trips(load):
    assert decode_load(encode_sign_magnitude(load, 10)) == load


def test_a_position_too_large_for_15_bits_is_refused():
    with pytest.raises(ValueError):
        encode_position(40_000)


def test_checksum_is_the_inverted_low_byte_of_the_sum():
    # Ping of servo 1: FF FF 01 02 01 FB
    assert checksum([0x01, 0x02, 0x01]) == 0xFB


def test_error_bits_read_as_words():
    assert (StatusError.OVERLOAD | StatusError.VOLTAGE).describe() == "voltage+overload"
    assert StatusError(0).describe() == "none"


def test_error_bits_without_a_name_are_reported_not_hidden():
    from pinarray.hardware.feetech.registers import StatusError

    assert StatusError(32).describe() == "overload"
    assert StatusError(32 | 16).describe() == "overload+unknown bits 0x10"
    assert StatusError(0).describe() == "none"
