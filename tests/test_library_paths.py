"""One path to the pins: the library behaves through a serial port (simulated servos behind a
pseudo-terminal, the player process included) as on the in-process simulator. A stimulus
plays the same way; a stop stops (every servo at rest and released, as the servos themselves
show it, not as pinarray reports it); a port has one owner; a host program's socket defaults
do not reach the player. How fast a stop takes torque off is `make bench`'s (bench_stop)."""

import resource
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import nullcontext
from pathlib import Path

import pytest

import pinarray
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.testing import assert_delivered, assert_every_goal_confirmed

REST_STEPS = 2048  # the calibration below
REPO = Path(__file__).resolve().parents[1]

# One pin buzzing at 5 Hz: short (0.4 s) to be played, long (10 s) to be stopped. Its tolerance
# is wide and its stroke not judged: these tests are about the path, not the timing of a busy
# machine, whose starved simulator may sample too seldom to judge a cycle (`make bench`).
BUZZ = """\
protocol: buzz
description: One pin buzzing, to be played and stopped.
device:
  delivery_tolerance_ms: 500
  stroke_tolerance_percent: 0
  calibration:
    rest_steps: 2048
    positions: {{1.5: 2048, 2.0: 2162}}
    limits_steps: [2000, 2200]
stimuli:
  buzz:
    frequency_hz: 5
    duration_s: {seconds}
    pulse_width_ms: {{up: 2.0, down: 1.5}}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [6]
  frequencies_hz: [5]
  repetitions: 1
"""


def buzz(tmp_path: Path, seconds: float) -> pinarray.Protocol:
    path = tmp_path / f"buzz_{seconds}.yaml"
    path.write_text(BUZZ.format(seconds=seconds))
    return pinarray.load_protocol(path)


class Way:
    """One way to the pins: ``sim`` (the in-process simulator, in real time) or ``pty`` (a
    serial port served by the simulated bus, the player process driving it). ``servos`` are
    the simulated servos themselves, inspected from their side of the wire."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start() \
            if kind == "pty" else None
        self.arrays: list[pinarray.PinArray] = []

    def open(self, protocol: pinarray.Protocol) -> pinarray.PinArray:
        if self.server is not None:
            array = pinarray.open_array(protocol, port=self.server.path)
        else:
            array = pinarray.open_array(protocol, sim="sim://",
                                        clock=pinarray.MonotonicClock())
        self.arrays.append(array)
        return array

    def servos(self, array: pinarray.PinArray):
        bus = self.server.sim if self.server is not None else array._rig.bus.sim
        return bus.servos

    def close(self) -> None:
        for array in self.arrays:
            array.close()
        if self.server is not None:
            self.server.stop()


@pytest.fixture(params=["sim", "pty"])
def way(request):
    """Each way to the pins in turn (real time on both)."""
    way = Way(request.param)
    yield way
    way.close()


realtime = pytest.mark.realtime  # the wall clock and pseudo-terminals: run apart


def at_rest_and_released(servos, ids=range(1, 17)) -> list[int]:
    """The servos in ``ids`` that hold torque or stand away from rest, as they show it now."""
    unsafe = []
    for servo_id in ids:
        servo = servos[servo_id]
        servo.read(56, 2, time.monotonic_ns())  # the simulated horn brought up to now
        if servo.torque_enabled or abs(servo.position_steps - REST_STEPS) > 4:
            unsafe.append(servo_id)
    return unsafe


def wait_moving(servos, pin: int = 6, timeout_s: float = 30.0) -> None:
    """Until the pin's servo has left rest: the stimulus is playing (``timeout_s``: a bound
    against a hang, not a timing check)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        servo = servos[pin]
        servo.read(56, 2, time.monotonic_ns())
        if abs(servo.position_steps - REST_STEPS) > 20:
            return
        time.sleep(0.005)
    raise AssertionError(f"pin {pin} never moved")


def start_playing(array, protocol, way):
    """Pin 6's buzz armed, started on its cue and moving: a cue, not a time a little ahead, so
    that a busy host cannot make its onset pass before playback begins (it would end "not
    delivered, nothing moved", rightly, and never move)."""
    armed = array.arm(pinarray.find_condition(protocol, pin=6))
    armed.start()
    wait_moving(way.servos(array))
    return armed


@realtime
def test_a_stimulus_plays_the_same_way_through_either_path(way, tmp_path):
    # A host program's default socket timeout (PsychoPy sets one on import) made every
    # stimulus through a port fail: it must not reach the player's channel.
    protocol = buzz(tmp_path, 0.4)
    default = socket.getdefaulttimeout()
    socket.setdefaulttimeout(20)
    try:
        array = way.open(protocol)
    finally:
        socket.setdefaulttimeout(default)
    delivery = array.present(pinarray.find_condition(protocol, pin=6))
    assert_delivered(delivery)
    assert_every_goal_confirmed(delivery)
    assert isinstance(delivery.ending, pinarray.Played)
    assert array.is_open and "open, idle" in repr(array) and array.url in repr(array)
    array.close()
    assert not array.is_open and "closed" in repr(array)
    assert at_rest_and_released(way.servos(array)) == []


