"""Bring-up over `pinarray sim-serve`'s pseudo-terminal, checked by clients we did not write.

The servos live in another process behind a pseudo-terminal, as real ones live behind a USB
adapter; `pinarray servos ...` runs as a lab would run it, and what it did is checked the way
the vendor's SDK examples and LeRobot's ``FeetechMotorsBus`` see the bus (`test_compat`).
"""

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from scservo_sdk import COMM_SUCCESS

from pinarray.hardware.feetech.registers import Register

from .test_compat import LeRobotStyleBus, sim_serve, vendor_port  # noqa: F401  (a fixture)

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = pytest.mark.realtime

PROTOCOL = Path(__file__).resolve().parents[2] / "protocols" / "localisation.yaml"


def servos(*args, stdin: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pinarray", "servos", *args], input=stdin,
                          capture_output=True, text=True, timeout=120)


def test_a_fresh_servo_renumbered_by_set_id_is_found_by_other_clients_only_at_its_new_id(
        sim_serve):  # noqa: F811
    found = servos("scan", "--port", sim_serve)
    assert found.returncode == 0, found.stderr
    assert found.stdout.splitlines()[-1] == f"1 servo(s) answered a broadcast ping on {sim_serve}"
    renumbered = servos("set-id", "1", "7", "--port", sim_serve)
    assert renumbered.returncode == 0, renumbered.stderr
    assert renumbered.stdout.startswith("servo 1 is now servo 7 (model 777)")
    lerobot = LeRobotStyleBus(sim_serve)
    assert lerobot.broadcast_ping() == {7: 777}
    lerobot.close()
    port, handler = vendor_port(sim_serve)
    assert handler.ping(port, 7)[:2] == (777, COMM_SUCCESS)
    assert handler.ping(port, 1)[1] != COMM_SUCCESS
    lock, result, _ = handler.read1ByteTxRx(port, 7, Register.LOCK.address)
    port.closePort()
    assert (result, lock) == (COMM_SUCCESS, 1)


@pytest.mark.parametrize("sim_serve", ["1-3"], indirect=True)
def test_set_id_onto_a_servo_already_there_changes_nothing(sim_serve):  # noqa: F811
    refused = servos("set-id", "1", "3", "--port", sim_serve)
    assert refused.returncode == 2 and refused.stdout == ""
    assert refused.stderr == (
        "pinarray: set-id: servo id 3 is already taken (a servo of model 777 answers there); "
        "refusing to give servo 1 the same id. Choose a free id, or renumber servo 3 first\n")
    port, handler = vendor_port(sim_serve)
    assert [handler.ping(port, i)[1] for i in (1, 2, 3)] == [COMM_SUCCESS] * 3
    port.closePort()


@pytest.mark.parametrize("sim_serve", ["1-16"], indirect=True)
def test_a_scan_of_a_full_array_sweeps_every_id_with_progress(sim_serve):  # noqa: F811
    found = servos("scan", "--port", sim_serve)
    assert found.returncode == 0, found.stderr
    assert found.stdout.splitlines()[-1] == (
        f"16 servo(s) answered on {sim_serve} (ids 0-252 pinged, up to 10 ms each; answers "
        "to a broadcast ping collided: several servos answer)")
    assert found.stderr.splitlines()[-1] == "sweeping: id 252 of 252, found so far: 1-16"


def test_a_lowered_return_delay_is_what_other_clients_read(sim_serve):  # noqa: F811
    lowered = servos("return-delay", "--ids", "1", "--port", sim_serve)
    assert lowered.returncode == 0, lowered.stderr
    assert lowered.stdout == "servo 1: RETURN_DELAY_TIME (address 7) 500 us -> 0 us, until power-off\n"
    port, handler = vendor_port(sim_serve)
    delay, result, _ = handler.read1ByteTxRx(port, 1, Register.RETURN_DELAY_TIME.address)
    lock, _, _ = handler.read1ByteTxRx(port, 1, Register.LOCK.address)
    port.closePort()
    assert (result, delay, lock) == (COMM_SUCCESS, 0, 1)


@pytest.mark.parametrize("sim_serve", ["6"], indirect=True)
def test_calibrating_a_real_time_pin_leaves_it_at_rest_with_torque_off(sim_serve, tmp_path):  # noqa: F811
    protocol = tmp_path / "localisation.yaml"
    protocol.write_bytes(PROTOCOL.read_bytes())
    done = servos("calibrate", str(protocol), "--pin", "6", "--port", sim_serve,
                  stdin="-20\nok\n+110\nok\n")
    assert done.returncode == 0, done.stderr
    assert "6: {rest_steps: 2028, positions: {1.5: 2028, 2.0: 2138}}" in protocol.read_text()
    port, handler = vendor_port(sim_serve)
    torque, result, _ = handler.read1ByteTxRx(port, 6, Register.TORQUE_ENABLE.address)
    position, _, _ = handler.read2ByteTxRx(port, 6, Register.PRESENT_POSITION.address)
    port.closePort()
    assert (result, torque) == (COMM_SUCCESS, 0) and abs(position - 2028) <= 4


@pytest.mark.parametrize("sim_serve", ["6"], indirect=True)
@pytest.mark.parametrize("number", [signal.SIGALRM, signal.SIGXCPU, signal.SIGVTALRM,
                                    signal.SIGRTMIN + 3])
def test_a_calibration_ended_by_any_signal_that_would_end_it_leaves_the_pin_released(
        sim_serve, tmp_path, number):  # noqa: F811
    # Stranger attack (attack-stop): only the signals a terminal sends were handled; `kill
    # -ALRM`, a CPU-time limit (SIGXCPU) or a real-time signal ended the calibration at its
    # prompt by their default action, the pin holding torque where it was jogged.
    protocol = tmp_path / "localisation.yaml"
    protocol.write_bytes(PROTOCOL.read_bytes())
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "servos", "calibrate", str(protocol), "--pin", "6",
         "--port", sim_serve], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)
    try:
        for line in process.stdout:  # the pin held, torque on, waiting at the prompt
            if line.startswith("Jog pin 6"):
                break
        process.send_signal(number)
        process.wait(timeout=60)  # stdin still open: only the signal ends it
        err = process.stderr.read()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + number, err
    assert "Traceback" not in err and " stopped by SIG" in err.splitlines()[-1], err
    port, handler = vendor_port(sim_serve)
    torque, result, _ = handler.read1ByteTxRx(port, 6, Register.TORQUE_ENABLE.address)
    port.closePort()
    assert (result, torque) == (COMM_SUCCESS, 0)


@pytest.mark.parametrize("sim_serve", ["1,2"], indirect=True)
def test_ctrl_c_during_a_sweep_ends_it_at_once(sim_serve):  # noqa: F811
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "servos", "scan", "--port", sim_serve],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = process.stderr.readline()  # the sweep's first progress line
        # (Whom it found so far is the first pass's, 10 ms a PING: on a busy machine the
        # simulated servos may answer later, and be found when the sweep looks again.)
        assert first.startswith("sweeping: id 31 of 252, found so far: "), first
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130 and out == ""
    assert err.splitlines()[-1] == "pinarray: stopped by SIGINT", err
