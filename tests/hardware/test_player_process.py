"""The player in its own process, on servos behind a pseudo-terminal: every way out is safe."""

import os
import signal
import subprocess
import sys
import threading
import time
from fractions import Fraction
from pathlib import Path

import pytest

from pinarray.clock import MonotonicClock
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.hardware.feetech.transport import open_bus
from pinarray.player.child import process_state
from pinarray.player.playback import OnsetAt, OnsetPassed, prepare_trial
from pinarray.player.process import PlayerDied, PlayerProcess, StartCue
from pinarray.stop import Stopped, StopRequest

from .lab import REST_STEPS, SignalFromAnotherThread, device_setup, pulse_train

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = [pytest.mark.realtime,
              # one worker builds the module's fixture once (make test runs --dist loadgroup)
              pytest.mark.xdist_group("start-up window")]

DEMO = Path(__file__).resolve().parents[2] / "protocols" / "demo.yaml"
IDS = tuple(range(1, 5))


@pytest.fixture
def server():
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    yield server
    server.stop()


def wait_until_safe(server, ids, timeout_s=30.0):
    """Every servo in ``ids`` at rest with torque off, as the lab checks after a stop."""
    deadline = time.monotonic() + timeout_s
    while True:
        servos = [server.sim.servos[i] for i in ids]
        for servo in servos:
            servo.read(56, 2, time.monotonic_ns())  # bring the simulated horn up to now
        unsafe = [s.servo_id for s in servos
                  if s.torque_enabled or abs(s.position_steps - REST_STEPS) > 4]
        if not unsafe:
            return
        assert time.monotonic() < deadline, f"servo(s) {unsafe} not at rest with torque off"
        time.sleep(0.05)


def connected(server, ids=IDS):
    clock = MonotonicClock()
    bus = open_bus(server.path, device_setup(ids), clock)
    return bus, PlayerProcess(bus, bus.link.wire.fd, StopRequest())


def maps_numpy(pid: int) -> bool:
    """Whether process ``pid`` has numpy's compiled core mapped: it imported numpy."""
    return "numpy" in Path(f"/proc/{pid}/maps").read_text()


def test_a_trial_played_in_the_player_process_is_verified_ends_at_rest_and_loads_no_numpy(server):
    bus, player = connected(server)
    try:
        # A tolerance no scheduler hiccup reaches, and no stroke checked (a starved simulator
        # samples too seldom to judge a cycle): this test is about verification, not timing
        # (timing is measured by `make bench`). At 2 Hz a busy machine's simulated servos have
        # 250 ms to confirm each frame's goals before the next.
        report = player.play(prepare_trial(bus, pulse_train(IDS, 2, 3)), tolerance_ns=10**9,
                             stroke_tolerance=Fraction(0))
        # The player process has played, sampled and measured a trial, and waits for the next:
        # numpy (a tenth of a second of its start-up) never came in; the report's arrays are
        # this process's.
        in_player = maps_numpy(player.process.pid)
    finally:
        player.close()
    assert maps_numpy(os.getpid())  # the maps are read right: this process did import numpy
    assert not in_player
    assert report.trace and all(len(t.time_ns) == len(t.position_steps) for t in report.trace)
    assert report.sent_ns.dtype == report.scheduled_ns.dtype == "int64"
    assert report.frames_sent == 6
    assert report.delivery.scheduled == 24 and report.delivery.delivered
    assert report.delivery.confirmed + report.delivery.healed == 24
    bus.rest_and_release()
    bus.close()
    wait_until_safe(server, IDS)


def test_a_trial_held_ready_in_the_player_process_starts_on_its_cue_never_before(server):
    bus, player = connected(server)
    try:
        cue = StartCue()
        asked_ns = time.monotonic_ns()
        threading.Timer(0.3, cue.give).start()
        # 2 Hz: a busy machine's simulated servos have 250 ms to confirm the first goals.
        report = player.play(prepare_trial(bus, pulse_train(IDS, 2, 1)), onset=cue,
                             tolerance_ns=10**9)
        assert report.onset_ns >= asked_ns + 300_000_000  # its time zero: when the cue came
        assert report.delivery.missing == 0
        # An onset already passed is refused before anything is sent, saying by how much.
        with pytest.raises(OnsetPassed) as passed:
            player.play(prepare_trial(bus, pulse_train(IDS, 10, 1)),
                        onset=OnsetAt(time.monotonic_ns() - 10**7), tolerance_ns=10**9)
        assert passed.value.late_ns >= 10**7 and player.alive
    finally:
        player.close()
    bus.rest_and_release()
    bus.close()
    wait_until_safe(server, IDS)


def test_a_stop_request_ends_the_trial_in_the_player_process_with_pins_at_rest(server):
    bus, player = connected(server)
    threading.Timer(0.5, player.stop.request, args=("stopped by SIGTERM", 15)).start()
    try:
        with pytest.raises(Stopped, match="stopped by SIGTERM"):
            player.play(prepare_trial(bus, pulse_train(IDS, 5, 20)), tolerance_ns=10**7)
        assert player.alive  # ready for the next trial
    finally:
        player.close()
    bus.close()
    wait_until_safe(server, IDS)


