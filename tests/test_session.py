"""Whole sessions on the simulated array in virtual time, checked row by row on disk."""

import csv
import itertools
import os
import random
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import BusError
from pinarray.grid import classify
from pinarray.hardware.delivery import DEFAULT_TOLERANCE_NS, DeliveryRecord, Presentation
from pinarray.journal.manifest import Provenance, RunStatus, read_manifest
from pinarray.journal.rows import read_trials
from pinarray.journal.runs import plan_entries, task_info
from pinarray.journal.writer import RunWriter
from pinarray.plan import make_plan
from pinarray.player.rig import Rig
from pinarray.protocol.load import load_protocol
from pinarray.session.trials import PAUSE_CUT_SHORT, Phase, Session, SessionError, task_label
from pinarray.stop import StoppableClock, Stopped, StopRequest
from tests.commands import Forked, pinarray_here
from tests.runs import VIRTUAL, write_short_localisation

S = 1_000_000_000  # ns per s
PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
LOCALISATION = PROTOCOLS / "localisation.yaml"
MOTION = PROTOCOLS / "apparent_motion.yaml"


def open_session(tmp_path, path, seed=3, stimulator=None):
    protocol = load_protocol(path)
    plan = make_plan(protocol, seed)
    clock = VirtualClock()
    writer = RunWriter.start(tmp_path, "01", "1", task_label(protocol), plan_entries(plan),
                             Provenance(seed, protocol.sha256, "sim://"), task_info(protocol),
                             VIRTUAL)
    rig = stimulator or Rig(protocol, None, None, clock)
    return Session(protocol, plan, writer, rig, clock), rig


def nothing_to_deliver(onset_ns):
    """What a stimulator that moves no servo reports: delivered, with no goal changes."""
    return Presentation(onset_ns, DeliveryRecord(0, 0, 0, 0, 0, DEFAULT_TOLERANCE_NS))


def rows_on_disk(session):
    return read_trials(session.writer.paths.beh_tsv)


def test_a_whole_localisation_session_logs_every_trial_as_it_happened(tmp_path):
    # The seed's plan with 1 s stimuli: ten seconds of simulated servos per trial add nothing.
    session, rig = open_session(tmp_path, write_short_localisation(tmp_path))
    answers = {}
    with rig:
        session.begin()
        while session.phase is Phase.READY:
            session.present()
            assert session.phase is Phase.RESPONSE
            planned = session.current
            # the subject is right on odd trials and names the pin to the right otherwise
            answer = planned.condition.pin if planned.trial % 2 else planned.condition.pin % 16 + 1
            answers[planned.trial] = answer
            session.respond(answer)
    assert session.phase is Phase.DONE
    rows = rows_on_disk(session)
    assert [r.trial for r in rows] == list(range(1, 27))
    for row, planned in zip(rows, session.plan.trials, strict=True):
        assert (row.pin, row.frequency_hz) == (planned.condition.pin, float(planned.condition.frequency_hz))
        assert row.response == str(answers[row.trial])
        assert row.error_class == classify(row.pin, answers[row.trial])
        assert row.status == "ok" and row.practice == planned.practice and row.block == planned.block
        assert row.duration_ns == 1 * S and row.response_time_ns >= 1 * S
    onsets = [r.onset_ns for r in rows]
    assert onsets[0] == 0  # the run's time zero is its first trial's stimulus onset
    assert all(b - a >= 4 * S for a, b in itertools.pairwise(onsets))  # 1 s stimulus + 3 s interval
    assert read_manifest(session.writer.paths.manifest).status == "completed"
    with open(session.writer.paths.events_tsv) as stream:
        assert len(list(csv.reader(stream, delimiter="\t"))) == 27


