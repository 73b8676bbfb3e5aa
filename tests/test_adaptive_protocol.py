"""An adaptive design as a lab writes it: what is accepted, and every mistake located in the file."""

from pathlib import Path

import pytest

from pinarray.errors import ProtocolErrors
from pinarray.protocol.load import load_protocol
from pinarray.protocol.procedures import Parameter, QuestPlus, Staircase
from tests.commands import pinarray_here

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
STAIRCASES = (PROTOCOLS / "staircase_motion.yaml").read_text()
QUEST = (PROTOCOLS / "quest_stroke.yaml").read_text()


def test_the_shipped_staircase_protocol_reads_as_its_comments_say():
    design = load_protocol(PROTOCOLS / "staircase_motion.yaml").design
    adaptive = design.adaptive
    assert adaptive.parameter is Parameter.SOA_MS and adaptive.task == "direction"
    assert [float(v) for v in adaptive.values] == list(range(20, 301, 20))
    assert adaptive.guess_rate == 0.5  # two directions
    assert [type(p) for p in adaptive.procedures] == [Staircase, Staircase]
    assert design.trial_count == 40 + 40 + 4 + 2


def test_the_shipped_quest_protocol_reads_as_its_comments_say():
    adaptive = load_protocol(PROTOCOLS / "quest_stroke.yaml").design.adaptive
    (quest,) = adaptive.procedures
    assert isinstance(quest, QuestPlus) and quest.stop_after_trials == 60
    assert adaptive.parameter is Parameter.STROKE_STEPS and adaptive.catch.count == 6
    assert adaptive.catch.stimulus == ""  # a stroke of 0


def line_of(text, fragment):
    return next(n for n, line in enumerate(text.splitlines(), start=1) if fragment in line)


MISTAKES = [
    (STAIRCASES, "        stop_after_trials: 40               # every procedure needs a trial limit\n",
     "", "method: staircase", "expected a 'stop_after_trials' key in procedure 'from_above', found none"),
    (STAIRCASES, "start: 300", "start: 310", "start: 310",
     "expected the start to be one of the values (20, 40, 60, ..., 280, 300), found 310"),
    (STAIRCASES, "{from: 20, to: 300, step: 20}", "[20, 60, 40]", "values:",
     "expected the values in ascending order"),
    (STAIRCASES, "{from: 20, to: 300, step: 20}", "{from: 20, to: 310, step: 20}", "values:",
     "a whole number of 20 ms steps"),
    (STAIRCASES, "  adaptive:\n", "  blocks: 2\n  adaptive:\n", "blocks: 2",
     "expected no 'blocks' in an adaptive design"),
    (STAIRCASES, "task: direction ", "task: localisation ", "task: localisation",
     "expected the task of a apparent_motion design to be one of direction, detection"),
    (STAIRCASES, "      from_below:", "      catch:", "      catch:",
     "expected a procedure name"),
    (STAIRCASES, "{count: 4, stimulus: no_wave}", "{count: 4}", "catch_trials:",
     "only a stroke can be presented at 0"),
    (QUEST, "{from: 4, to: 120, step: 4}", "{from: 4, to: 160, step: 4}", "values:",
     "at stroke_steps 156: pin 6: expected a stroke within its calibrated limits 2000..2200, "
     "found 156 steps, which lifts it to 2204"),
    (QUEST, "parameter: stroke_steps", "parameter: stroke_us", "parameter:",
     "expected stroke_steps (this device's positions are in steps)"),
    (QUEST, "lapse_rates: [0, 0.02, 0.05]", "lapse_rates: [0, 0.6]", "lapse_rates:",
     "expected each of the lapse rates of at most 0.5"),
    # How long the train plays: at 220 ms its second cycle is cut to a 20 ms lift, which a
    # 114-step stroke cannot make (it needs 38 ms): refused before a run fails on it.
    (QUEST.replace("parameter: stroke_steps", "parameter: duration_ms").replace(
        "threshold_prior: {mean: 40, sd: 30}", "threshold_prior: {mean: 500, sd: 300}").replace(
        "stop_below_width: 12", "stop_below_width: 100").replace(
        "    catch_trials: {count: 6}                # a stroke of 0: nothing lifts\n", ""),
     "values: {from: 4, to: 120, step: 4}", "values: {from: 200, to: 1000, step: 20}", "values:",
     "at duration_ms 220: pin 6 cannot follow its train at 5 Hz (datasheet figures): the "
     "signal's length (or its phase) cuts a cycle, leaving a lift of 20.0 ms"),
    # A catch trial's right answer is "no motion": a wave that moves cannot be its stimulus.
    (STAIRCASES, "{count: 4, stimulus: no_wave}", "{count: 4, stimulus: rightwards}",
     "catch_trials:", "expected a no-wave control (wave: none) for catch trials, whose right "
     "answer is no motion; found 'rightwards', a wave going right"),
    # A prior no run can use: it weighs one threshold, 1e90, where no value is ever felt.
    (QUEST, "threshold_prior: {mean: 40, sd: 30}",
     "thresholds: [1e90, 2e90]\n        threshold_prior: {mean: 1, sd: 1e-90}",
     "threshold_prior:", "procedure 'quest': at every value (4 to 120) a correct answer has "
     "less than a 1e-12 chance under every threshold its prior weighs (1e+90 to 1e+90, 1 of 2)"),
    (QUEST, "threshold_prior: {mean: 40, sd: 30}", "thresholds: [1e90, 2e90]", "thresholds:",
     "under every threshold of its grid (1e+90 to 2e+90)"),
    # Far below every value, with no lapse: nothing but a correct answer can come.
    (QUEST.replace("lapse_rates: [0, 0.02, 0.05]", "lapse_rates: [0]"),
     "threshold_prior: {mean: 40, sd: 30}", "thresholds: [1e-90, 2e-90]", "thresholds:",
     "a wrong answer has less than a 1e-12 chance under every threshold of its grid (1e-90 to "
     "2e-90): no answer can move it, and a run would stop at the first such answer; bring the "
     "thresholds and the prior near the values, or state a lapse rate above 0"),
]


