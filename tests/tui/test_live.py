"""The run screen's computed parts: which pins are up at a moment, and the running counts."""

from pinarray.journal.seam import rows_of
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol
from pinarray.schedule import compile_trial
from pinarray.tui.live import LiftTimeline, live_lines
from tests.tui.conftest import LOCALISATION

MS = 1_000_000


def test_a_5_hz_pin_is_up_for_the_first_100_ms_of_each_200_ms_cycle_and_down_after_the_end():
    protocol = load_protocol(LOCALISATION)
    trial = next(t for t in make_plan(protocol, 3).trials
                 if t.condition.pin == 6 and t.condition.frequency_hz == 5)
    timeline = LiftTimeline.from_targets(compile_trial(protocol, trial).targets, {6: 2048})
    up = [ms for ms in (-1, 0, 50, 99, 100, 150, 200, 250, 9_999, 10_001)
          if timeline.lifted_at(ms * MS)]
    assert up == [0, 50, 99, 200, 250]


def test_the_shortest_lift_of_a_5_hz_train_is_its_half_cycle():
    # The run screen draws lifts only where they last two frames (100 ms at 20 fps): this
    # train's, at --speed 1; not at --speed 20, where its 100 ms are 5 ms of the wall.
    protocol = load_protocol(LOCALISATION)
    trial = next(t for t in make_plan(protocol, 3).trials if t.condition.frequency_hz == 5)
    timeline = LiftTimeline.from_targets(compile_trial(protocol, trial).targets,
                                         {trial.condition.pin: 2048})
    assert timeline.shortest_change_ns() == 100 * MS


def record(trial, error_class, practice=False, status="ok"):
    return LocalisationRecord(trial=trial, block=0 if practice else 1, task="t", onset_ns=0,
                              duration_ns=10**9, status=status,
                              response="none" if error_class == "none" else "1", pin=1,
                              frequency_hz=5.0, practice=practice,
                              error_class=None if error_class == "none" else error_class)


def test_counts_leave_out_practice_and_redone_trials():
    lines = live_lines(rows_of("localisation"),
                       [record(1, "A", practice=True), record(2, "correct"),
                        record(3, "B", status="redone"), record(3, "B"), record(4, "none")])
    assert lines == ["correct 1/3", "A 0  B 1  C 0  D 0", "nothing felt 1",
                     "practice done 1 (not counted)"]