def test_a_player_process_killed_mid_trial_is_noticed_and_the_parent_rests_the_pins(server):
    bus, player = connected(server)
    threading.Timer(0.5, os.kill, args=(player.process.pid, signal.SIGKILL)).start()
    with pytest.raises(PlayerDied, match="killed by signal 9") as died:
        player.play(prepare_trial(bus, pulse_train(IDS, 5, 20)), tolerance_ns=10**7)
    assert died.value.safe_stop.complete  # how soon it is noticed: `make bench`
    player.close()
    player.close()  # again (a rig's close after a Ctrl-C as it replaced it): nothing more
    bus.close()
    wait_until_safe(server, IDS)


def test_a_player_killed_under_a_script_that_ignores_sigchld_is_not_said_to_have_exited_well(
        server):
    # Some supervisors start a lab's script with SIGCHLD ignored: the system then keeps no
    # exit status of its children, and a player killed mid-trial read as "exit status 0".
    previous = signal.signal(signal.SIGCHLD, signal.SIG_IGN)
    try:
        bus, player = connected(server)
        threading.Timer(0.5, os.kill, args=(player.process.pid, signal.SIGKILL)).start()
        with pytest.raises(PlayerDied, match=r"\(its exit status unknown: SIGCHLD is ignored") \
                as died:
            player.play(prepare_trial(bus, pulse_train(IDS, 5, 20)), tolerance_ns=10**7)
        assert died.value.safe_stop.complete
        player.close()
        bus.close()
    finally:
        signal.signal(signal.SIGCHLD, previous)
    wait_until_safe(server, IDS)


@pytest.mark.parametrize("sent", ["SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGINT"])
def test_a_signal_sent_to_the_player_process_itself_rests_the_pins_and_stops_the_run(server, sent):
    # As when `pkill` or systemd signals every process of pinarray: a stop, not a failure.
    bus, player = connected(server)
    threading.Timer(0.5, os.kill, args=(player.process.pid, getattr(signal, sent))).start()
    with pytest.raises(Stopped, match=f"stopped by {sent}"):
        player.play(prepare_trial(bus, pulse_train(IDS, 5, 20)), tolerance_ns=10**7)
    assert player.process.returncode == 128 + getattr(signal, sent)  # it made the pins safe
    player.close()
    bus.close()
    wait_until_safe(server, IDS)


