"""The simulated PCA9685 keeps the datasheet's rules, one test per rule (NXP rev. 4 sections)."""

from fractions import Fraction
from math import floor

import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.driver import PortLost
from pinarray.hardware.pca9685 import registers as r
from pinarray.hardware.pca9685.board_sim import SimulatedBoard
from pinarray.hardware.pca9685.i2c import I2cNack
from pinarray.hardware.pca9685.sim import SimI2cLink, is_pca9685_url

OSC_HZ = 25_300_000
PRESCALE_100HZ = r.prescale_for(OSC_HZ, Fraction(100))
ADDRESS = 0x40
MS = 1_000_000
AWAKE = r.AI | r.ALLCALL


def running_board(prescale: int = PRESCALE_100HZ, wake_ns: int = 10_000) -> SimulatedBoard:
    """A board set to ``prescale`` in SLEEP, then woken at ``wake_ns`` (counter from +500 us)."""
    board = SimulatedBoard(OSC_HZ)
    assert board.write(bytes([r.MODE1, r.SLEEP | AWAKE]), 1_000)
    assert board.write(bytes([r.PRE_SCALE, prescale]), 2_000)
    assert board.write(bytes([r.MODE1, AWAKE]), wake_ns)
    return board


def set_channel(board: SimulatedBoard, channel: int, block: r.LedBlock, at_ns: int) -> None:
    assert board.write(bytes([r.led_register(channel)]) + block.encode(), at_ns)


def read(board: SimulatedBoard, register: int, count: int, at_ns: int) -> bytes:
    assert board.write(bytes([register]), at_ns)
    return board.read(count, at_ns)


def counter_start(board: SimulatedBoard) -> Fraction:
    return board.counter_runs()[-1][0]


# -- power-up and reset (7.3, 7.6) ---------------------------------------------------------------

def test_power_up_leaves_mode1_0x11_mode2_0x04_every_output_full_off_and_prescale_0x1e():
    board = SimulatedBoard(OSC_HZ)
    registers = read(board, r.MODE1, r.LAST_LED_REGISTER + 1, 100)  # AI is clear: MODE1 only
    assert registers == bytes([r.MODE1_RESET]) * (r.LAST_LED_REGISTER + 1)
    board.write(bytes([r.MODE1, r.SLEEP | AWAKE]), 200)
    everything = read(board, r.MODE1, r.LAST_LED_REGISTER + 1, 300)
    assert everything[r.MODE2] == 0x04
    assert everything[r.SUBADR1:r.ALLCALLADR + 1] == bytes([0xE2, 0xE4, 0xE8, 0xE0])
    assert all(everything[r.led_register(c):r.led_register(c) + 4] == bytes([0, 0, 0, 0x10])
               for c in range(r.CHANNELS))
    assert read(board, r.PRE_SCALE, 1, 400) == bytes([0x1E])
    assert board.counter_runs() == []


def test_a_board_that_lost_power_comes_back_asleep_with_its_reset_values_and_its_pins_silent():
    board = running_board()
    set_channel(board, 0, r.LedBlock.pulse(0, 600), 20_000)
    board.lose_power(30 * MS)
    assert not board.answers(ADDRESS)
    board.power_up(31 * MS)
    assert read(board, r.MODE1, 1, 32 * MS) == bytes([r.MODE1_RESET])
    assert read(board, r.PRE_SCALE, 1, 33 * MS) == bytes([r.PRESCALE_RESET])
    assert all(start < 30 * MS for start, _ in board.pulses(0, 0, 100 * MS))


def test_the_software_reset_is_the_general_call_0x00_with_the_one_byte_0x06():
    link = SimI2cLink("sim://pca9685?osc_hz=25300000", VirtualClock())
    link.write(ADDRESS, bytes([r.MODE1, r.SLEEP | AWAKE]))
    link.write(ADDRESS, bytes([r.PRE_SCALE, 100]))
    with pytest.raises(I2cNack):
        link.write(r.SWRST_ADDRESS, bytes([0x07]))
    with pytest.raises(I2cNack):
        link.write(r.SWRST_ADDRESS, bytes([r.SWRST_BYTE, 0x00]))
    assert link.write_read(ADDRESS, bytes([r.PRE_SCALE]), 1) == bytes([100])
    link.write(r.SWRST_ADDRESS, bytes([r.SWRST_BYTE]))
    assert link.write_read(ADDRESS, bytes([r.PRE_SCALE]), 1) == bytes([r.PRESCALE_RESET])


# -- registers and the pointer (7.3) ---------------------------------------------------------------

