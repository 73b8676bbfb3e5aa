"""Adaptive designs as a lab runs them: each value decided from the rows on disk, resumed exactly."""

from fractions import Fraction
from pathlib import Path

import pytest

from pinarray.adaptive.psychometric import Psychometric
from pinarray.analysis.adaptive_subject import AdaptiveSubject, parse_psychometric
from pinarray.analysis.load import load_run
from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.delivery import DEFAULT_TOLERANCE_NS, DeliveryRecord, Presentation
from pinarray.journal.manifest import Provenance, RunStatus, read_manifest
from pinarray.journal.rows import read_trials
from pinarray.journal.runs import plan_entries, task_info
from pinarray.journal.writer import RunWriter
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol
from pinarray.session.trials import Phase, Session, task_label
from tests.runs import VIRTUAL

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
STAIRCASES = PROTOCOLS / "staircase_motion.yaml"
QUEST = PROTOCOLS / "quest_stroke.yaml"


class Stimulator:
    """Presents every trial at once; a trial numbered in ``fail`` is not delivered, once."""

    def __init__(self, clock, fail=()):
        self.clock, self.fail, self.schedules = clock, set(fail), []

    def present(self, schedule):
        self.schedules.append(schedule)
        failing = self.fail and self.session.current.trial in self.fail
        if failing:
            self.fail.discard(self.session.current.trial)
        missing = 1 if failing else 0
        return Presentation(self.clock.now_ns(), DeliveryRecord(
            1, 1 - missing, 0, missing, 0, DEFAULT_TOLERANCE_NS,
            "1 goal change never confirmed" if failing else ""))


def open_session(root, path, seed=11, fail=(), resume=False):
    protocol = load_protocol(path)
    plan = make_plan(protocol, seed)
    clock = VirtualClock()
    label = task_label(protocol)
    if resume:
        writer = RunWriter.resume(read_writer_paths(root, label), VIRTUAL)
    else:
        writer = RunWriter.start(root, "01", "1", label, plan_entries(plan),
                                 Provenance(seed, protocol.sha256, "sim://"),
                                 task_info(protocol), VIRTUAL)
    stimulator = Stimulator(clock, fail)
    session = Session(protocol, plan, writer, stimulator, clock)
    stimulator.session = session
    return session, stimulator


def read_writer_paths(root, label):
    from pinarray.journal.paths import RunPaths

    return RunPaths(root, "01", "1", label, 1)


def answer_all(session, subject, stop_after=None):
    """Answer the run's trials as ``subject`` would, up to ``stop_after`` answers."""
    if session.phase is Phase.INSTRUCTIONS:
        session.begin()
    answered = 0
    while session.phase in (Phase.READY, Phase.FAULT) and answered != stop_after:
        if session.phase is Phase.FAULT:
            session.retry()
        session.present()
        if session.phase is Phase.RESPONSE:
            planned, presented = session.current, session.presented
            session.respond(subject.respond(planned.trial, planned.condition, planned.catch,
                                            presented.value), response_time_ns=None)
            answered += 1


def subject_for(path, **function):
    protocol = load_protocol(path)
    spec = ",".join(f"{k}={v}" for k, v in function.items()) or "default"
    return AdaptiveSubject(protocol, parse_psychometric(spec, protocol.design.adaptive), 5)


def steps(rows):
    return [(r.trial, r.adaptive.procedure, r.adaptive.intensity, r.adaptive.correct,
             r.adaptive.reversal, r.adaptive.estimate) for r in rows]


def test_every_step_of_each_staircase_is_recomputed_from_its_rows_by_the_documented_rule(tmp_path):
    session, _ = open_session(tmp_path, STAIRCASES)
    answer_all(session, subject_for(STAIRCASES, threshold=120))
    assert session.phase is Phase.DONE
    rows = read_trials(session.writer.paths.beh_tsv)
    design = load_protocol(STAIRCASES).design.adaptive
    values = [float(v) for v in design.values]
    for procedure in design.procedures:
        mine = [r for r in rows if r.counts and r.adaptive.procedure == procedure.name]
        assert mine, procedure.name
        # The rule as the module's docstring states it, written out plainly here.
        index, good, bad, last, reversals = values.index(float(procedure.start)), 0, 0, None, []
        for number, row in enumerate(mine, start=1):
            assert row.adaptive.intensity == values[index], (procedure.name, row.trial)
            correct = row.adaptive.correct
            good, bad = (good + 1, 0) if correct else (0, bad + 1)
            move = "down" if good >= procedure.down else "up" if bad >= procedure.up else None
            reversal = move is not None and last is not None and move != last
            assert row.adaptive.reversal == reversal, (procedure.name, row.trial)
            if reversal:
                reversals.append(values[index])
            if move is not None:
                good = bad = 0
                sizes = [s for s in procedure.steps if s.after_reversals <= len(reversals)][-1]
                index += -sizes.down if move == "down" else sizes.up
                index = min(max(index, 0), len(values) - 1)
                last = move
            kept = reversals[-procedure.estimate_reversals:]
            expected = sum(kept) / len(kept) if kept else None
            assert row.adaptive.estimate == pytest.approx(expected), (procedure.name, row.trial)
            stops = number >= procedure.stop_after_trials or len(reversals) >= \
                procedure.stop_after_reversals
        assert stops  # each staircase ran until its own rule stopped it