def play_demo(server, *extra):
    return subprocess.Popen(
        [sys.executable, "-m", "pinarray", "play", str(DEMO), "--port", server.path, *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def wait_for_first_trial(process, server, timeout_s=30.0):
    """Until the first 2 s stimulus plays: a pin away from rest, as its servo shows it (not a
    sleep, which a busy machine may spend before the trial starts or past its end)."""
    line = process.stdout.readline()
    assert "played by a player process" in line, line + process.stderr.read()
    deadline = time.monotonic() + timeout_s  # a hang guard, not a timing check
    while True:
        now_ns = time.monotonic_ns()
        servos = [server.sim.servos[i] for i in range(1, 17)]
        for servo in servos:
            servo.read(56, 2, now_ns)  # bring the simulated horn up to now
        if any(abs(s.position_steps - REST_STEPS) > 20 for s in servos):
            return
        assert process.poll() is None and time.monotonic() < deadline, "no pin ever moved"
        time.sleep(0.005)


@pytest.mark.parametrize("sent", ["SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGPIPE",
                                  "SIGTERM", "SIGINT"])
def test_every_signal_to_play_leaves_pins_at_rest_and_torque_off(server, sent):
    process = play_demo(server)
    wait_for_first_trial(process, server)
    number = getattr(signal, sent)
    process.send_signal(number)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + number, stderr
    assert f"stopped by {sent}" in stderr and "Traceback" not in stderr
    wait_until_safe(server, range(1, 17))


def test_a_killed_play_leaves_its_player_process_to_rest_the_pins(server):
    process = play_demo(server)
    wait_for_first_trial(process, server)
    process.kill()  # SIGKILL: the parent cannot do anything; its player process must
    process.wait(timeout=30)
    wait_until_safe(server, range(1, 17))


GOAL_POSITION, TORQUE_ENABLE, WRITE, SYNC_WRITE = 42, 40, 0x03, 0x83


def turns_torque_on(packet) -> bool:
    """A goal (an STS servo takes torque with it) or a torque-enable write."""
    if packet.instruction == SYNC_WRITE:
        return packet.params[0] == GOAL_POSITION
    return packet.instruction == WRITE and (
        packet.params[0] == GOAL_POSITION or packet.params[:2] == bytes([TORQUE_ENABLE, 1]))


def lifts_a_pin(packet) -> bool:
    """The first frame of a trial: a sync write sending some pin away from rest."""
    if packet.instruction != SYNC_WRITE or packet.params[0] != GOAL_POSITION:
        return False
    length, body = packet.params[1], packet.params[2:]
    goals = [int.from_bytes(body[k + 1:k + 3], "little") for k in range(0, len(body), length + 1)]
    return any(goal != REST_STEPS for goal in goals)


class StartUpWatch:
    """Notes, from the servos' side, when torque first goes on and when the first frame comes;
    kills ``pid`` a given time after torque first went on (0: as that packet arrives)."""

    def __init__(self, kill_after_s: float | None = None):
        self.kill_after_s = kill_after_s
        self.pid: int | None = None
        self.torque_on_ns: int | None = None
        self.first_frame_ns: int | None = None
        self.killed = threading.Event()

    def __call__(self, packet) -> None:
        if self.torque_on_ns is None and turns_torque_on(packet):
            self.torque_on_ns = time.monotonic_ns()
            if self.kill_after_s == 0:
                self._kill()
            elif self.kill_after_s is not None:
                threading.Timer(self.kill_after_s, self._kill).start()
        if self.first_frame_ns is None and lifts_a_pin(packet):
            self.first_frame_ns = time.monotonic_ns()

    def _kill(self) -> None:
        if self.pid is not None and not self.killed.is_set():
            os.kill(self.pid, signal.SIGKILL)
            self.killed.set()


@pytest.fixture(scope="module")
def start_up_window_s():
    """How long, on this machine, from torque first going on to the first frame (one run)."""
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    watch = StartUpWatch()
    server.sim.packet_listener = watch
    process = play_demo(server)
    try:
        deadline = time.monotonic() + 60  # a hang guard
        while watch.first_frame_ns is None and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        process.kill()
        process.communicate(timeout=30)
        server.stop()
    assert watch.torque_on_ns is not None and watch.first_frame_ns is not None
    return (watch.first_frame_ns - watch.torque_on_ns) / 1e9


@pytest.mark.parametrize("moment", [0.0, 0.01, 0.05, 0.15, 0.3, 0.5, 0.7, 0.9, 1.0])
def test_killing_play_at_any_moment_of_its_start_up_leaves_every_pin_at_rest_and_torque_off(
        server, start_up_window_s, moment):
    # ``moment``: where in the window from the first torque write to the first frame, as a
    # fraction of it; the window was measured on this machine by one run left alone.
    watch = StartUpWatch(kill_after_s=moment * start_up_window_s)
    server.sim.packet_listener = watch
    process = play_demo(server)
    watch.pid = process.pid
    try:
        assert watch.killed.wait(60), "play never turned torque on"
        process.wait(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
        process.communicate(timeout=30)
    wait_until_safe(server, range(1, 17))


def test_a_stop_signal_taken_by_another_thread_wakes_the_player_waiting_between_requests():
    # The player process waits for its parent's next request with no timeout. Python runs a
    # signal's handler only when the main thread next runs: a stop signal given to another
    # thread (a marker stream's), or landing just before the wait began, must still wake it
    # and end it (as `sim-serve`'s wait, tests/hardware/test_pty.py), not wait for a message.
    from multiprocessing import Pipe

    from pinarray.player.child import ControlledClock, Parent, woken_by_signals
    from pinarray.stop import raise_on_signals

    parent_end, child_end = Pipe()
    with pytest.raises(Stopped, match="SIGTERM"), raise_on_signals("the player process"), \
            woken_by_signals() as woken_fd:
        clock = ControlledClock(child_end, 1_000_000, Parent(os.getppid()), woken_fd)
        with SignalFromAnotherThread(lambda: parent_end.send("a request")) as signalled:
            clock.wait_for_request()
    assert not signalled.slept_through, "the player slept through the signal until its parent wrote"


def test_a_player_process_frozen_part_way_through_a_long_answer_is_killed_not_waited_on():
    # An answer bigger than the socket between them (here 400 000 wake-ups measured, some
    # 2 MB; a stimulus of minutes gives one) comes in pieces. A player stopped (SIGSTOP) once
    # its first piece has come never sends the rest: the parent waited on it for ever.
    player = PlayerProcess(None, None, StopRequest(), realtime=False)
    child = player.process.pid
    read = player.conn._read

    def frozen_after_the_length(count, *how):
        data = read(count, *how)
        if count == 8:  # the answer's length: the child is writing the rest
            os.kill(child, signal.SIGSTOP)
            while process_state(child) not in ("T", "t"):
                time.sleep(0.001)
        return data

    player.conn._read = frozen_after_the_length
    outcome = {}

    def measure():
        try:
            outcome["lateness"] = player.measure_wake_ups(100_000_000, 250)
        except PlayerDied as died:
            outcome["error"] = died

    measuring = threading.Thread(target=measure, daemon=True)
    measuring.start()
    measuring.join(timeout=60)
    hung = measuring.is_alive()
    if hung:
        os.kill(child, signal.SIGKILL)  # ends the read that waits on it, and so this test
        measuring.join(timeout=30)
    player.close()
    assert not hung, "the parent waited for the rest of a frozen player's answer for ever"
    assert "SIGSTOP" in str(outcome.get("error")) and "killed" in str(outcome["error"]), outcome
    assert player.process.poll() is not None  # killed, not left stopped