def test_prescale_written_while_awake_is_ignored():
    board = running_board(prescale=50)
    assert board.write(bytes([r.PRE_SCALE, 121]), 5 * MS)
    assert read(board, r.PRE_SCALE, 1, 6 * MS) == bytes([50])


def test_prescale_below_3_loads_3():
    board = SimulatedBoard(OSC_HZ)
    board.write(bytes([r.PRE_SCALE, 1]), 1_000)
    assert read(board, r.PRE_SCALE, 1, 2_000) == bytes([r.PRESCALE_MIN])


def test_auto_increment_rolls_over_from_led15_off_h_to_mode1():
    board = running_board()
    data = bytes([r.LAST_LED_REGISTER, 0x10 | 0x03, AWAKE | r.SLEEP])
    assert board.write(data, 20_000)
    assert read(board, r.MODE1, 1, 30_000)[0] & r.SLEEP


def test_auto_increment_rolls_over_from_pre_scale_to_mode1():
    board = SimulatedBoard(OSC_HZ)
    board.write(bytes([r.MODE1, r.SLEEP | AWAKE]), 1_000)
    assert read(board, r.ALL_LED_ON_L, 6, 2_000) == bytes([0, 0, 0, 0, 0x1E, r.SLEEP | AWAKE])


def test_without_auto_increment_every_byte_goes_to_the_same_register():
    board = SimulatedBoard(OSC_HZ)  # AI clear at power-up
    board.write(bytes([r.led_register(3), 0x11, 0x22, 0x33]), 1_000)
    board.write(bytes([r.MODE1, r.SLEEP | AWAKE]), 2_000)
    assert read(board, r.led_register(3), 2, 3_000) == bytes([0x33, 0x00])


def test_a_reserved_register_is_not_acknowledged():
    board = SimulatedBoard(OSC_HZ)
    assert not board.write(bytes([0x46, 0x00]), 1_000)
    assert not board.write(bytes([0xF9]), 1_000)
    assert board.write(bytes([r.ALL_LED_ON_L]), 1_000)


def test_all_led_writes_every_channel_and_reads_back_as_zero():
    board = running_board()
    assert board.write(bytes([r.ALL_LED_ON_L, 0x00, 0x01, 0x00, 0x02]), 20_000)
    assert read(board, r.ALL_LED_ON_L, 4, 30_000) == bytes(4)
    for channel in range(r.CHANNELS):
        assert read(board, r.led_register(channel), 4, 40_000) == bytes([0, 1, 0, 2])


def test_the_reserved_bits_of_the_led_high_registers_are_not_writable():
    board = running_board()
    set_channel(board, 2, r.LedBlock(0, 0), 20_000)
    board.write(bytes([r.led_register(2) + 1, 0xFF]), 30_000)
    assert read(board, r.led_register(2) + 1, 1, 40_000) == bytes([0x1F])


# -- outputs (7.3.3) -----------------------------------------------------------------------------

def exact_pulses(start: Fraction, prescale: int, on: int, width: int, first: int, count: int):
    period, tick = r.period_ns(OSC_HZ, prescale), r.tick_ns(OSC_HZ, prescale)
    found = []
    for k in range(first, first + count):
        rise = start + k * period + on * tick
        found.append((floor(rise), floor(rise + width * tick) - floor(rise)))
    return found


def test_a_new_off_count_takes_effect_at_the_next_period():
    board = running_board()
    start = counter_start(board)
    period = board.period_ns()
    set_channel(board, 0, r.LedBlock.pulse(0, 600), 20_000)
    later = int(start + 5 * period + period / 2)  # mid period 5
    set_channel(board, 0, r.LedBlock.pulse(0, 300), later)
    pulses = board.pulses(0, 0, int(start + 8 * period))
    assert pulses[:6] == exact_pulses(start, PRESCALE_100HZ, 0, 600, 0, 6)
    assert pulses[6:] == exact_pulses(start, PRESCALE_100HZ, 0, 300, 6, 2)


def test_with_och_set_a_new_value_is_taken_at_its_ack_not_at_the_stop():
    board = running_board()
    start, period = counter_start(board), board.period_ns()
    board.write(bytes([r.MODE2, r.MODE2_RESET | r.OCH]), 20_000)
    boundary = int(start + 3 * period)
    # a long message: its last LED byte is acknowledged before the period boundary, its STOP after
    data = bytes([r.led_register(0)]) + r.LedBlock.pulse(0, 600).encode() * 2  # LED0, LED1
    assert board.write(data, boundary + 10_000, byte_ns=22_500)
    assert board.pulses(0, 0, boundary + 1)[0][0] == boundary


