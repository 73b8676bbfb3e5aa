"""One servo connected, the rest of the array not yet: the commands a lab types then, over
`pinarray sim-serve`'s pseudo-terminal as if it were a USB adapter, checked with the vendor's SDK."""

import subprocess
import sys

import pytest
from scservo_sdk import COMM_SUCCESS

from pinarray.hardware.feetech.registers import Register

from .test_compat import sim_serve, vendor_port  # noqa: F401  (a fixture)

pytestmark = pytest.mark.realtime

NOT_CONNECTED = "no answer from servo(s) 1-5, 7-16 (not connected?): left as they are"


def servos(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pinarray", "servos", *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("sim_serve", ["6"], indirect=True)
def test_torque_off_and_return_delay_act_on_the_one_servo_connected_without_ids(
        sim_serve):  # noqa: F811
    for _ in range(2):  # the second time servo 6 is already limp
        done = servos("torque-off", "--port", sim_serve)
        assert (done.returncode, done.stderr) == (0, "")
        assert done.stdout.splitlines() == ["torque off on servo(s) 6", NOT_CONNECTED]
    lowered = servos("return-delay", "--port", sim_serve)
    assert (lowered.returncode, lowered.stderr) == (0, "")
    assert lowered.stdout.splitlines() == [
        "servo 6: RETURN_DELAY_TIME (address 7) 500 us -> 0 us, until power-off", NOT_CONNECTED]
    port, handler = vendor_port(sim_serve)
    torque, result, _ = handler.read1ByteTxRx(port, 6, Register.TORQUE_ENABLE.address)
    delay, _, _ = handler.read1ByteTxRx(port, 6, Register.RETURN_DELAY_TIME.address)
    port.closePort()
    assert (result, torque, delay) == (COMM_SUCCESS, 0, 0)