def test_a_run_killed_mid_staircase_resumes_to_the_identical_sequence(tmp_path):
    subject = subject_for(STAIRCASES, threshold=120)
    whole, _ = open_session(tmp_path / "whole", STAIRCASES)
    answer_all(whole, subject)
    expected = steps(read_trials(whole.writer.paths.beh_tsv))

    first, _ = open_session(tmp_path / "cut", STAIRCASES)
    answer_all(first, subject, stop_after=23)
    first.writer.close()  # killed: the manifest still says running, 23 rows on disk
    assert read_manifest(first.writer.paths.manifest).status is RunStatus.RUNNING
    second, _ = open_session(tmp_path / "cut", STAIRCASES, resume=True)
    answer_all(second, subject)
    assert second.phase is Phase.DONE
    assert steps(read_trials(second.writer.paths.beh_tsv)) == expected


def test_an_undelivered_trial_moves_no_staircase_and_is_presented_again_at_its_value(tmp_path):
    session, stimulator = open_session(tmp_path, STAIRCASES, fail={9, 10})
    answer_all(session, subject_for(STAIRCASES, threshold=120))
    rows = read_trials(session.writer.paths.beh_tsv)
    for trial in (9, 10):
        failed, retried = [r for r in rows if r.trial == trial]
        assert failed.status == "invalid" and retried.status == "ok"
        assert failed.adaptive.correct is None and failed.adaptive.estimate is None
        assert (failed.adaptive.procedure, failed.adaptive.intensity) == \
            (retried.adaptive.procedure, retried.adaptive.intensity)
    clean, _ = open_session(tmp_path / "clean", STAIRCASES)
    answer_all(clean, subject_for(STAIRCASES, threshold=120))
    ok = [r for r in rows if r.status == "ok"]
    assert steps(ok) == steps(read_trials(clean.writer.paths.beh_tsv))


def test_practice_and_catch_trials_move_no_procedure_and_are_judged_by_the_task(tmp_path):
    session, _ = open_session(tmp_path, STAIRCASES)
    answer_all(session, subject_for(STAIRCASES, threshold=120))
    rows = read_trials(session.writer.paths.beh_tsv)
    practice = [r for r in rows if r.practice]
    assert [r.adaptive.procedure for r in practice] == ["practice", "practice"]
    assert {r.adaptive.intensity for r in practice} == {300.0}  # the easiest value
    catches = [r for r in rows if r.adaptive.procedure == "catch"]
    assert len(catches) == 4 and {r.direction for r in catches} == {"none"}
    for row in catches:
        assert row.adaptive.intensity is None and row.adaptive.reversal is None
        assert row.adaptive.correct == (row.response == "none")


def test_procedures_that_have_all_stopped_end_the_run_and_the_trials_left_are_not_needed(tmp_path):
    session, _ = open_session(tmp_path, QUEST)
    answer_all(session, subject_for(QUEST, threshold=40))
    assert session.phase is Phase.DONE
    manifest = read_manifest(session.writer.paths.manifest)
    rows = read_trials(session.writer.paths.beh_tsv)
    assert manifest.status is RunStatus.COMPLETED
    assert 0 < manifest.needed_until == max(r.trial for r in rows) < len(manifest.plan)
    last = [r for r in rows if r.adaptive.procedure == "quest"][-1]
    assert last.adaptive.estimate_ci_high - last.adaptive.estimate_ci_low <= 12  # its stop
    assert load_run(session.writer.paths.beh_tsv).incomplete_reason is None


