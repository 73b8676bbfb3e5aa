"""One time base per run: onsets in seconds from the first trial, continuing across sittings."""

import csv
import itertools
import json
from dataclasses import replace
from datetime import datetime, timedelta, timezone

from hypothesis import given
from hypothesis import strategies as st

from pinarray.clock import MonotonicClock, PacedClock, ScaledClock, VirtualClock
from pinarray.journal.manifest import read_manifest
from pinarray.journal.rows import read_trials
from pinarray.journal.runs import open_run, time_scale_of
from pinarray.journal.timebase import (
    REAL_TIME,
    ClockKind,
    TimeScale,
    resumed_start_ns,
    seconds_text,
)
from pinarray.journal.writer import RunWriter
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.player.rig import Rig
from pinarray.protocol.load import load_protocol
from pinarray.session.trials import Phase, Session, task_label
from tests.commands import pinarray_here
from tests.runs import (
    PROVENANCE,
    REPO,
    VIRTUAL,
    localisation_plan,
    start_run,
    write_short_localisation,
)

S = 1_000_000_000  # ns per s
MOTION = REPO / "protocols" / "apparent_motion.yaml"
T0 = datetime(2024, 5, 1, 14, 3, 7, tzinfo=timezone(timedelta(hours=2)))


def sitting(root, resume, stop_after=None):
    """Run a localisation sitting in virtual time (a new process's clock: it starts at 0), the
    seed's plan at 1 s stimuli."""
    (root / "protocol").mkdir(parents=True, exist_ok=True)
    protocol = load_protocol(write_short_localisation(root / "protocol"))
    clock = VirtualClock()
    writer, plan = open_run(protocol, root, "01", "1", task_label(protocol), resume=resume,
                            seed=3, port_url="sim://", clock=clock)
    with Rig(protocol, None, None, clock) as rig, writer:
        session = Session(protocol, plan, writer, rig, clock)
        session.begin()
        while session.phase is Phase.READY:
            if stop_after is not None and session.done_count == stop_after:
                session.present()
                session.abort("the subject needed a break")
                break
            session.present()
            session.respond(session.current.condition.pin)
    return writer.paths


def test_onsets_are_seconds_from_the_first_trial_and_continue_after_a_resume(tmp_path):
    paths = sitting(tmp_path, resume=False, stop_after=9)
    before = read_trials(paths.beh_tsv)
    sitting(tmp_path, resume=True)
    rows = read_trials(paths.beh_tsv)
    onsets = [r.onset_ns for r in rows]
    assert onsets[0] == 0  # the run's time zero is its first trial's stimulus onset
    assert all(b > a for a, b in itertools.pairwise(onsets))
    # The second sitting's clock started at 0 again; on the run's time base it continues
    # after the end of the last trial of the first (the one cut short).
    resumed = [r for r in rows if r.resumed]
    assert min(r.onset_ns for r in resumed) > max(r.end_ns for r in before)
    assert [r.trial for r in rows if r.status == "ok"] == list(range(1, 27))
    manifest = read_manifest(paths.manifest)
    assert [s.start_ns for s in manifest.sittings][1] == max(r.end_ns for r in before)
    # In the file the times are decimal seconds, exactly.
    with open(paths.beh_tsv, newline="") as handle:
        cells = [row["stimulus_onset"] for row in csv.DictReader(handle, delimiter="\t")]
    assert cells == [seconds_text(t) for t in onsets] and cells[0] == "0"
    with open(paths.events_tsv, newline="") as handle:
        assert [row["onset"] for row in csv.DictReader(handle, delimiter="\t")] == cells


