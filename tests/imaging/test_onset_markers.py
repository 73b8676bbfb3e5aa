"""Markers at the onset: whoever plays a trial announces it, right after the onset frame's write.

An online EEG or BCI reader must learn of a stimulus as it starts, not once it ended. Stamps:
on Linux LSL's clock is CLOCK_MONOTONIC, the player process's clock too, so the outlet's
offset is exactly 0 (`pinarray.imaging.lsl.SAME_CLOCK_S`) and a stamp is ``at_ns / 1e9``: equal
to the schedule's time to a double's precision (1e-11 s at these magnitudes; 1 ns asked).
"""

import json
from pathlib import Path

import pytest

from pinarray.clock import MonotonicClock, ScaledClock
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.hardware.feetech.transport import open_bus
from pinarray.imaging.lsl import MarkerStream
from pinarray.player.markers import TrialMarkers
from pinarray.player.playback import play_prepared, prepare_trial
from pinarray.player.process import PlayerProcess
from pinarray.protocol.load import load_protocol
from pinarray.session.sitting import SessionRequest, Sitting
from pinarray.stop import StopRequest
from tests.hardware.lab import device_setup, pulse_train, sim_bus, targets
from tests.imaging.lsl_inlet import MarkerInlet, unique_stream_name
from tests.runs import REPO

IDS = tuple(range(1, 5))
NS = 1_000_000_000
STAMP_S = 1e-9  # a stamp is the schedule's time in s to a double's precision (module docstring)
MARKERS = TrialMarkers(json.dumps({"event": "onset"}), json.dumps({"event": "offset"}))


def lsl_loaded(pid: int) -> bool:
    """Whether process ``pid`` has liblsl mapped: it opened an LSL stream itself."""
    return "liblsl" in Path(f"/proc/{pid}/maps").read_text()


@pytest.fixture
def server():
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    yield server
    server.stop()


class Recorder:
    """An announcer that notes each marker, its stamp and how many goals were written by then."""

    def __init__(self, bus):
        self.bus = bus
        self.pushed: list[tuple[str, int, int]] = []
        self.closed = False

    def push(self, marker: str, at_ns: int) -> None:
        self.pushed.append((json.loads(marker)["event"], at_ns, self.bus.stats().goals_written))

    def close(self) -> None:
        self.closed = True


class Broken:
    def push(self, marker: str, at_ns: int) -> None:
        raise RuntimeError("liblsl: the outlet's buffer is gone")

    def close(self) -> None:
        pass


def test_the_onset_marker_goes_out_right_after_the_onset_frame_stamped_on_the_schedule():
    bus = sim_bus()
    trial = prepare_trial(bus, targets([(0, 1, 2100), (50_000_000, 1, 2048)], 100_000_000))
    recorder = Recorder(bus)
    report = play_prepared(bus, trial, bus.clock, markers=MARKERS, announcer=recorder)
    # After the onset frame's one goal, before the next frame's; the offset at the trial's end.
    assert recorder.pushed == [("onset", report.onset_ns, 1),
                               ("offset", report.onset_ns + 100_000_000, 2)]
    assert report.markers_sent == 2 and report.marker_problem == ""


def test_an_onset_marker_never_delays_a_frame_due_just_after_the_onset():
    bus = sim_bus()
    # A second frame 0.1 ms after the onset: less slack than the read-backs' guard, so the
    # onset marker waits for that frame's write.
    changes = [(0, 1, 2100), (100_000, 2, 2100), (50_000_000, 1, 2048), (50_000_000, 2, 2048)]
    recorder = Recorder(bus)
    report = play_prepared(bus, prepare_trial(bus, targets(changes, 100_000_000)), bus.clock,
                           markers=MARKERS, announcer=recorder)
    assert recorder.pushed[0] == ("onset", report.onset_ns, 2)
    assert report.delivery.delivered