@pytest.mark.parametrize("path, parameter", [(QUEST, "threshold"), (STAIRCASES, "threshold")])
def test_a_subject_whose_threshold_is_doubled_gets_an_estimate_about_twice_as_large(
        tmp_path, path, parameter):
    protocol = load_protocol(path)
    values = protocol.design.adaptive.values
    low = float(values[len(values) // 4])
    estimates = []
    for truth in (low, 2 * low):
        # A steep subject (slope 4): the estimates' spread is then a few values' steps.
        session, _ = open_session(tmp_path / str(truth), path)
        answer_all(session, subject_for(path, threshold=truth, slope=4))
        rows = [r for r in read_trials(session.writer.paths.beh_tsv) if r.counts
                and r.adaptive.procedure not in ("catch", "practice")]
        finals = {r.adaptive.procedure: r.adaptive.estimate for r in rows}
        estimates.append(sum(finals.values()) / len(finals))
    # The staircases converge near 0.83 x threshold (70.7 % with guess 1/2, slope 4), QUEST+
    # on the threshold itself; either way the ratio is 2 within the grid's steps (here 20 ms
    # and 4 steps of values around thresholds of 80-160 ms and 32-64 steps).
    assert estimates[1] / estimates[0] == pytest.approx(2, rel=0.25)


def test_the_simulated_subject_answers_from_the_function_it_was_given():
    protocol = load_protocol(QUEST)
    assert parse_psychometric("threshold=30,slope=2,lapse=0", protocol.design.adaptive) == \
        Psychometric("weibull", 30.0, 2.0, 0.0, 0.0)
    with pytest.raises(PinArrayError, match="unknown parameter 'treshold'"):
        parse_psychometric("treshold=30", protocol.design.adaptive)
    subject = AdaptiveSubject(protocol, Psychometric("weibull", 30.0, 2.0, 0.0, 0.0), 1)
    condition = protocol.design.conditions[0]
    felt = [subject.respond(n, condition, False, Fraction(90)) != "none" for n in range(1, 401)]
    # p(90) = 1 - exp(-9): every answer felt; at 30, 1 - 1/e: about 63 %, within 5 sd of 400
    assert all(felt)
    at_threshold = sum(subject.respond(n, condition, False, Fraction(30)) != "none"
                       for n in range(1, 401)) / 400
    assert abs(at_threshold - (1 - 1 / 2.718281828)) < 5 * (0.632 * 0.368 / 400) ** 0.5


def test_a_localisation_row_names_the_frequency_an_adaptive_design_played(tmp_path):
    text = (PROTOCOLS / "quest_stroke.yaml").read_text()
    text = text.replace("  frequencies_hz: [5]\n", "").replace(
        "parameter: stroke_steps", "parameter: frequency_hz").replace(
        "values: {from: 4, to: 120, step: 4}", "values: [1, 2, 3, 4, 5]").replace(
        "    catch_trials: {count: 6}                # a stroke of 0: nothing lifts\n", "").replace(
        "threshold_prior: {mean: 40, sd: 30}", "threshold_prior: uniform")
    path = tmp_path / "quest_frequency.yaml"
    path.write_text(text)
    session, stimulator = open_session(tmp_path / "run", path)
    answer_all(session, subject_for(path, threshold=3), stop_after=8)
    rows = [r for r in read_trials(session.writer.paths.beh_tsv) if not r.practice]
    assert rows and all(r.frequency_hz == r.adaptive.intensity for r in rows)


def edited_run(root, trial_index=2):
    """A staircase run of 8 answers, killed, whose ``trial_index``-th counted row had its
    ``correct`` cell flipped by hand; returns (beh.tsv, that row's line, its trial)."""
    first, _ = open_session(root, STAIRCASES)
    answer_all(first, subject_for(STAIRCASES, threshold=120), stop_after=8)
    first.writer.close()  # killed
    beh = first.writer.paths.beh_tsv
    lines = beh.read_text().splitlines(keepends=True)
    header = lines[0].rstrip("\n").split("\t")
    column = header.index("correct")
    counted = [n for n, row in enumerate(read_trials(beh), start=1)
               if row.counts and row.adaptive.procedure not in ("catch", "practice")]
    line = counted[trial_index] + 1  # the header is line 1
    cells = lines[line - 1].rstrip("\n").split("\t")
    cells[column] = {"true": "false", "false": "true"}[cells[column]]
    lines[line - 1] = "\t".join(cells) + "\n"
    beh.write_text("".join(lines))
    return beh, line, read_trials(beh)[line - 2].trial


def test_a_correct_cell_edited_by_hand_is_named_on_its_own_line_with_the_files_path(tmp_path):
    beh, line, trial = edited_run(tmp_path)
    with pytest.raises(PinArrayError) as refused:
        open_session(tmp_path, STAIRCASES, resume=True)
    message = str(refused.value)
    assert message.startswith(f"{beh}:{line}: trial {trial}: correct is ")
    assert "(edited by hand?); put the row back as it was, then resume" in message
