"""One sitting at the array, as the UI and batch both drive it: on the simulated array in
virtual time, its runs checked on disk and its servos checked after it closes."""

import threading
import time
from contextlib import nullcontext
from pathlib import Path

import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.journal.manifest import read_manifest
from pinarray.journal.rows import read_trials
from pinarray.journal.runs import unfinished_run
from pinarray.player.rig import Rig
from pinarray.protocol.load import load_protocol
from pinarray.session.sitting import MAX_ATTEMPTS, NotDelivered, SessionRequest, Sitting
from pinarray.session.trials import Phase
from pinarray.stop import Stopped
from tests.runs import write_short_localisation

LOCALISATION = Path(__file__).resolve().parent.parent / "protocols" / "localisation.yaml"


class RigNeverOnTime(Rig):
    """The simulated rig with a delivery tolerance of 1 ns: the wire alone makes every goal
    change late, so no stimulus is delivered as scheduled."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.tolerance_ns = 1


class RigLateEveryOtherTime(Rig):
    """The simulated rig, every other stimulus late from the first: each trial fails once,
    then plays."""

    presented = 0

    def present(self, schedule):
        self.presented += 1
        if self.presented % 2 == 0:
            return super().present(schedule)
        tolerance_ns, self.tolerance_ns = self.tolerance_ns, 1
        try:
            return super().present(schedule)
        finally:
            self.tolerance_ns = tolerance_ns


class RigStoppedMidStimulus(Rig):
    """The simulated rig, its first stimulus stopped as it starts (a signal, quitting)."""

    def present(self, schedule):
        self.stop.request("stopped by SIGHUP", 1)
        return super().present(schedule)


def sitting_on(results: Path, rig_factory=Rig) -> tuple[Sitting, SessionRequest]:
    """A sitting in virtual time with the seed's plan at 1 s stimuli (how each trial goes is
    the point, not ten seconds of simulated servos)."""
    sitting = Sitting(results, clock_factory=lambda port: VirtualClock(), rig_factory=rig_factory)
    (results / "protocol").mkdir(parents=True, exist_ok=True)
    protocol = load_protocol(write_short_localisation(results / "protocol"))
    request = SessionRequest(protocol, "01", "1", "", None, None, 3, False)
    return sitting, request


def answer_pin_one(question):
    return 1


def rows(session):
    return read_trials(session.writer.paths.beh_tsv)


def assert_at_rest(protocol, sim):
    """Every servo back at its pin's rest position with torque off."""
    for pin in protocol.device.pins:
        servo = sim.servos[pin.servo_id]
        assert not servo.torque_enabled, f"servo {pin.servo_id} still has torque"
        assert abs(servo.position_steps - pin.rest_steps) <= 4, f"pin {pin.pin} not at rest"


def test_an_undelivered_trial_is_presented_three_times_then_the_run_stops_naming_it(tmp_path):
    sitting, request = sitting_on(tmp_path, RigNeverOnTime)
    attempts = []
    with sitting:
        sim = sitting.connect(request).bus.sim
        session = sitting.open_session()
        with pytest.raises(NotDelivered) as gave_up:
            sitting.run_scripted(answer_pin_one, failed=attempts.append)
    first = session.plan.trials[0].trial
    assert [(a.planned.trial, a.attempt, a.last) for a in attempts] == [
        (first, 1, False), (first, 2, False), (first, MAX_ATTEMPTS, True)]
    assert str(gave_up.value) == f"trial {first} failed 3 times"
    assert [(r.trial, r.status) for r in rows(session)] == [(first, "invalid")] * 3
    manifest = read_manifest(session.writer.paths.manifest)
    assert manifest.status == "aborted"
    assert manifest.abort_reason.startswith(
        f"trial {first} failed 3 times: the stimulus was not delivered as scheduled")
    assert unfinished_run(tmp_path, "01", "1", request.task) is not None  # resumable
    assert_at_rest(request.protocol, sim)