def test_a_whole_motion_session_scores_felt_motion_and_direction(tmp_path):
    session, rig = open_session(tmp_path, MOTION)
    cycle = ["right", "left", "none", "unsure"]
    with rig:
        session.begin()
        while session.phase is Phase.READY:
            session.present()
            session.respond(cycle[session.current.trial % 4])
    rows = rows_on_disk(session)
    assert len(rows) == 13
    for row in rows:
        answer = cycle[row.trial % 4]
        assert row.response == answer
        assert row.perceived_motion is (answer != "none")
        if answer == "none" or row.direction == "none":
            assert row.direction_correct is None
        else:
            assert row.direction_correct is (answer == row.direction)
    assert {r.direction for r in rows} == {"left", "right", "none"}


def test_redo_logs_the_first_presentation_and_presents_the_trial_again(tmp_path):
    session, rig = open_session(tmp_path, LOCALISATION)
    with rig:
        session.begin()
        session.present()
        first = session.current.trial
        session.redo()
        assert session.phase is Phase.READY and session.current.trial == first
        session.present()
        session.respond(1)
    rows = rows_on_disk(session)
    assert [(r.trial, r.status) for r in rows] == [(first, "redone"), (first, "ok")]


def test_pause_holds_the_session_until_resumed(tmp_path):
    session, rig = open_session(tmp_path, LOCALISATION)
    with rig:
        session.begin()
        session.pause()
        with pytest.raises(SessionError, match="session is at paused"):
            session.present()
        session.resume()
        assert session.phase is Phase.READY
        session.present()
        session.pause()
        session.resume()
        session.respond("none")
    assert rows_on_disk(session)[0].category == "none"


class HeldStimulus:
    """A stimulator whose first stimulus plays until a stop is requested, as a long one would
    (the player looks at the stop request between frames); later ones end at once."""

    def __init__(self, stop):
        self.stop = stop
        self.playing = threading.Event()
        self.calls = 0

    def present(self, schedule):
        self.calls += 1
        if self.calls == 1:
            self.playing.set()
            self.stop.wait(10)
            self.stop.raise_if_requested()
        return nothing_to_deliver(0)


def test_a_pause_during_a_stimulus_cuts_it_short_logs_it_and_presents_it_again_after_resume(tmp_path):
    stop = StopRequest()
    session, _ = open_session(tmp_path, LOCALISATION, stimulator=HeldStimulus(stop))
    session.begin()
    first = session.current
    worker = threading.Thread(target=session.present)
    worker.start()
    assert session.stimulator.playing.wait(10) and session.phase is Phase.STIMULUS
    session.pause()
    assert session.pausing and session.phase is Phase.STIMULUS  # until the stimulus stops
    stop.request("paused")
    worker.join(10)
    assert session.phase is Phase.PAUSED and not session.pausing
    (cut,) = rows_on_disk(session)
    assert (cut.trial, cut.status, cut.status_reason) == (first.trial, "aborted", PAUSE_CUT_SHORT)
    stop.clear()
    session.resume()
    assert session.phase is Phase.READY and session.current == first
    session.present()
    session.respond(first.condition.pin)
    assert [(r.trial, r.status) for r in rows_on_disk(session)] == [(first.trial, "aborted"),
                                                                    (first.trial, "ok")]


def test_a_pause_without_a_stop_lets_the_stimulus_end_and_holds_the_run_at_the_answer(tmp_path):
    class PausedWhilePlaying:
        def present(self, schedule):
            session.pause()  # from another thread in the UI; the effect is the same
            assert session.pausing and session.phase is Phase.STIMULUS
            return nothing_to_deliver(0)

    session, _ = open_session(tmp_path, LOCALISATION, stimulator=PausedWhilePlaying())
    session.begin()
    session.present()
    assert session.phase is Phase.PAUSED and rows_on_disk(session) == []
    session.resume()
    assert session.phase is Phase.RESPONSE
    session.respond("none")
    assert [r.status for r in rows_on_disk(session)] == ["ok"]