@pytest.mark.parametrize("text, old, new, where, message", MISTAKES,
                         ids=[m[-1][:40] for m in MISTAKES])
def test_a_mistake_in_an_adaptive_design_is_one_located_line(tmp_path, text, old, new, where,
                                                             message):
    assert old in text
    bad = text.replace(old, new, 1)
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    with pytest.raises(ProtocolErrors) as caught:
        load_protocol(path)
    (error,) = caught.value.errors
    assert message in error.message
    assert error.line == line_of(bad, where)


def test_a_soa_that_drives_a_pin_twice_at_once_is_refused_at_that_value(tmp_path):
    # The no-wave control taps the centre pin at 0 and 2 x SOA: below 200 ms, its two 400 ms
    # taps overlap.
    bad = STAIRCASES.replace("configurations: [rightwards, leftwards]",
                             "configurations: [rightwards, leftwards, no_wave]")
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    with pytest.raises(ProtocolErrors, match="at soa_ms 20: expected one train at a time on each "
                                               "pin, found pin 6 driven twice at once"):
        load_protocol(path)


def test_validate_says_an_adaptive_design_runs_up_to_its_procedures_limits():
    done = pinarray_here("validate", PROTOCOLS / "staircase_motion.yaml")
    assert done.returncode == 0, done.stderr
    assert "adaptive: soa_ms over 15 values (20..300 ms), 2 procedures" in done.stdout
    assert "at most 86 trials with 4 catch and 2 practice" in done.stdout


@pytest.mark.parametrize("command", [["compile", "--out", "{out}"], ["preview", "--trial", "3"]])
def test_compile_and_preview_refuse_an_adaptive_design_in_one_line_and_write_nothing(
        tmp_path, command):
    out = tmp_path / "schedules.json"
    args = [part.format(out=out) for part in command]
    done = pinarray_here(args[0], PROTOCOLS / "quest_stroke.yaml", *args[1:])
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "adapts stroke_steps as the run goes" in done.stderr
    assert not out.exists()