def test_a_trial_that_fails_once_then_plays_does_not_count_against_the_next(tmp_path):
    sitting, request = sitting_on(tmp_path, RigLateEveryOtherTime)
    with sitting:
        sitting.connect(request)
        session = sitting.open_session()
        sitting.run_scripted(answer_pin_one)
    assert session.phase is Phase.DONE
    statuses = [r.status for r in rows(session)]
    assert statuses == ["invalid", "ok"] * session.total


def test_a_stop_asked_for_mid_run_aborts_the_run_with_its_reason_and_rests_the_pins(tmp_path):
    sitting, request = sitting_on(tmp_path)
    answered = []

    def answer(question):
        answered.append(question.trial.trial)
        if len(answered) == 2:
            sitting.stop.request("stopped by SIGTERM", 15)  # as the signal handler does
        return 1

    with pytest.raises(Stopped, match="stopped by SIGTERM"), sitting:
        sim = sitting.connect(request).bus.sim
        session = sitting.open_session()
        sitting.run_scripted(answer)
    manifest = read_manifest(session.writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("aborted", "stopped by SIGTERM")
    assert [r.status for r in rows(session)] == ["ok", "ok"]
    assert sitting.rig is None
    assert_at_rest(request.protocol, sim)


def test_a_sitting_closed_by_a_stop_request_cuts_the_stimulus_short_and_leaves_the_pins_at_rest(
        tmp_path):
    sitting, request = sitting_on(tmp_path, RigStoppedMidStimulus)
    sim = sitting.connect(request).bus.sim
    session = sitting.open_session()
    session.begin()
    assert sitting.present() is None  # cut short, not a failed stimulus
    assert session.phase is Phase.STIMULUS
    safe = sitting.finish("stopped by SIGHUP")
    assert safe is not None and safe.complete
    (cut,) = rows(session)
    assert (cut.status, cut.status_reason) == ("aborted", "stopped by SIGHUP")
    assert read_manifest(session.writer.paths.manifest).status == "aborted"
    assert sitting.rig is None and sitting.session is None
    assert_at_rest(request.protocol, sim)


def test_an_error_inside_a_sitting_marks_the_run_crashed_and_rests_the_pins(tmp_path):
    sitting, request = sitting_on(tmp_path)

    def answer(question):
        raise RuntimeError("a bug in the answers")

    with pytest.raises(RuntimeError), sitting:
        sim = sitting.connect(request).bus.sim
        session = sitting.open_session()
        sitting.run_scripted(answer)
    manifest = read_manifest(session.writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("crashed", "RuntimeError: a bug in the answers")
    assert_at_rest(request.protocol, sim)


def test_a_sitting_left_before_its_run_ends_marks_it_and_rests_the_pins(tmp_path):
    sitting, request = sitting_on(tmp_path)
    with sitting:
        sim = sitting.connect(request).bus.sim
        session = sitting.open_session()
        session.begin()
        sitting.present()  # the subject's answer never comes: the experimenter leaves
    manifest = read_manifest(session.writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("aborted", "the sitting ended")
    assert [r.status for r in rows(session)] == ["aborted"]
    assert_at_rest(request.protocol, sim)


def test_a_sitting_closed_while_it_connects_leaves_the_new_rig_at_rest_and_closed(tmp_path):
    # q while the pre-flight still says "Connecting": the close waits for the connection,
    # which then closes the rig it just made instead of keeping it held.
    import threading

    made: list[Rig] = []
    closer: list[threading.Thread] = []

    def connecting(*args, **kwargs):
        closer.append(threading.Thread(target=sitting.finish))
        closer[0].start()
        while not sitting._closing:  # the close has begun, and waits for this connection
            pass
        made.append(Rig(*args, **kwargs))
        return made[0]

    sitting, request = sitting_on(tmp_path, rig_factory=connecting)
    with pytest.raises(Stopped):
        sitting.connect(request)
    closer[0].join(10)
    assert sitting.rig is None
    servos = made[0].bus.sim.servos.values()
    assert not any(s.torque_enabled for s in servos)


def test_stimuli_play_on_the_wall_clock_when_lsl_markers_stamp_them(tmp_path):
    # A rehearsal plays each stimulus in the simulator's own time; with LSL markers, stamped
    # on this machine's clock for another machine's recording, on the wall clock.
    from pinarray.clock import ScaledClock
    from tests.imaging.lsl_inlet import unique_stream_name

    request = SessionRequest(load_protocol(LOCALISATION), "01", "1", "", None, None, 3, False)
    with Sitting(tmp_path, clock_factory=lambda port: ScaledClock(1.0)) as rehearsal:
        assert rehearsal.connect(request).plays_in_own_time
    with Sitting(tmp_path, clock_factory=lambda port: ScaledClock(1.0),
                 lsl_name=unique_stream_name()) as marked:
        assert not marked.connect(request).plays_in_own_time


def test_a_rig_whose_player_process_will_not_end_quietly_still_rests_the_pins(tmp_path):
    sitting, request = sitting_on(tmp_path)
    rig = sitting.connect(request)

    class Interrupted:
        def close(self):
            raise KeyboardInterrupt  # a second Ctrl-C as the player process left

    rig.player = Interrupted()
    with pytest.raises(KeyboardInterrupt):
        sitting.release()
    servos = rig.bus.sim.servos.values()
    assert not any(s.torque_enabled for s in servos)


def test_a_scanner_that_fails_to_close_does_not_keep_the_rig_held(tmp_path):
    sitting, request = sitting_on(tmp_path)
    rig = sitting.connect(request)

    class Stuck:
        def close(self):
            raise OSError(5, "Input/output error")

    sitting.scanner = Stuck()
    with pytest.raises(OSError):
        sitting.release()
    assert sitting.rig is None
    assert not any(s.torque_enabled for s in rig.bus.sim.servos.values())


def test_a_worker_that_asks_for_the_rig_after_the_release_is_told_it_is_not_connected(tmp_path):
    # The pre-flight's timing check, pin test and return-delay change run in workers, and the
    # experimenter may leave the pre-flight as one starts: the UI shows the error the sitting
    # raises. An assert said so before, which `python -O` (PYTHONOPTIMIZE=1) removes: the worker
    # then failed on None instead, which the UI does not expect.
    sitting, request = sitting_on(tmp_path)
    sitting.connect(request)
    sitting.release()
    for call in (lambda: sitting.check_timing(0), lambda: sitting.test_pin(1),
                 lambda: sitting.lower_return_delay(0), sitting.connected):
        with pytest.raises(PinArrayError, match="not connected"):
            call()


def test_servos_connected_again_are_the_ones_the_release_left_with_their_lowered_return_delay(
        tmp_path):
    # Releasing turns torque off and closing the port does nothing to servos: what was written
    # until power-off stays, on the simulated array as on real servos.
    sitting, request = sitting_on(tmp_path)
    with sitting:
        first = sitting.connect(request)
        assert set(first.bus.link.return_delay_ns.values()) == {500_000}
        sitting.lower_return_delay(0)
        sitting.release()
        again = sitting.connect(request)
        assert again is not first and again.bus.sim is first.bus.sim
        assert set(again.bus.link.return_delay_ns.values()) == {0}  # read by its handshake
        assert all(s.return_delay_ns == 0 for s in again.bus.sim.servos.values())


def test_servos_connected_again_on_a_clock_of_its_own_move_on_it_and_deliver_every_stimulus(
        tmp_path):
    # As batch connects each run: a new clock at 0, behind where the first run left the servos.
    sitting, request = sitting_on(tmp_path)
    pin = request.protocol.device.pins[0]
    with sitting:
        first = sitting.connect(request, VirtualClock())
        sitting.open_session()
        sitting.run_scripted(answer_pin_one)
        assert first.clock.now_ns() > 60 * 1_000_000_000
        sitting.release()
        again = sitting.connect(request, VirtualClock())
        sim = again.bus.sim
        assert sim is first.bus.sim
        servo = sim.servos[pin.servo_id]
        servo.start_recording()
        start_ns = again.clock.now_ns()
        sitting.test_pin(pin.pin)
        # The horn went to and fro on the new clock, while the pin test played.
        wiggle = [abs(servo.position_at_ns(t) - pin.rest_steps)
                  for t in range(start_ns, again.clock.now_ns(), 1_000_000)]
        assert max(wiggle) > 60  # up and down the seed's stroke of 65 steps
        session = sitting.open_session()
        sitting.run_scripted(answer_pin_one)
    assert session.phase is Phase.DONE
    assert {r.status for r in rows(session)} == {"ok"}
    assert_at_rest(request.protocol, sim)


@pytest.mark.realtime
@pytest.mark.parametrize("stopped", [False, True], ids=["whole run", "stopped mid-stimulus"])
def test_a_sitting_through_a_serial_port_runs_as_on_the_simulator_and_leaves_servos_released(
        tmp_path, stopped):
    # The same sitting, its servos behind a pseudo-terminal: the player process plays, and the
    # servos themselves show how they were left.
    from pinarray.clock import MonotonicClock
    from pinarray.hardware.feetech.faults import SimConfig
    from pinarray.hardware.feetech.serve import PtyServer
    from tests.test_library_paths import at_rest_and_released, buzz

    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    try:
        rig_factory = RigStoppedMidStimulus if stopped else Rig
        sitting = Sitting(tmp_path, clock_factory=lambda port: MonotonicClock(),
                          rig_factory=rig_factory)
        request = SessionRequest(buzz(tmp_path, 0.3), "01", "1", "", server.path, None, 3, False)
        failed = []
        with pytest.raises(Stopped) if stopped else nullcontext(), sitting:
            assert sitting.connect(request).isolated  # played by a player process
            session = sitting.open_session()
            sitting.run_scripted(lambda question: 6, failed=failed.append)
        manifest = read_manifest(session.writer.paths.manifest)
        if stopped:
            assert (manifest.status, manifest.abort_reason) == ("aborted", "stopped by SIGHUP")
        else:
            assert manifest.status == "completed"
            # On the wall clock a busy machine may starve the served bus: a stimulus is then
            # reported not delivered, logged invalid and presented again, and nothing else.
            assert all(f.fault.startswith("the stimulus was not delivered as scheduled: ")
                       for f in failed), failed
            written = rows(session)
            assert [r.status_reason for r in written if r.status == "invalid"] == [
                f.fault for f in failed]
            assert [r.status for r in written if r.status != "invalid"] == ["ok"] * session.total
        assert at_rest_and_released(server.sim.servos) == []
    finally:
        server.stop()


def test_a_second_finish_returns_only_once_the_first_has_rested_the_pins(tmp_path):
    # A signal's close and a hang-up's, one on the UI's worker and one on its watch: the
    # second leaves the process (os._exit) as soon as its finish returns, which must not cut
    # the first one's rest short.
    resting, rested = threading.Event(), threading.Event()

    class RigSlowToRest(Rig):
        """The simulated rig, whose rest takes a while (a lossy bus healing its goals)."""

        def close(self):
            resting.set()
            time.sleep(0.5)
            safe = super().close()
            rested.set()
            return safe

    sitting, request = sitting_on(tmp_path, rig_factory=RigSlowToRest)
    sitting.connect(request, VirtualClock())
    sitting.open_session()
    first = threading.Thread(target=sitting.finish, args=("stopped by SIGTERM",))
    first.start()
    assert resting.wait(30)
    sitting.finish("stopped by SIGHUP")
    assert rested.is_set()
    first.join()
    manifest = read_manifest(sitting.runs[-1][1].writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("aborted", "stopped by SIGTERM")