def _run_with_one_trial(root, clock, wall_at, port="/dev/ttyUSB0"):
    """A run whose zero is fixed at ``wall_at`` and whose only trial lasted 10 s, closed."""
    writer = start_run(root, "01", "localisation", localisation_plan((4, 10), (7, 3)),
                       clock=clock, provenance=replace(PROVENANCE, port=port),
                       wall=lambda: wall_at)
    writer.set_time_zero(sitting_start_ns=-S // 50, zero_ago_ns=0)
    writer.write_trial(LocalisationRecord(trial=1, block=1, task="localisation", onset_ns=0,
                                          duration_ns=10 * S, response="4", pin=4,
                                          frequency_hz=10.0, error_class="correct"))
    writer.close()
    return writer.paths


def test_in_real_time_the_pause_between_sittings_counts(tmp_path):
    paths = _run_with_one_trial(tmp_path, REAL_TIME, T0)
    resumed = RunWriter.resume(paths, REAL_TIME, wall=lambda: T0 + timedelta(minutes=5))
    resumed.close()
    assert resumed.sitting_start_ns == 300 * S  # five minutes after the zero, not 10 s


def test_sped_up_real_time_counts_the_pause_sped_up_and_simulated_time_does_not(tmp_path):
    scaled = TimeScale(ClockKind.SCALED, 10.0)
    paths = _run_with_one_trial(tmp_path / "scaled", scaled, T0)
    resumed = RunWriter.resume(paths, scaled, wall=lambda: T0 + timedelta(minutes=1))
    resumed.close()
    assert resumed.sitting_start_ns == 600 * S
    paths = _run_with_one_trial(tmp_path / "virtual", VIRTUAL, T0)
    resumed = RunWriter.resume(paths, VIRTUAL, wall=lambda: T0 + timedelta(hours=1))
    resumed.close()
    assert resumed.sitting_start_ns == 10 * S  # the end of the last trial on file


def test_each_sitting_is_in_the_manifest_and_described_in_the_sidecars(tmp_path):
    paths = _run_with_one_trial(tmp_path, REAL_TIME, T0)
    paced = TimeScale(ClockKind.PACED, 20.0)
    RunWriter.resume(paths, paced, wall=lambda: T0 + timedelta(minutes=5)).close()
    manifest = read_manifest(paths.manifest)
    assert [(s.number, s.started_at, s.clock, s.start_ns) for s in manifest.sittings] == [
        (1, "2024-05-01T14:03:07+02:00", REAL_TIME, -S // 50),
        (2, "2024-05-01T14:08:07+02:00", paced, 10 * S)]
    assert manifest.time_zero.at == "2024-05-01T14:03:07.000000+02:00"
    for sidecar in (paths.beh_json, paths.events_json):
        time_base = json.loads(sidecar.read_text())["TimeBase"]
        assert time_base["Zero"] == "the stimulus onset of the run's first trial"
        assert time_base["ZeroAt"] == "2024-05-01T14:03:07.000000+02:00"
        first, second = time_base["Sittings"]
        assert (first["StartedAt"], first["Clock"], first["TimeScale"], first["RunTimeAtStart"]) == (
            "2024-05-01T14:03:07+02:00", "real", 1.0, -0.02)
        assert (second["StartedAt"], second["Clock"], second["TimeScale"],
                second["RunTimeAtStart"]) == ("2024-05-01T14:08:07+02:00", "paced", 20.0, 10.0)
        assert "paced at 20x real time" in second["Description"] and "at 10 s" in second["Description"]
        assert time_base["Simulated"] is True  # a paced sitting is a rehearsal, not data


def test_a_run_on_real_servos_in_real_time_is_not_marked_simulated(tmp_path):
    paths = _run_with_one_trial(tmp_path, REAL_TIME, T0, port="/dev/ttyUSB0")
    time_base = json.loads(paths.beh_json.read_text())["TimeBase"]
    assert time_base["Simulated"] is False
    assert [s["Description"] for s in time_base["Sittings"]] == [
        "real time; joins the run's time base at -0.02 s"]


def test_a_sped_up_rehearsal_is_marked_as_such_in_the_manifest_and_the_sidecar(tmp_path):
    result = pinarray_here("batch", MOTION, "--subject", "01", "--observer", "default",
                           "--time-scale", "50", "--results", tmp_path)
    assert result.returncode == 0, result.stderr
    (manifest_path,) = tmp_path.rglob("*_manifest.json")
    (only,) = read_manifest(manifest_path).sittings
    assert (only.clock.kind, only.clock.factor) == (ClockKind.PACED, 50.0)
    assert datetime.fromisoformat(only.started_at).utcoffset() is not None  # a zone, always
    (sidecar,) = tmp_path.rglob("*_beh.json")
    time_base = json.loads(sidecar.read_text())["TimeBase"]
    assert time_base["Simulated"] is True
    assert time_base["Sittings"][0]["TimeScale"] == 50.0
    assert "rehearsal paced at 50x real time" in time_base["Sittings"][0]["Description"]


def test_a_zero_given_to_the_session_is_what_the_sidecars_say(tmp_path):
    writer = start_run(tmp_path, "01", "localisation", localisation_plan((4, 10)))
    writer.set_time_zero(sitting_start_ns=-2 * S, zero_ago_ns=0,
                         event="the first counted scanner volume")
    writer.close()
    beh = json.loads(writer.paths.beh_json.read_text())
    events = json.loads(writer.paths.events_json.read_text())
    assert beh["TimeBase"]["Zero"] == events["TimeBase"]["Zero"] == "the first counted scanner volume"
    assert beh["stimulus_onset"]["Description"].endswith("Zero: the first counted scanner volume.")
    assert events["onset"]["Description"].endswith("Zero: the first counted scanner volume.")


def test_each_kind_of_session_clock_is_recorded_as_what_it_measures():
    assert time_scale_of(MonotonicClock()) == REAL_TIME  # real servos
    assert time_scale_of(ScaledClock(1.0)) == REAL_TIME  # the UI's simulated array, 1x
    assert time_scale_of(ScaledClock(10.0)) == TimeScale(ClockKind.SCALED, 10.0)
    assert time_scale_of(PacedClock(50.0)) == TimeScale(ClockKind.PACED, 50.0)  # batch --time-scale
    assert time_scale_of(VirtualClock()) == VIRTUAL  # batch without --time-scale, the tests


nanoseconds = st.integers(0, 10**15)
scales = st.one_of(st.just(REAL_TIME), st.builds(lambda f: TimeScale(ClockKind.SCALED, f),
                                                 st.floats(0.01, 10_000)),
                   st.just(VIRTUAL), st.builds(lambda f: TimeScale(ClockKind.PACED, f),
                                               st.floats(0.01, 10_000)))


@given(last_end=nanoseconds, pause_us=st.integers(-10**9, 10**12), clock=scales)
def test_a_resumed_sitting_never_starts_before_the_end_of_the_last_trial(last_end, pause_us, clock):
    now = T0 + timedelta(microseconds=pause_us)
    start = resumed_start_ns(last_end, T0, now, clock)
    assert start >= last_end
    if clock.kind.follows_wall_clock:
        # In wall-clock time the pause counts (times the scale), whatever the clock reads.
        assert start >= round(pause_us * 1000 * clock.factor) - 1
    else:
        assert start == last_end
    assert resumed_start_ns(None, T0, now, clock) is None  # nothing on file: a fresh zero


class _WallClock:
    """A wall clock that records each sleep and oversleeps each by ``late_ns``."""

    def __init__(self, late_ns=0):
        self.now, self.late_ns, self.sleeps = 0, late_ns, []

    def now_ns(self):
        return self.now

    def doze_until_ns(self, deadline_ns):
        self.sleeps.append(deadline_ns - self.now)
        self.now = deadline_ns + self.late_ns


def test_the_hosts_computing_between_paced_waits_is_paid_from_the_sleeps_not_added():
    # A simulated trial at 20x: every 4 ms of simulated time the host computes 0.1 ms (a
    # motion sample); 10 s of stimulus take their 0.5 s of wall time, not 0.5 s + 0.25 s.
    wall = _WallClock(late_ns=60_000)
    clock = PacedClock(20.0, base=wall)
    for step in range(1, 2_501):
        wall.now += 100_000  # computing
        clock.sleep_until_ns(step * 4_000_000)
    assert clock.now_ns() == 10_000_000_000
    assert abs(wall.now - 500_000_000) <= 1_000_000 + 100_000  # a sleep's worth, a step's
    # A host slower than the pace (2 ms a step at 20x: 0.2 ms allowed) is as late as its
    # computing, and does not sleep on top of it.
    wall = _WallClock()
    clock = PacedClock(20.0, base=wall)
    for step in range(1, 101):
        wall.now += 2_000_000
        clock.sleep_until_ns(step * 4_000_000)
    assert wall.now == 200_000_000 and wall.sleeps == []


def test_a_paced_rehearsal_sleeps_its_many_short_waits_together_and_keeps_the_pace():
    # A simulated bus waits for every exchange: 20 000 waits of 20 us, paced at 50x, owe
    # 8 ms of wall time; slept one by one they cost the host a sleep each.
    wall = _WallClock(late_ns=60_000)
    clock = PacedClock(50.0, base=wall)
    for step in range(1, 20_001):
        clock.sleep_until_ns(step * 20_000)
    assert clock.now_ns() == 400_000_000
    assert len(wall.sleeps) <= 8  # each sleep at least MIN_WALL_SLEEP_NS of the 8 ms owed
    # the OS's oversleeping is owed back by the following waits, not added to the pace
    assert 8_000_000 - 1_000_000 <= wall.now <= 8_000_000 + 1_000_000