@realtime
def test_stop_cuts_a_playing_stimulus_and_every_servo_rests_released(way, tmp_path):
    protocol = buzz(tmp_path, 10)
    array = way.open(protocol)
    armed = start_playing(array, protocol, way)
    before_ns = array.now_ns()
    report = array.stop()
    assert at_rest_and_released(way.servos(array)) == []  # as the servos show it
    assert report.complete and sorted(report.released_ids) == list(range(1, 17))
    delivery = armed.result(timeout_s=30)
    assert not delivery.delivered and isinstance(delivery.ending, pinarray.Cut)
    assert delivery.ending.by == "stop()" and delivery.ending.at_ns >= before_ns
    assert delivery.problem == "cut short by stop()"
    # The array stays open: the next stimulus turns torque on again, and cancel cuts it too.
    again = array.arm(pinarray.find_condition(protocol, pin=6))
    again.start()
    wait_moving(way.servos(array))
    again.cancel()
    assert at_rest_and_released(way.servos(array)) == []
    assert again.result(timeout_s=30).ending.by == "cancel()"


@realtime
def test_cancel_before_the_onset_moves_nothing(way, tmp_path):
    protocol = buzz(tmp_path, 0.4)
    array = way.open(protocol)
    armed = array.arm(pinarray.find_condition(protocol, pin=6))  # waits for its start
    armed.cancel()
    delivery = armed.result(timeout_s=30)
    assert isinstance(delivery.ending, pinarray.NotStarted)
    assert "before it started: nothing moved" in delivery.problem
    with pytest.raises(pinarray.PinArrayError, match="has started, been cancelled or ended"):
        armed.start()
    assert at_rest_and_released(way.servos(array)) == []


@realtime
def test_a_stimulus_armed_on_a_cue_starts_when_started(way, tmp_path):
    protocol = buzz(tmp_path, 0.4)
    array = way.open(protocol)
    armed = array.arm(pinarray.find_condition(protocol, pin=6))
    assert armed.onset_ns is None and not armed.done
    started_ns = array.now_ns()
    armed.start()
    delivery = armed.result(timeout_s=30)
    assert delivery.delivered, delivery.problem
    assert delivery.onset_ns >= started_ns  # its time zero: when the player took the start


@realtime
@pytest.mark.parametrize("leaving", ["close", "error"])
def test_close_and_an_error_leaving_the_block_cut_a_playing_stimulus(way, tmp_path, leaving):
    protocol = buzz(tmp_path, 10)
    array = way.open(protocol)
    with pytest.raises(KeyboardInterrupt) if leaving == "error" else nullcontext(), array:
        armed = start_playing(array, protocol, way)
        if leaving == "close":
            array.close()
        else:
            raise KeyboardInterrupt
    assert at_rest_and_released(way.servos(array)) == []
    ending = armed.result(timeout_s=30).ending
    assert isinstance(ending, pinarray.Cut)
    assert ending.by == ("close()" if leaving == "close"
                         else "leaving the with block on KeyboardInterrupt")