def test_a_failing_marker_outlet_never_fails_the_trial_and_the_report_says_so():
    bus = sim_bus()
    report = play_prepared(bus, prepare_trial(bus, pulse_train([1, 6], 10, 2)), bus.clock,
                           markers=MARKERS, announcer=Broken())
    assert report.delivery.delivered and report.frames_sent == 4
    assert report.markers_sent == 0
    assert report.marker_problem == ("the onset marker was not sent: "
                                     "liblsl: the outlet's buffer is gone")


@pytest.mark.realtime
def test_the_player_process_sends_the_onset_marker_while_the_trial_still_plays(server):
    name = unique_stream_name()
    bus = open_bus(server.path, device_setup(IDS), MonotonicClock())
    player = PlayerProcess(bus, bus.link.wire.fd, StopRequest(), markers=MarkerStream(name))
    try:
        inlet = MarkerInlet(name, count=2)
        assert inlet.found.wait(60), "the player process opened no stream named so"
        assert lsl_loaded(player.process.pid)  # the stream is the player process's own
        trial = prepare_trial(bus, pulse_train(IDS, 2, 2))  # 1 s of pulses, ends at 1.2 s
        report = player.play(trial, tolerance_ns=NS, markers=MARKERS)
        markers = inlet.join()
    finally:
        player.close()
        bus.rest_and_release()
        bus.close()
    assert [m["event"] for m, _ in markers] == ["onset", "offset"]
    (_, onset_s), (_, offset_s) = markers
    assert onset_s == pytest.approx(report.onset_ns / NS, abs=STAMP_S)
    assert offset_s == pytest.approx((report.onset_ns + trial.end_ns) / NS, abs=STAMP_S)
    assert inlet.arrivals[0] < offset_s  # the reader knew while the pins still moved
    assert report.markers_sent == 2 and report.marker_problem == ""


@pytest.mark.realtime
def test_without_a_marker_stream_the_player_process_sends_no_marker_and_loads_no_lsl(server):
    bus = open_bus(server.path, device_setup(IDS), MonotonicClock())
    player = PlayerProcess(bus, bus.link.wire.fd, StopRequest())
    try:
        report = player.play(prepare_trial(bus, pulse_train(IDS, 10, 1)), tolerance_ns=NS,
                             markers=MARKERS)
        loaded = lsl_loaded(player.process.pid)
    finally:
        player.close()
        bus.rest_and_release()
        bus.close()
    assert report.markers_sent == 0 and report.marker_problem == ""
    assert not loaded


@pytest.mark.realtime
def test_a_sitting_with_lsl_sends_each_onset_marker_while_its_stimulus_still_plays(tmp_path):
    # The lab's rehearsal: the simulator in this process at --speed 1 (the playback announces).
    text = (REPO / "protocols" / "localisation.yaml").read_text()
    assert "    duration_s: 10\n" in text
    short = tmp_path / "localisation.yaml"
    short.write_text(text.replace("    duration_s: 10\n", "    duration_s: 1\n"))
    request = SessionRequest(load_protocol(short), "01", "1", "", None, None, 3, False)
    name = unique_stream_name()
    inlet = MarkerInlet(name, count=2)
    with Sitting(tmp_path / "results", clock_factory=lambda port: ScaledClock(1.0),
                 lsl_name=name) as sitting:
        sitting.connect(request)
        assert inlet.found.wait(60)
        session = sitting.open_session()
        session.begin()
        planned, schedule = session.current, session.current_schedule()
        session.present()
        markers = inlet.join()
    assert [(m["event"], m["trial"]) for m, _ in markers] == [("onset", planned.trial),
                                                             ("offset", planned.trial)]
    (_, onset_s), (_, offset_s) = markers
    assert inlet.arrivals[0] < offset_s  # before the stimulus ended, not after it
    # Both stamps through the same offset: their difference is the schedule's to a double's
    # precision, whatever the offset of the simulator's clock to LSL's.
    assert offset_s - onset_s == pytest.approx(schedule.end_ns / NS, abs=STAMP_S)
