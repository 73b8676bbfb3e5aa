"""Hobby servos following pulses, the i2c-dev link (on a fake smbus2) and the I2C log file."""

import errno
from fractions import Fraction

import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import BusError
from pinarray.hardware.driver import PortLost
from pinarray.hardware.pca9685 import smbus_link
from pinarray.hardware.pca9685.i2c import I2cMessage, I2cNack
from pinarray.hardware.pca9685.i2c_log import I2cLog
from pinarray.hardware.pca9685.servo_sim import HobbyServo

MS = 1_000_000


def train(width_us: int, count: int, period_ns: int = 10 * MS, first_ns: int = 0):
    return [(first_ns + k * period_ns, width_us * 1000) for k in range(count)]


# -- hobby servos ----------------------------------------------------------------------------------

def test_a_servo_moves_toward_a_new_width_no_faster_than_its_speed_limit():
    points = HobbyServo().follow(train(2000, 5), start_us=Fraction(1500))
    first, last = points[0], points[-1]
    assert first.position_us == 1500  # limp before its first pulse: it has not moved
    elapsed_s = Fraction(last.t_ns - first.t_ns, 10**9)
    assert last.position_us == 1500 + 6667 * elapsed_s


def test_a_width_inside_the_dead_band_does_not_move_the_servo():
    points = HobbyServo().follow(train(1506, 10), start_us=Fraction(1500))
    assert {p.position_us for p in points} == {1500}


def test_a_servo_without_pulses_for_three_periods_goes_limp_where_it_is():
    pulses = train(2000, 5) + train(2000, 1, first_ns=200 * MS)
    points = HobbyServo().follow(pulses, start_us=Fraction(1500))
    limp = [p for p in points if p.limp]
    assert len(limp) == 1 and limp[0].t_ns == 4 * 10 * MS + 2 * MS + 30 * MS
    assert points[-1].position_us == limp[0].position_us  # it held while limp


# -- the i2c-dev link ------------------------------------------------------------------------------

class FakeSMBus:
    """smbus2.SMBus as the kernel would answer: bytes for reads, or an errno."""

    def __init__(self, bus=None):
        self.fd = 7
        self.sent = []
        self.fail: int | None = None
        self.answer = b""

    def i2c_rdwr(self, *messages):
        if self.fail is not None:
            raise OSError(self.fail, "fake")
        for message in messages:
            if message.flags & 0x0001:  # I2C_M_RD
                for index, value in enumerate(self.answer[:message.len]):
                    message.buf[index] = value
            else:
                self.sent.append(bytes(message))

    def close(self):
        pass


@pytest.fixture
def link(monkeypatch):
    monkeypatch.setattr(smbus_link, "SMBus", FakeSMBus)
    return smbus_link.SmbusLink("/dev/i2c-1", VirtualClock(5_000))


def test_a_write_and_read_go_as_one_i2c_rdwr_transaction(link):
    heard = []
    link.listener = heard.append
    link._bus.answer = bytes([0x21])
    assert link.write_read(0x40, bytes([0x00]), 1) == bytes([0x21])
    assert link._bus.sent == [bytes([0x00])]
    assert [m.log_line(0) for m in heard][1] == "5000 0x40 r 21 ack"


@pytest.mark.parametrize("code, error, words", [
    (errno.ENXIO, I2cNack, "0x40 did not acknowledge"),
    (errno.EREMOTEIO, I2cNack, "0x40 did not acknowledge"),
    (errno.ETIMEDOUT, BusError, "/dev/i2c-1: bus stuck"),
    (errno.EAGAIN, BusError, "/dev/i2c-1: bus stuck"),
    (errno.ENODEV, PortLost, "adapter is gone"),
    (errno.EIO, PortLost, "adapter is gone"),
])
def test_the_kernels_errors_become_a_nack_a_stuck_bus_or_a_lost_adapter(link, code, error, words):
    heard = []
    link.listener = heard.append
    link._bus.fail = code
    with pytest.raises(error, match=words):
        link.write(0x40, bytes([0x00, 0x11]))
    assert heard[-1].acked is False


# -- the log ---------------------------------------------------------------------------------------

def message(stop_ns, data=b"\x06\x00", acked=True, read=False):
    return I2cMessage(0x40, read, data, acked, stop_ns)


def test_a_log_line_is_t_ns_addr_rw_data_hex_ack():
    assert message(1_250, bytes([0x06, 0x00, 0x01]), acked=False).log_line(1_000) == \
        "250 0x40 w 060001 nack"


def test_arming_writes_before_a_trial_are_logged_negative_from_its_onset(tmp_path):
    path = tmp_path / "i2c.txt"
    log = I2cLog(path)
    log(message(900))
    log.trial_onset(1_000)
    log(message(1_100))
    log.trial_end()
    log(message(1_900, read=True))
    log.trial_onset(2_000)
    log.close()
    assert path.read_text().splitlines() == [
        "-100 0x40 w 0600 ack", "100 0x40 w 0600 ack", "-100 0x40 r 0600 ack"]


def test_the_log_holds_back_at_most_max_held_messages(tmp_path):
    path = tmp_path / "i2c.txt"
    log = I2cLog(path, max_held=2)
    for t in (10, 20, 30):
        log(message(t))
    assert log._held.maxlen is None and len(log._held) == 2
    log.close()
    assert [line.split()[0] for line in path.read_text().splitlines()] == ["10", "20", "30"]
