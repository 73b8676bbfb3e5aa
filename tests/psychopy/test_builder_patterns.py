"""Builder's "Pin array touch" building its stimulus in the dialog: Pins and a train instead of
a protocol's stimulus, with no protocol on the simulated array. Pins decides which kind a
dialog makes; a dialog that mixes the two stops the compiling in one line; the pattern is built
at every repeat (so the loop's variables reach it), checked against the array's device before
it is armed (one it refuses is written as not delivered, and the experiment goes on), and armed
on the flip as a protocol's stimulus is. The example (examples/psychopy_patterns.psyexp) runs
on both ways to the pins."""

import ast
import shutil

import pytest
from builder import (
    assert_every_servo_released,
    compile_and_run,
    data_file_of,
    headless_experiment,
    minimal,
    rows_of,
    run_compiled,
    set_up_device_manager,
)
from conftest import APPARENT_MOTION, REPO
from psychopy import experiment
from psychopy.experiment.utils import CodeGenerationException

import pinarray
from pinarray.psychopy import PinArrayDevice, PinArrayTouch
from pinarray.psychopy.components.pinArrayTouch import PinArrayTouchComponent

PATTERNS = REPO / "examples" / "psychopy_patterns.psyexp"


class Row(dict):
    """A row of PsychoPy's data, as `ExperimentHandler.addData` fills it."""

    def addData(self, name, value):
        self[name] = value


def test_pins_given_build_a_pattern_on_the_dialogs_train_at_every_repeat():
    script = minimal(deviceLabel="touch", pins="6, 7, 10, 11", frequency="5",
                     trainDuration="1").writeScript(target="PsychoPy")
    assert "protocol=''," in script  # none: the simulated array's default device
    assert ("    with endOnProblem(thisExp, 'tactile'), tactile.repeat():\n"
            "        tactile.stimulus = pinarray.Pattern(\n"
            "            pins=[6, 7, 10, 11],\n"
            "            train=pinarray.Train(frequency_hz=5, duration_s=1))\n") in script
    assert "find_condition" not in script
    assert script.index("tactile.stimulus = pinarray.Pattern(") < script.index(
        "tactile.armOnFlip(win)")  # built as the routine starts, armed on its frame
    # The loop's variables, and every field of the train.
    script = minimal(deviceLabel="touch", pins="$pins", frequency="$frequency_hz",
                     trainDuration="0.4", dutyCycle="$duty", pulsesPerCycle="20",
                     ).writeScript(target="PsychoPy")
    assert ("            pins=pins,\n"
            "            train=pinarray.Train(frequency_hz=frequency_hz, duration_s=0.4, "
            "duty_cycle=duty, pulses_per_cycle=20))\n") in script
    compile(script, "compiled", "exec")