def test_a_pause_during_the_inter_trial_interval_presents_nothing_until_resumed(tmp_path):
    stop = StopRequest()

    class HeldInterval(VirtualClock):
        """Waits between looks at the stop request until one is made, as a real 3 s would."""

        def __init__(self):
            super().__init__()
            self.waiting = threading.Event()

        def doze_until_ns(self, deadline_ns):
            self.waiting.set()
            stop.wait(10)

    calls = []

    def present(schedule):
        calls.append(schedule)
        return nothing_to_deliver(0)

    stimulator = type("Counting", (), {"present": staticmethod(present)})()
    session, _ = open_session(tmp_path, LOCALISATION, stimulator=stimulator)
    session.clock = StoppableClock(HeldInterval(), stop)
    session.begin()
    session.present()  # the first trial has no interval before it
    session.respond("none")
    second = session.current
    worker = threading.Thread(target=session.present)
    worker.start()
    assert session.clock.clock.waiting.wait(10) and session.phase is Phase.READY
    session.pause()
    assert session.pausing
    stop.request("paused")
    worker.join(10)
    assert session.phase is Phase.PAUSED and len(calls) == 1
    assert [r.status for r in rows_on_disk(session)] == ["ok"]  # nothing was presented to log
    stop.clear()
    session.resume()
    assert session.phase is Phase.READY and session.current == second


def test_practice_and_counted_trials_are_numbered_apart(tmp_path):
    session, _ = open_session(tmp_path, LOCALISATION, stimulator=type(
        "Nothing", (), {"present": staticmethod(lambda schedule: nothing_to_deliver(0))})())
    session.begin()
    seen = []
    while session.phase is Phase.READY:
        seen.append(str(session.number_of(session.current)))
        session.present()
        session.respond("none")
        if len(seen) == 3:
            assert (session.done_of(practice=True), session.done_of(practice=False)) == (2, 1)
    assert seen[:3] == ["practice 1 of 2", "practice 2 of 2", "trial 1 of 24"]
    assert seen[-1] == "trial 24 of 24" and len(seen) == 26