def test_full_off_wins_over_full_on():
    board = running_board()
    board.write(bytes([r.led_register(1), 0, r.FULL_BIT, 0, r.FULL_BIT]), 20_000)
    assert board.pulses(1, 0, 100 * MS) == []
    board.write(bytes([r.led_register(1) + 3, 0]), 100 * MS)
    assert board.pulses(1, 100 * MS, 200 * MS) != []


def test_on_equal_to_off_gives_no_pulse():
    board = running_board()
    set_channel(board, 0, r.LedBlock(700, 700), 20_000)
    assert board.pulses(0, 0, 100 * MS) == []


def test_an_off_below_on_makes_one_pulse_that_wraps_into_the_next_period():
    board = running_board()
    start, period, tick = counter_start(board), board.period_ns(), board.period_ns() / 4096
    set_channel(board, 0, r.LedBlock.pulse(3900, 600), 20_000)
    pulses = board.pulses(0, 0, int(start + 3 * period))
    rise = start + 3900 * tick
    assert pulses[0] == (floor(rise), floor(start + period + 404 * tick) - floor(rise))
    assert len(pulses) == 3


def test_a_full_off_pin_carries_nothing_until_written():
    board = running_board()
    assert board.pulses(5, 0, 10**9) == []


# -- SLEEP and RESTART (7.3.1, 7.3.1.1) ----------------------------------------------------------

def test_the_counter_starts_500_us_after_sleep_is_cleared():
    board = running_board(wake_ns=10_000)
    assert counter_start(board) == 10_000 + r.OSCILLATOR_START_NS


def test_sleep_with_active_channels_sets_restart_at_the_end_of_the_period_and_stops_the_pins():
    board = running_board()
    start, period = counter_start(board), board.period_ns()
    set_channel(board, 0, r.LedBlock.pulse(0, 600), 20_000)
    asleep_at = int(start + 2 * period + 1000)
    board.write(bytes([r.MODE1, AWAKE | r.SLEEP]), asleep_at)
    assert not read(board, r.MODE1, 1, asleep_at + 1)[0] & r.RESTART
    end = start + 3 * period
    assert read(board, r.MODE1, 1, int(end) + 1)[0] & r.RESTART
    assert len(board.pulses(0, 0, 10**9)) == 3


def test_restart_resumes_the_channels_with_the_counter_from_zero():
    board = running_board()
    start, period = counter_start(board), board.period_ns()
    set_channel(board, 0, r.LedBlock.pulse(0, 600), 20_000)
    board.write(bytes([r.MODE1, AWAKE | r.SLEEP]), int(start + period / 2))
    wake = 50 * MS
    board.write(bytes([r.MODE1, AWAKE]), wake)
    assert board.pulses(0, wake, wake + 10 * MS) == []  # held until RESTART
    restart = wake + r.OSCILLATOR_START_NS
    board.write(bytes([r.MODE1, AWAKE | r.RESTART]), restart)
    assert not read(board, r.MODE1, 1, restart + 1)[0] & r.RESTART
    assert board.pulses(0, wake, restart + 1) == [exact_pulses(Fraction(restart),
                                                               PRESCALE_100HZ, 0, 600, 0, 1)[0]]


def test_restart_written_sooner_than_500_us_after_waking_is_ignored():
    board = running_board()
    start, period = counter_start(board), board.period_ns()
    set_channel(board, 0, r.LedBlock.pulse(0, 600), 20_000)
    board.write(bytes([r.MODE1, AWAKE | r.SLEEP]), int(start + period / 2))
    board.write(bytes([r.MODE1, AWAKE]), 50 * MS)
    board.write(bytes([r.MODE1, AWAKE | r.RESTART]), 50 * MS + 100_000)
    assert read(board, r.MODE1, 1, 51 * MS)[0] & r.RESTART
    assert board.pulses(0, 50 * MS, 100 * MS) == []


def test_extclk_is_sticky_until_a_reset():
    board = SimulatedBoard(OSC_HZ)
    board.write(bytes([r.MODE1, r.SLEEP | r.EXTCLK]), 1_000)
    board.write(bytes([r.MODE1, r.SLEEP]), 2_000)
    assert read(board, r.MODE1, 1, 3_000)[0] & r.EXTCLK
    board.general_call(bytes([r.SWRST_BYTE]), 4_000)
    assert not read(board, r.MODE1, 1, 5_000)[0] & r.EXTCLK


# -- addresses (7.1) -------------------------------------------------------------------------------

def test_the_board_answers_all_call_0x70_while_allcall_is_set():
    board = SimulatedBoard(OSC_HZ)
    assert board.answers(r.ALL_CALL_ADDRESS)
    board.write(bytes([r.MODE1, r.SLEEP]), 1_000)
    assert not board.answers(r.ALL_CALL_ADDRESS)
    assert board.answers(ADDRESS) and not board.answers(0x41)