@pytest.mark.parametrize("params, message", [
    ({"stimulus": "rightwards", "pins": "6, 7", "frequency": "5", "trainDuration": "1"},
     "expected a stimulus of the protocol (Stimulus, Pin) or a pattern built here (Pins and "
     "its train), found both: Stimulus, Pins, Duration (s) given"),
    ({"pin": "6", "pins": "6, 7", "frequency": "5", "trainDuration": "1"},
     "expected a stimulus of the protocol (Stimulus, Pin) or a pattern built here (Pins and "
     "its train), found both: Pin, Pins, Duration (s) given"),
    ({"stimulus": "rightwards", "trainDuration": "1", "dutyCycle": "0.5"},
     "expected a stimulus of the protocol (Stimulus, Pin) or a pattern built here (Pins and "
     "its train), found both: Stimulus, Duration (s), Duty cycle given"),
    ({"trainDuration": "1"},
     "expected Pins beside Duration (s) (a pattern's train), found Pins blank: give Pins, or "
     "leave Duration (s) blank"),
    ({"pins": "6, 7", "trainDuration": "1"},
     "expected Frequency (Hz) and Duration (s) for a pattern built from Pins, found "
     "Frequency (Hz) blank"),
    ({"pins": "$pins"},
     "expected Frequency (Hz) and Duration (s) for a pattern built from Pins, found "
     "Frequency (Hz) and Duration (s) blank"),
    ({"pins": "6, 7", "frequency": "5", "trainDuration": "1", "dutyCycle": "0.33"},
     "pinarray.Train: duty_cycle: expected a duty cycle that is a whole number of the 10 "
     "pulses per cycle, found 0.33 (3.3 pulses)"),
    ({"pins": "6, 7.5", "frequency": "5", "trainDuration": "1"},
     "pinarray.Pattern: pins[1]: expected a whole number (int), found 7.5 (float)"),
    ({"pins": "6 7", "frequency": "5", "trainDuration": "1"},
     "Pins: expected pin numbers such as 6, 7, 10, 11, or a $variable, found '6 7'"),
    ({"pins": "\uff16, \uff17", "frequency": "5", "trainDuration": "1"},
     "Pins: expected pin numbers such as 6, 7, 10, 11, or a $variable, found "
     "'\uff16, \uff17'"),
    ({"pins": "6, 7", "frequency": "5 Hz", "trainDuration": "1"},
     "Frequency (Hz): expected a number such as 5, or a $variable, found '5 Hz'"),
    ({"pins": "$pins", "frequency": "1e9", "trainDuration": "1"},
     "pinarray.Train: frequency_hz: expected the frequency of at most 1000 Hz, found 1e+09"),
    ({"pins": "$pins", "frequency": "$f", "trainDuration": "1", "dutyCycle": "1.5"},
     "pinarray.Train: duty_cycle: expected the duty cycle of at most 1 (fraction), found 1.5"),
    ({"pins": "6, 7.5", "frequency": "$f", "trainDuration": "$d"},
     "pinarray.Pattern: pins[1]: expected a whole number (int), found 7.5 (float)"),
], ids=["stimulus and pins", "pin and pins", "stimulus and a train", "a train without pins",
        "no frequency", "no train", "a train refused", "a pattern refused", "pins not a list",
        "full-width digits", "a frequency in words", "a fixed frequency beside $pins",
        "a fixed duty cycle beside $variables", "fixed pins beside a $train"])
def test_a_dialog_that_contradicts_itself_stops_the_compiling_in_one_line(params, message):
    with pytest.raises(CodeGenerationException) as raised:
        minimal(deviceLabel="touch", **params).writeScript(target="PsychoPy")
    assert (raised.value.source, raised.value.message) == ("tactile", message)


@pytest.mark.parametrize("params", [
    {"pins": "$pins", "frequency": "5", "trainDuration": "1", "dutyCycle": "0.25",
     "pulsesPerCycle": "$pulses"},  # 20 pulses make 0.25 whole
    {"pins": "$pins", "frequency": "$f", "trainDuration": "0.01", "pulsesPerCycle": "3",
     "dutyCycle": "$duty"},  # 1 of 3 pulses, at 166.7 Hz a 10 ms train holds one cycle
    {"pins": "6, 7", "frequency": "$f", "trainDuration": "$d"},
], ids=["a duty cycle that some pulses make whole", "three pulses and a short train",
        "pins alone"])
def test_fixed_values_that_some_value_of_the_variables_makes_whole_compile(params):
    script = minimal(deviceLabel="touch", **params).writeScript(target="PsychoPy")
    compile(script, "compiled", "exec")


def test_a_problem_found_at_its_repeat_names_the_component_and_a_refused_one_is_not_armed(win):
    with PinArrayDevice(sim="sim://?seed=11") as device:
        touch = PinArrayTouch(device, name="tactile")  # no protocol: the default device
        with pytest.raises(pinarray.PinArrayError) as raised, touch.repeat():
            touch.stimulus = pinarray.Pattern(pins=[6, 7], train=pinarray.Train(
                frequency_hz=5, duration_s=1, duty_cycle=0.33))  # a $variable's value
        assert str(raised.value).startswith("tactile: pinarray.Train: duty_cycle: expected a "
                                            "duty cycle that is a whole number")
        # One the array cannot play as specified: refused as the routine starts, never armed.
        with touch.repeat():
            touch.stimulus = pinarray.Pattern(pins=[6, 17], train=pinarray.Train(
                frequency_hz=5, duration_s=1))
        assert touch.refused == ("prepare: Pattern: pins[1]: expected a pin from 1 to 16 on "
                                 "the 4x4 grid, found 17")
        assert touch.armOnFlip(win) is None and touch.touch is None and touch.done
        row = Row()
        assert touch.addData(row) is None
        assert row == {
            "tactile.stimulus": repr(touch.stimulus), "tactile.delivered": False,
            "tactile.problem": "refused before it played: prepare: Pattern: pins[1]: expected "
                               "a pin from 1 to 16 on the 4x4 grid, found 17",
            "tactile.ending": "not started"}
        # The next repeat starts afresh.
        with touch.repeat():
            touch.stimulus = pinarray.Pattern(pins=[6, 7], train=pinarray.Train(
                frequency_hz=5, duration_s=0.2))
        assert touch.refused is None and not touch.done
        played = touch.present()
        assert played is touch.touch and played.wait().delivered in (True, False)
        assert [stroke.pin for stroke in played.wait().strokes] == [6, 7]