def test_a_crash_marks_the_run_crashed_and_the_trial_cut_short(tmp_path):
    session, rig = open_session(tmp_path, LOCALISATION)
    with rig:
        session.begin()
        session.present()
        session.abort("RuntimeError: a bug", RunStatus.CRASHED)
    manifest = read_manifest(session.writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("crashed", "RuntimeError: a bug")
    assert [r.status for r in rows_on_disk(session)] == ["aborted"]


def test_a_bad_answer_is_refused_and_nothing_is_written(tmp_path):
    session, rig = open_session(tmp_path, LOCALISATION)
    with rig:
        session.begin()
        session.present()
        with pytest.raises(SessionError, match="expected a pin number from 1 to 16 or 'none', found 17"):
            session.respond(17)
    assert rows_on_disk(session) == []


def test_abort_marks_the_trial_and_the_run_and_resume_presents_it_again(tmp_path):
    session, rig = open_session(tmp_path, LOCALISATION)
    with rig:
        session.begin()
        session.present()
        session.respond(4)
        session.present()
        aborted = session.current.trial
        session.abort("subject needed a break")
    manifest = read_manifest(session.writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("aborted", "subject needed a break")
    assert [r.status for r in rows_on_disk(session)] == ["ok", "aborted"]

    protocol = load_protocol(LOCALISATION)
    writer = RunWriter.resume(session.writer.paths, VIRTUAL)
    resumed = Session(protocol, make_plan(protocol, 3), writer, None, VirtualClock())
    assert resumed.queue[0].trial == aborted and len(resumed.queue) == 25


def test_a_signal_landing_as_the_run_is_aborted_waits_until_its_row_and_status_are_written(
        tmp_path, monkeypatch):
    # Stranger attack 12: a third Ctrl-C landed in the abort's sidecar write; the run said
    # "aborted" on the screen and "crashed" in its manifest.
    from pinarray.stop import stop_on_signals

    session, rig = open_session(tmp_path, LOCALISATION)
    finish = session.writer.finish

    def tapped_while_finishing(status, reason):
        os.kill(os.getpid(), signal.SIGINT)  # again: it raises at once where it lands
        for _ in range(10_000):  # every chance to run in here
            pass
        return finish(status, reason)

    monkeypatch.setattr(session.writer, "finish", tapped_while_finishing)
    with rig, stop_on_signals(StopRequest()) as stop:
        session.begin()
        session.present()
        stop.request("stopped by SIGINT", signal.SIGINT)  # the first tap
        with pytest.raises(Stopped, match="again"):
            session.abort("stopped by SIGINT")
    manifest = read_manifest(session.writer.paths.manifest)
    assert (manifest.status, manifest.abort_reason) == ("aborted", "stopped by SIGINT")
    assert [r.status for r in rows_on_disk(session)] == ["aborted"]


class FailingOnce:
    """A stimulator whose first presentation fails as a lost servo would."""

    def __init__(self, clock):
        self.calls = 0
        self.clock = clock

    def present(self, schedule):
        self.calls += 1
        if self.calls == 1:
            raise BusError("servo 6 (pin 6): no status packet after 3 retries")
        return nothing_to_deliver(self.clock.now_ns())

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass


def test_a_bus_fault_marks_the_trial_invalid_and_retry_presents_it_again(tmp_path):
    session, _ = open_session(tmp_path, LOCALISATION, stimulator=FailingOnce(VirtualClock()))
    session.stimulator.clock = session.clock
    session.begin()
    session.present()
    assert session.phase is Phase.FAULT and "servo 6" in session.fault
    session.retry()
    session.present()
    session.respond(6)
    rows = rows_on_disk(session)
    assert [r.status for r in rows] == ["invalid", "ok"] and rows[0].trial == rows[1].trial


def batch(*args):
    """`pinarray batch` in this process; the tests of a kill or a signal start one of its own."""
    return pinarray_here("batch", *args)


def test_batch_with_a_responses_file_runs_the_session_it_describes(tmp_path):
    plan = make_plan(load_protocol(MOTION), 9)
    answers = tmp_path / "answers.csv"
    answers.write_text("trial,response\n" + "".join(f"{t.trial},left\n" for t in plan.trials))
    result = batch(str(MOTION), "--subject", "p7", "--responses", str(answers), "--seed", "9",
                   "--results", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    (beh,) = (tmp_path / "out").rglob("*_beh.tsv")
    rows = read_trials(beh)
    assert [r.response for r in rows] == ["left"] * 13
    assert [r.trial for r in rows] == [t.trial for t in plan.trials]


def test_batch_refuses_unsafe_labels_and_incomplete_answers_in_one_line(tmp_path):
    result = batch(str(MOTION), "--subject", "../x", "--observer", "default", "--results", str(tmp_path))
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    assert "subject" in result.stderr and "Traceback" not in result.stderr
    answers = tmp_path / "a.csv"
    answers.write_text("trial,response\n1,left\n")
    result = batch(str(MOTION), "--subject", "p1", "--responses", str(answers), "--results", str(tmp_path))
    assert result.returncode == 2 and "no response for trial(s) 2, 3" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.long
@pytest.mark.parametrize("rows_before_kill", [None, 0, 1, 9, 20])
def test_a_batch_killed_at_any_moment_resumes_with_exactly_the_remaining_trials(tmp_path, rows_before_kill):
    out = tmp_path / "out"
    # The seed's plan with 1 s stimuli: what is on disk at the kill is the point. Paced at 50x
    # a trial takes 80 ms, so the kill lands before the 26th.
    common = [str(write_short_localisation(tmp_path)), "--subject", "k1", "--observer",
              "default", "--seed", "21", "--results", str(out)]
    if rows_before_kill is None:  # a fresh interpreter: the kill lands in its start-up
        process = subprocess.Popen([sys.executable, "-m", "pinarray", "batch", *common,
                                    "--time-scale", "50"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(0.1)  # most likely before the manifest exists: nothing written yet
    else:  # forked from this process: killed mid-run all the same, without a start-up
        process = Forked(tmp_path / "killed", "batch", *common, "--time-scale", "50")
    if rows_before_kill is not None:
        deadline = time.monotonic() + 60
        while True:  # kill once that many rows are on disk (plus a random few ms)
            found = list(out.rglob("*_beh.tsv"))
            if found and len(read_trials(found[0])) >= rows_before_kill:
                break
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.01)
        time.sleep(random.Random(rows_before_kill).random() * 0.1)
    os.kill(process.pid, signal.SIGKILL)
    process.wait(timeout=30)
    killed_rows = [r.trial for r in read_trials(next(out.rglob("*_beh.tsv")))] if list(out.rglob("*_beh.tsv")) else []
    result = batch(*common, "--resume")
    if not list(out.rglob("*_manifest.json")):  # killed before its run existed: nothing to resume
        assert result.returncode == 2 and "no unfinished run of localisation" in result.stderr
        result = batch(*common)
    assert result.returncode == 0, result.stderr
    (beh,) = out.rglob("*_beh.tsv")
    rows = read_trials(beh)
    ok = [r for r in rows if r.status == "ok"]
    assert [r.trial for r in ok] == list(range(1, 27))  # none lost, none repeated, plan order
    onsets = [r.onset_ns for r in rows]  # one time base: the resumed sitting continues it
    assert onsets[0] == 0 and all(b > a for a, b in itertools.pairwise(onsets))
    first_sitting = [r.trial for r in ok if not r.resumed]
    if killed_rows or any(r.resumed for r in ok):
        assert first_sitting == killed_rows  # what was on disk stayed, the rest is marked resumed
    else:
        assert first_sitting == list(range(1, 27))  # killed before its manifest: a fresh run
    (manifest,) = out.rglob("*_manifest.json")
    assert read_manifest(manifest).status == "completed"


def test_sigterm_during_a_batch_aborts_the_run_and_marks_the_trial_cut_short(tmp_path):
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "batch", str(LOCALISATION), "--subject", "t1", "--observer",
         "default", "--time-scale", "20", "--results", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )
    deadline = time.monotonic() + 60
    while not list(out.rglob("*_beh.tsv")) or len(read_trials(next(out.rglob("*_beh.tsv")))) < 2:
        assert time.monotonic() < deadline and process.poll() is None
        time.sleep(0.05)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + signal.SIGTERM, stderr
    lines = stderr.strip().splitlines()
    assert "aborted, resume with: pinarray batch" in lines[-2] and "--resume" in lines[-2]
    assert lines[-1] == "pinarray: stopped by SIGTERM"
    (manifest,) = out.rglob("*_manifest.json")
    assert read_manifest(manifest).status == "aborted"
    rows = read_trials(next(out.rglob("*_beh.tsv")))
    # a trial cut short is logged aborted; between trials there is nothing to cut short
    assert rows[-1].status in ("ok", "aborted") and all(r.status == "ok" for r in rows[:-1])
    # simulated time (paced): the cut trial's duration is what it played, whatever the load
    assert rows[-1].status == "ok" or (rows[-1].duration_ns < 10 * S
                                       and rows[-1].status_reason == "stopped by SIGTERM")


def test_a_second_present_during_the_interval_is_refused_not_played_twice(tmp_path):
    class IntervalClock(VirtualClock):
        """Holds the first inter-trial wait until released, as a real interval would."""

        def __init__(self):
            super().__init__()
            self.waiting = threading.Event()
            self.release = threading.Event()

        def sleep_until_ns(self, deadline_ns):
            self.waiting.set()
            self.release.wait(10)
            super().sleep_until_ns(deadline_ns)

    class Counting:
        calls = 0

        def present(self, schedule):
            Counting.calls += 1
            return nothing_to_deliver(0)

    session, _ = open_session(tmp_path, LOCALISATION, stimulator=Counting())
    session.clock = IntervalClock()
    session.begin()
    worker = threading.Thread(target=session.present)
    worker.start()
    assert session.clock.waiting.wait(10) and session.phase is Phase.READY
    with pytest.raises(SessionError, match="already being presented"):
        session.present()
    session.clock.release.set()
    worker.join(10)
    assert Counting.calls == 1 and session.phase is Phase.RESPONSE


def test_an_incomplete_answers_file_leaves_no_half_started_run(tmp_path):
    answers = tmp_path / "a.csv"
    answers.write_text("trial,response\n1,left\n")
    result = batch(str(MOTION), "--subject", "p2", "--responses", str(answers), "--results", str(tmp_path / "out"))
    assert result.returncode == 2
    assert not (tmp_path / "out").exists()


def test_results_that_cannot_be_written_are_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    result = batch(str(MOTION), "--subject", "p3", "--observer", "default", "--results", str(blocker))
    assert result.returncode == 2 and "cannot write results there: Not a directory" in result.stderr
    assert "Traceback" not in result.stderr and blocker.read_text() == "not a folder"


def test_the_resume_command_a_failed_trial_suggests_resumes_the_run_as_typed(tmp_path):
    # Issue 46's re-run: the suggestion left out --results and --sim (and the answers), so
    # typed as given it found no run. Here every one of them differs from the default.
    from tests.lab_protocols import short_copy

    results = tmp_path / "my results"
    protocol = short_copy("toj", tmp_path)
    slow_bus = "sim://?baud=38400"  # the two pins' strokes are not measured: a trial fails
    failed = pinarray_here("batch", protocol, "--subject", "k1", "--observer", "default",
                           "--results", results, "--sim", slow_bus, "--speed", "0", cwd=tmp_path)
    assert failed.returncode == 3, failed.stderr
    said = failed.stderr.strip().splitlines()[-1]
    command = shlex.split(said[said.index("resume with: ") + 13:-1])
    assert command[:2] == ["pinarray", "batch"] and command[-1] == "--resume"
    again = pinarray_here(*command[1:], cwd=tmp_path)
    assert "starting a new run" not in again.stderr  # it found the run ...
    (manifest,) = results.rglob("*_manifest.json")
    assert len(read_manifest(manifest).sittings) == 2  # ... and resumed it, on the same bus
    assert again.returncode == 3 and again.stderr.strip().splitlines()[-1] == said


def test_a_scanner_timed_run_is_offered_a_new_run_as_typed_and_refused_a_resume(tmp_path):
    # Issue 46's fourth pass: the printed resume of a run timed from scanner volumes left out
    # --trigger, and typed as given finished the run with no scanner (exit 0), though its time
    # zero was the old scan's first volume; with --trigger the same resume was refused.
    from tests.lab_protocols import short_copy

    results = tmp_path / "my results"
    protocol = short_copy("toj", tmp_path)
    slow_bus = "sim://?baud=38400"  # the two pins' strokes are not measured: a trial fails
    failed = pinarray_here("batch", protocol, "--subject", "k1", "--observer", "default",
                           "--results", results, "--sim", slow_bus, "--speed", "0",
                           "--trigger", "emulate:2", cwd=tmp_path)
    assert failed.returncode == 3, failed.stderr
    said = failed.stderr.strip().splitlines()[-1]
    assert "a run timed from scanner volumes cannot be resumed" in said
    command = shlex.split(said.split("start a new run in a new scan with: ")[1])
    assert "--resume" not in command and command[-2:] == ["--trigger", "emulate:2"]
    (manifest,) = results.rglob("*_manifest.json")
    before = {f: f.read_bytes() for f in results.rglob("*") if f.is_file()}
    # The resume, with no scanner as with one, is refused in one line, nothing written.
    for scanner in ([], ["--trigger", "emulate:2"]):
        words = [w for w in command[1:] if w not in ("--trigger", "emulate:2")]
        resumed = pinarray_here(*words, *scanner, "--resume", cwd=tmp_path)
        assert resumed.returncode == 2, resumed.stderr
        (line,) = resumed.stderr.splitlines()
        assert "cannot be resumed" in line or "cannot go on in a new scan" in line
        assert {f: f.read_bytes() for f in results.rglob("*") if f.is_file()} == before
    # The command printed works as typed: a new run, in a new scan.
    again = pinarray_here(*command[1:], cwd=tmp_path)
    assert again.returncode == 3 and "waiting for the scanner" in again.stderr
    assert len(list(results.rglob("*_manifest.json"))) == 2
    assert len(read_manifest(manifest).sittings) == 1  # the first run not gone on
