"""Adaptive runs written as a session writes them: simulated subjects (a known psychometric
function) answer interleaved staircases and QUEST+, and every row's adaptive cells come from
the procedures' own rule (`pinarray.adaptive`), the way the session fills them."""

from dataclasses import dataclass, field
from pathlib import Path

from pinarray.adaptive import staircase
from pinarray.adaptive.interleave import pick_procedure
from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric
from pinarray.adaptive.questplus import QuestPlus, QuestPlusRule
from pinarray.journal.records import AdaptiveCells
from pinarray.paradigms.apparent_motion.rows import MotionRecord
from pinarray.paradigms.localisation.rows import LocalisationRecord
from pinarray.protocol.procedures import CATCH
from tests.runs import plan_of, start_run

S = 1_000_000_000  # ns per s
SOA_MS = tuple(float(x) for x in range(5, 305, 5))
STAIRCASE = staircase.StaircaseRule(
    domain=SOA_MS, down=2, up=1, stop_after_trials=100, estimate_reversals=8,
    steps=(staircase.StepSizes(0, 4, 4), staircase.StepSizes(3, 2, 2),
           staircase.StepSizes(5, 1, 1)))
STARTS = {"ascending": 0, "descending": SOA_MS.index(250.0)}
CATCH_EVERY = 25  # every 25th main trial of the motion run is a no-wave catch trial
STROKE_STEPS = tuple(float(x) for x in range(1, 31))
QUEST = QuestPlusRule(kind="weibull", intensities=STROKE_STEPS,
                      thresholds=tuple(float(x) for x in range(2, 31)), slopes=(2.0, 3.0, 4.0, 5.0),
                      lapses=(0.0, 0.02, 0.04), guess=0.0, stop_after_trials=60)


@dataclass
class Written:
    """What a simulated run wrote, kept to check the analysis against."""

    rows: list = field(default_factory=list)
    estimates: dict = field(default_factory=dict)  # procedure -> its final estimate


def motion_row(trial, cells, correct, direction="left", **fields):
    response = direction if correct else ("right" if direction == "left" else "left")
    if direction == "none":
        response = "none" if correct else "left"
    return MotionRecord(trial=trial, block=fields.pop("block", 1), task="motion",
                        onset_ns=4 * S * trial, duration_ns=S, response=response, row=2,
                        direction=direction, adaptive=cells, **fields)


def motion_run(root: Path, subject: str, threshold_ms: float, seed: int) -> Written:
    """Apparent-motion direction (2AFC, guess 1/2), SOA adapted by two interleaved 1-up/2-down
    staircases; two practice rows first, a catch trial every `CATCH_EVERY` trials, and one
    invalid row presented again: none of them moves a staircase."""
    observer = PsychometricObserver(Psychometric("weibull", threshold_ms, 4.0, 0.5, 0.01), seed)
    written = Written()
    rows = written.rows
    for trial in (1, 2):  # practice: answered, but moving nothing
        rows.append(motion_row(trial, AdaptiveCells("ascending", "soa_ms", 100.0, 0.5, True),
                                True, practice=True, block=0))
    states = {name: staircase.start(STAIRCASE, index) for name, index in STARTS.items()}
    trial = adaptive_trials = 0
    while any(not s.finished for s in states.values()):
        trial += 1
        if trial % CATCH_EVERY == 0:
            rows.append(motion_row(trial, AdaptiveCells(CATCH, "soa_ms", None, 0.5, True), True,
                                    direction="none"))
            continue
        adaptive_trials += 1
        name = pick_procedure(seed, adaptive_trials,
                              [n for n, s in states.items() if not s.finished])
        intensity = STAIRCASE.domain[states[name].index]
        if trial == 7:  # a bus fault: the row is invalid and the trial is presented again
            rows.append(motion_row(trial, AdaptiveCells(name, "soa_ms", intensity, 0.5), False,
                                    status="invalid", status_reason="bus fault"))
        step = staircase.advance(STAIRCASE, states[name], observer.answer(trial, intensity))
        states[name] = step.state
        cells = AdaptiveCells(name, "soa_ms", intensity, 0.5, step.correct, step.reversal,
                              staircase.reversal_mean(STAIRCASE, step.state))
        rows.append(motion_row(trial, cells, step.correct))
    written.estimates = {n: staircase.reversal_mean(STAIRCASE, s) for n, s in states.items()}
    _write(root, subject, "motion", rows)
    return written


def detection_run(root: Path, subject: str, threshold_steps: float, seed: int) -> Written:
    """Detection of a stroke (guess 0), stroke adapted by QUEST+."""
    observer = PsychometricObserver(Psychometric("weibull", threshold_steps, 3.0, 0.0, 0.02),
                                    seed)
    quest = QuestPlus.prepare(QUEST)
    state = quest.start()
    written = Written()
    trial = 0
    while not quest.finished(state):
        trial += 1
        intensity = quest.next_intensity(state)
        correct = observer.answer(trial, intensity)
        state = quest.update(state, intensity, correct)
        posterior = quest.summary(state)
        cells = AdaptiveCells("quest", "stroke_steps", intensity, 0.0, correct, None,
                              posterior.threshold_mean, posterior.threshold_ci_low,
                              posterior.threshold_ci_high)
        written.rows.append(LocalisationRecord(
            trial=trial, block=1, task="detection", onset_ns=4 * S * trial, duration_ns=S,
            response="6" if correct else "none", pin=6, frequency_hz=10.0, adaptive=cells))
    summary = quest.summary(state)
    written.estimates = {"quest": (summary.threshold_mean, summary.threshold_ci_low,
                                   summary.threshold_ci_high)}
    _write(root, subject, "detection", written.rows)
    return written


def _write(root, subject, task, rows):
    writer = start_run(root, subject, task, plan_of([r for r in rows if r.status == "ok"]))
    for row in rows:
        writer.write_trial(row)
    writer.finish("completed")