def test_the_patterns_example_compiles_and_runs_writing_every_pins_stroke(tmp_path, monkeypatch,
                                                                          way):
    # As shipped, no protocol: the simulated array with pinarray's default device. Real
    # servos need the rig's protocol: given in the dialog, as a lab does on its rig.
    settings, served = way
    (where,) = settings.values()
    set_up_device_manager(tmp_path, monkeypatch, {
        "deviceName": f"pin array@{where}", **settings,
        "deviceClass": "pinarray.psychopy.device.PinArrayDevice"})
    (tmp_path / "examples").mkdir()
    shutil.copy(PATTERNS.with_suffix(".csv"), tmp_path / "examples")
    exp = experiment.Experiment()
    exp.loadFromXML(str(PATTERNS))
    (component,) = [c for c in exp.routines["trial"] if isinstance(c, PinArrayTouchComponent)]
    assert component.params["protocol"].val == ""
    if served is not None:
        (tmp_path / "protocols").mkdir()
        shutil.copy(APPARENT_MOTION, tmp_path / "protocols")
        component.params["protocol"].val = "../protocols/apparent_motion.yaml"
    exp_file = tmp_path / "examples" / PATTERNS.name
    exp.saveToXML(str(exp_file))
    data_file = compile_and_run(exp_file, tmp_path)
    script = exp_file.with_suffix(".py").read_text()
    assert "tactile.stimulus = pinarray.Pattern(\n" in script

    header, rows = rows_of(data_file)
    trials = [row for row in rows if row["pins"]]
    assert len(trials) == 6  # 3 shapes at 2 frequencies
    for row in trials:
        pins = ast.literal_eval(row["pins"])
        built = pinarray.Pattern(pins=pins, train=pinarray.Train(
            frequency_hz=float(row["frequency_hz"]), duration_s=0.4, duty_cycle=0.5))
        assert row["tactile.stimulus"] == repr(built)  # this repeat's, in full
        assert row["tactile.ending"] == "played"  # none refused: the device delivers them all
        from_flip_ms = float(row["tactile.onset_from_flip_ms"])
        assert from_flip_ms >= 0  # started by the flip, never before it
        within = from_flip_ms <= float(row["tactile.tolerance_ms"])
        if row["tactile.delivered"] == "True":
            assert within and row["tactile.missing"] == "0" and not row["tactile.problem"]
        else:
            # PsychoPy's flips are on the wall clock, so the simulated servos play in real
            # time on either way (not virtual time): a host too busy to keep the frames or
            # sample a stroke is the benchmark's. A stroke the servos fall short of is not:
            # tests/test_stimuli_in_code_example.py delivers these very patterns in full in
            # virtual time, and the array refuses before it plays what they cannot.
            assert row["tactile.problem"], row
            assert "commanded steps" not in row["tactile.problem"], row
        for pin in range(1, 17):  # every pin of its pattern measured, and only those
            commanded = row.get(f"tactile.pin{pin}.commanded_steps", "")
            achieved = row.get(f"tactile.pin{pin}.achieved_steps", "")
            if pin in pins:
                assert int(commanded) > 0 and achieved and row[f"tactile.pin{pin}.lag_ms"], pin
            else:
                assert commanded == achieved == "", pin
    assert {ast.literal_eval(row["pins"])[0] for row in trials} == {6, 5, 2}
    log = data_file.with_suffix(".log").read_text(encoding="utf-8")
    assert log.count("DATA \ttactile: Pattern(pins=") == 6
    if served is not None:
        assert_every_servo_released(served)