# -- exactness -------------------------------------------------------------------------------------

def test_ten_seconds_at_100_hz_on_a_25_3_mhz_board_are_exact_to_the_ns():
    board = running_board()
    start = counter_start(board)
    set_channel(board, 0, r.LedBlock.pulse(1000, 614), 20_000)
    period = r.period_ns(OSC_HZ, PRESCALE_100HZ)
    count = int(10 * 10**9 / period)
    pulses = board.pulses(0, 0, int(start + count * period))
    assert pulses == exact_pulses(start, PRESCALE_100HZ, 1000, 614, 0, count)
    assert count == 996


def test_a_day_of_periods_later_the_edges_are_still_exact():
    board = running_board()
    start = counter_start(board)
    set_channel(board, 0, r.LedBlock.pulse(1000, 614), 20_000)
    period = r.period_ns(OSC_HZ, PRESCALE_100HZ)
    k = int(24 * 3600 * 10**9 / period)
    window = (int(start + k * period), int(start + (k + 2) * period))
    assert board.pulses(0, *window) == exact_pulses(start, PRESCALE_100HZ, 1000, 614, k, 2)


# -- the simulated bus -----------------------------------------------------------------------------

def test_a_message_takes_start_nine_bits_a_byte_and_stop_on_the_virtual_clock():
    clock = VirtualClock()
    link = SimI2cLink("sim://pca9685?bus_hz=100000", clock)
    message = link.write(ADDRESS, bytes([r.MODE1, AWAKE]))
    assert message.stop_ns == clock.now_ns() == (1 + 27 + 1) * 10_000


def test_an_absent_board_is_not_acknowledged_and_the_listener_hears_the_nack():
    heard = []
    link = SimI2cLink("sim://pca9685?address=0x41", VirtualClock())
    link.listener = heard.append
    with pytest.raises(I2cNack) as raised:
        link.write(ADDRESS, bytes([r.MODE1, 0]))
    assert raised.value.address == ADDRESS and "0x40" in str(raised.value)
    assert heard[0].log_line(0) == f"{heard[0].stop_ns} 0x40 w  nack"


def test_nack_at_refuses_that_message_only():
    link = SimI2cLink("sim://pca9685?nack_at=2", VirtualClock())
    link.write(ADDRESS, bytes([r.MODE1, r.SLEEP]))
    with pytest.raises(I2cNack):
        link.write(ADDRESS, bytes([r.MODE1, r.SLEEP]))
    link.write(ADDRESS, bytes([r.MODE1, r.SLEEP]))


def test_power_loss_at_puts_the_board_back_to_its_reset_values():
    link = SimI2cLink("sim://pca9685?power_loss_at=3", VirtualClock())
    link.write(ADDRESS, bytes([r.MODE1, r.SLEEP | AWAKE]))
    link.write(ADDRESS, bytes([r.PRE_SCALE, 121]))
    assert link.write_read(ADDRESS, bytes([r.PRE_SCALE]), 1) == bytes([r.PRESCALE_RESET])


def test_the_adapter_vanishes_after_the_given_number_of_messages():
    link = SimI2cLink("sim://pca9685?vanish_after=1", VirtualClock())
    link.write(ADDRESS, bytes([r.MODE1, r.SLEEP]))
    with pytest.raises(PortLost):
        link.write(ADDRESS, bytes([r.MODE1, r.SLEEP]))


def test_several_boards_share_one_bus():
    link = SimI2cLink("sim://pca9685?address=0x40,0x41&osc_hz=25300000", VirtualClock())
    link.write(0x41, bytes([r.MODE1, r.SLEEP | AWAKE]))
    assert link.board(0x41).osc_hz == OSC_HZ
    assert link.write_read(0x41, bytes([r.MODE1]), 1) == bytes([r.SLEEP | AWAKE])
    assert link.write_read(0x40, bytes([r.MODE1]), 1) == bytes([r.MODE1_RESET])


@pytest.mark.parametrize("url", ["sim://pca9685?colour=red", "sim://pca9685?bus_hz=fast",
                                 "sim://pca9685?address=0x70", "sim://pca9685?nack=2",
                                 "sim://pca9685?address=0x40&address=0x41"])
def test_a_bad_sim_url_is_one_clear_error(url):
    with pytest.raises(PinArrayError, match="sim URL key|unknown key"):
        SimI2cLink(url, VirtualClock())


def test_only_pca9685_sim_urls_are_recognised():
    assert is_pca9685_url("sim://pca9685?osc_hz=25300000") and is_pca9685_url("sim://pca9685")
    assert not is_pca9685_url("sim://?ids=1-4") and not is_pca9685_url("/dev/i2c-1")