@realtime
def test_a_port_has_one_owner_named_to_any_other_opener_until_that_owner_dies(tmp_path):
    protocol = buzz(tmp_path, 0.4)
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import pinarray, sys; array = pinarray.open_array("
         f"pinarray.load_protocol({str(protocol.source)!r}), port={server.path!r}); "
         "print('held', flush=True); sys.stdin.read()"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(pinarray.PortInUse, match=f"in use by process {holder.pid} "):
            pinarray.open_array(protocol, port=server.path)
        assert not pinarray.find_servo_ports([server.path])  # not a byte sent to it
        holder.kill()  # no goodbye: the kernel lets the lock go with the process (and its player's)
        holder.wait(timeout=30)
        deadline = time.monotonic() + 30
        while True:
            try:
                array = pinarray.open_array(protocol, port=server.path)
                break
            except pinarray.PortInUse:  # its player process still resting the pins
                assert time.monotonic() < deadline
                time.sleep(0.05)
        with array, pytest.raises(pinarray.PortInUse, match=r"in use by an array of protocol "
                                                            r"'buzz' \(pinarray.open_array\) in "
                                                            r"this process"):
            pinarray.open_array(protocol, port=server.path)
    finally:
        if holder.poll() is None:
            holder.kill()
        server.stop()


# Started on a cue at once, not armed for a time: on a busy machine an onset a little ahead
# may pass before the player is ready, and nothing would move.
SCRIPT = """\
import pinarray, sys
protocol = pinarray.load_protocol(sys.argv[1])
array = pinarray.open_array(protocol, port=sys.argv[2])
armed = array.arm(pinarray.find_condition(protocol, pin=6))
armed.start()
print("armed", flush=True)
{ending}
"""


@realtime
@pytest.mark.parametrize("ending", ["the script's end", "Ctrl-C"])
def test_a_script_that_ends_or_is_interrupted_mid_stimulus_leaves_every_servo_released(
        tmp_path, ending):
    protocol = buzz(tmp_path, 10)
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    # The script ends once its stimulus plays (its stdin closed then), not after a sleep a busy
    # machine may spend before the stimulus starts.
    body = "sys.stdin.read()" if ending == "the script's end" else "armed.result()"
    script = tmp_path / "script.py"
    script.write_text(SCRIPT.format(ending=body))
    process = subprocess.Popen([sys.executable, str(script), str(protocol.source), server.path],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        assert process.stdout.readline().strip() == "armed"
        wait_moving(server.sim.servos)
        if ending == "Ctrl-C":
            process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=60)
        assert at_rest_and_released(server.sim.servos) == []
        if ending == "Ctrl-C":
            assert "KeyboardInterrupt" in stderr
        else:
            assert process.returncode == 0, stderr
    finally:
        if process.poll() is None:
            process.kill()
        server.stop()


MANY_FILES_SCRIPT = """
import os, resource, sys
import pinarray
from pinarray.testing import assert_delivered, assert_every_goal_confirmed

soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
if soft < 2048:
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(2048, hard), hard))
held = [os.open(os.devnull, os.O_RDONLY) for _ in range(1100)]
assert held[-1] >= 1024, held[-1]  # what opens next (the port, the player's channel) is higher
protocol = pinarray.load_protocol(sys.argv[1])
where = ({{"sim": "sim://", "clock": pinarray.MonotonicClock()}} if sys.argv[2] == "sim"
         else {{"port": sys.argv[2]}})
with pinarray.open_array(protocol, **where) as array:
    delivery = array.present(pinarray.find_condition(protocol, pin=6))
    assert_delivered(delivery)
    assert_every_goal_confirmed(delivery)
print("delivered")
"""


@realtime
@pytest.mark.parametrize("kind", ["sim", "pty"])
def test_a_script_holding_more_than_1024_files_plays_through_either_path(tmp_path, kind):
    # select watches descriptors below 1024 only: the port and the player's channel got
    # higher numbers in such a script, and open_array ended in select's ValueError.
    if resource.getrlimit(resource.RLIMIT_NOFILE)[1] < 2048:
        pytest.skip("this machine lets a process hold fewer than 2048 files")
    protocol = buzz(tmp_path, 0.4)
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start() if kind == "pty" else None
    try:
        script = tmp_path / "script.py"
        script.write_text(MANY_FILES_SCRIPT.format())
        done = subprocess.run([sys.executable, str(script), str(protocol.source),
                               server.path if server is not None else "sim"],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and done.stdout.strip() == "delivered", done.stderr
        if server is not None:
            assert at_rest_and_released(server.sim.servos) == []
    finally:
        if server is not None:
            server.stop()


def test_an_armed_stimulus_whose_onset_passes_before_it_can_start_is_not_delivered(tmp_path):
    # The host stalls between arming and playing: the stimulus ends "not delivered", nothing
    # moved, and waiting for it does not raise.
    class StallingClock(pinarray.VirtualClock):
        def now_ns(self):
            if threading.current_thread() is not threading.main_thread() and not self.stalled:
                self.stalled = True
                self._now_ns += 100_000_000  # 100 ms of a stalled host
            return super().now_ns()

        stalled = False

    protocol = buzz(tmp_path, 0.4)
    with pinarray.open_array(protocol, clock=StallingClock()) as array:
        armed = array.arm(pinarray.find_condition(protocol, pin=6),
                          at_ns=array.now_ns() + array.lead_ns)
        delivery = armed.result(timeout_s=30)
    assert isinstance(delivery.ending, pinarray.NotStarted) and not delivery.delivered
    assert "onset had passed" in delivery.problem and "nothing moved" in delivery.problem
    assert delivery.onset_ns == armed.onset_ns


def test_notices_go_to_the_pinarray_logger(tmp_path, caplog):
    protocol = buzz(tmp_path, 0.4)
    with caplog.at_level("INFO", logger="pinarray"), \
            pinarray.open_array(protocol, sim="sim://?drop_writes=0.3&seed=3") as array:
        delivery = array.present(pinarray.find_condition(protocol, pin=6))
    assert delivery.record.healed > 0
    said = [r.getMessage() for r in caplog.records if r.name == "pinarray"]
    assert any("written again and confirmed" in line for line in said)
    assert any("goal changes confirmed" in line for line in said)  # the verdict
    assert any("closed by leaving the with block" in line for line in said)


def test_the_public_errors_are_documented_classes_of_the_face():
    # PlaybackAborted (a fault mid-stimulus) and PortInUse are raised by public calls.
    for name in ("PlaybackAborted", "PortInUse"):
        error = getattr(pinarray, name)
        assert issubclass(error, pinarray.PinArrayError) and name in pinarray.__all__
    source = (REPO / "docs" / "reference" / "errors.md").read_text()
    assert "PlaybackAborted" in source and "PortInUse" in source