def test_a_pattern_the_servos_cannot_follow_is_written_as_refused_and_the_experiment_goes_on(
        tmp_path, device_manager):
    exp = headless_experiment()
    for position, (routine_name, frequency) in enumerate({"fast": "40", "slow": "5"}.items()):
        routine = exp.addRoutine(routineName=routine_name)
        exp.flow.addRoutine(routine, position)
        routine.append(PinArrayTouchComponent(
            exp, routine_name, name=f"{routine_name}_touch", deviceLabel="touch", startVal="0",
            pins="6, 7, 10, 11", frequency=frequency, trainDuration="0.2"))
    exp_file = tmp_path / "refused.psyexp"
    exp.saveToXML(str(exp_file))
    data_file = compile_and_run(exp_file, tmp_path)
    _, rows = rows_of(data_file)
    value = {key: value for row in rows for key, value in row.items() if value}
    assert value["fast_touch.delivered"] == "False"
    assert value["fast_touch.ending"] == "not started"
    assert value["fast_touch.problem"].startswith(
        "refused before it played: prepare: Pattern: pins: pin 6 cannot follow 40 Hz")
    assert "fast_touch.onset_from_flip_ms" not in value  # never armed
    assert value["slow_touch.ending"] == "played"  # the experiment went on
    assert all(int(value[f"slow_touch.pin{pin}.commanded_steps"]) > 0 for pin in (6, 7, 10, 11))
    log = data_file.with_suffix(".log").read_text(encoding="utf-8")
    assert "fast_touch: Pattern(pins=[6, 7, 10, 11]" in log and "refused by the array" in log


def one_touch(**params):
    """An unattended experiment of one routine holding one Pin array touch, named tactile."""
    exp = headless_experiment()
    routine = exp.addRoutine(routineName="trial")
    exp.flow.addRoutine(routine, 0)
    routine.append(PinArrayTouchComponent(exp, "trial", name="tactile", deviceLabel="touch",
                                          startVal="0", **params))
    return exp


@pytest.mark.parametrize("params, says", [
    ({"pins": "6, 7", "frequency": "$1e9", "trainDuration": "1"},
     "tactile: pinarray.Train: frequency_hz: expected the frequency of at most 1000 Hz, found "
     "1e+09"),
    # A blank dialog compiles (PsychoPy's own tests ask that of a component's defaults); with
    # no protocol anywhere it has no stimulus to choose from.
    ({}, "tactile: a stimulus of a protocol needs a protocol, and the pin array sim://"),
], ids=["a $value refused", "a blank dialog and no protocol"])
def test_a_problem_at_its_repeat_ends_the_experiment_in_one_line_with_its_data_saved(
        tmp_path, device_manager, params, says):
    exp = one_touch(**params)
    exp_file = tmp_path / "refused_at_run.psyexp"
    exp.saveToXML(str(exp_file))
    run = run_compiled(exp_file)
    problems = [line for line in run.stderr.splitlines() if "tactile" in line]
    assert run.returncode == 2, run.stderr[-3000:]
    assert "Traceback" not in run.stderr
    assert len(problems) == 1 and problems[0].startswith(says), problems
    data_file = data_file_of(exp_file)
    assert problems[0].endswith(f"(the data so far are saved as {data_file})")
    assert data_file.stat().st_size > 0


def test_escape_mid_touch_cuts_it_and_its_row_says_so(tmp_path, device_manager):
    exp = one_touch(pins="6, 7, 10, 11", frequency="5", trainDuration="6")
    exp_file = tmp_path / "escape.psyexp"
    exp.saveToXML(str(exp_file))
    hook = 'if defaultKeyboard.getKeys(keyList=["escape"]):'

    def escape_once_it_plays(script: str) -> str:  # Escape, pressed 1 s into the touch
        assert hook in script
        return script.replace(hook, hook[:-1] + " or (tactile.touch is not None and "
                              "tThisFlip > 1.0):")

    run = run_compiled(exp_file, escape_once_it_plays)
    assert run.returncode == 0, run.stderr[-3000:]
    _, rows = rows_of(data_file_of(exp_file))
    (row,) = [row for row in rows if row.get("tactile.stimulus")]
    assert row["tactile.delivered"] == "False"
    assert row["tactile.ending"].startswith("cut"), row
    assert "the experiment ending (Escape)" in row["tactile.problem"], row
