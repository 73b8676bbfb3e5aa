"""Builder's "Pin array touch", as a lab uses it: found by PsychoPy's plugin manager, offered
by Builder's Device Manager, imported without PsychoPy's app or hardware, passing PsychoPy's
own component tests, and the example experiment (examples/psychopy_congruency.psyexp)
compiled as Builder compiles it and its script run on the simulated array under the virtual
display, its data file holding the tactile columns. Patterns built in the dialog:
test_builder_patterns.py."""

import importlib.metadata
import json
import re
import shutil
import subprocess
import sys

import pytest
from builder import (
    assert_every_servo_released,
    compile_and_run,
    headless_experiment,
    minimal,
    rows_of,
    set_up_device_manager,
)
from conftest import APPARENT_MOTION, REPO
from dialog_picture import PICTURES, example_component, picture
from psychopy import experiment
from psychopy.experiment.components import getAllComponents
from psychopy.experiment.devices import DeviceBackend
from psychopy.experiment.utils import CodeGenerationException
from psychopy.tests.test_experiment.test_components.test_base_components import (
    BaseComponentTests,
)

import pinarray
from pinarray.psychopy import PinArrayDevice, PinArrayTouch
from pinarray.psychopy.components.pinArrayTouch import (
    PinArrayDeviceBackend,
    PinArrayTouchComponent,
)

TACTILE_COLUMNS = ["tactile.stimulus", "tactile.flip_t", "tactile.onset_t",
                   "tactile.onset_from_flip_ms", "tactile.onset_write_late_ms",
                   "tactile.delivered", "tactile.problem", "tactile.ending",
                   "tactile.goal_changes", "tactile.confirmed", "tactile.healed",
                   "tactile.missing", "tactile.latest_ms", "tactile.tolerance_ms"]
STROKE_COLUMNS = [f"tactile.pin{pin}.{what}" for pin in (5, 6, 7)
                  for what in ("commanded_steps", "achieved_steps", "lag_ms")]


class TestPsychoPysOwnComponentTests(BaseComponentTests):
    """PsychoPy's tests every Builder component passes: default parameters compile, with
    blank start and stop too, the indentation is kept, the icons exist for every theme, a
    disabled component writes nothing."""

    comp = PinArrayTouchComponent


def test_the_entry_point_gives_builder_the_component_and_the_device_managers_backend():
    entry_points = {ep.name: ep for ep in importlib.metadata.distribution("pinarray").entry_points
                    if ep.group == "psychopy.experiment.components"}
    assert list(entry_points) == ["PinArrayTouchComponent"]
    assert entry_points["PinArrayTouchComponent"].load() is PinArrayTouchComponent
    assert getAllComponents()["PinArrayTouchComponent"] is PinArrayTouchComponent
    assert PinArrayDeviceBackend in PinArrayTouchComponent.backends
    assert PinArrayDeviceBackend in DeviceBackend.getAllBackends()
    # Builder's Device Manager lists what the backend's device class finds: the simulated
    # array here (no servos on this machine's serial ports).
    profiles = PinArrayDeviceBackend.getAvailableDevices()
    assert {"deviceName": "pin array@sim://", "sim": "sim://",
            "deviceClass": "pinarray.psychopy.device.PinArrayDevice"} in profiles
    template = PinArrayDeviceBackend.getTemplateJSON()
    assert template["device"] == "pinarray.psychopy.device.PinArrayDevice"
    assert list(template["params"]) == ["name"]


def test_the_component_imports_without_psychopys_app_or_hardware_or_pinarrays_array():
    # What Builder pays to show the component: beyond PsychoPy's own experiment classes,
    # which every component imports, only the component; no app (wx), no hardware, nothing
    # of pinarray's array (cedrus tests its components so: psychopy.tests.utils
    # .profiledImport, which psychopy-lib does not ship).
    code = """if True:
        import sys
        import psychopy.experiment.components, psychopy.experiment.devices
        before = set(sys.modules)
        import pinarray.psychopy.components.pinArrayTouch
        print("added", *sorted(set(sys.modules) - before))
        print("all", *sorted(sys.modules))
        """
    lines = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    added, loaded = (line.split()[1:] for line in lines[-2:])
    assert added == ["pinarray", "pinarray.psychopy", "pinarray.psychopy.components",
                     "pinarray.psychopy.components.pinArrayTouch", "pinarray.version"]
    assert not [name for name in loaded if name.split(".")[0] in ("wx", "psychopy_app")
                or name.startswith(("psychopy.app", "psychopy.hardware"))]


def dialog(component):
    """The component's dialog as Builder lays it out: {tab: [label, ...]}, those its order
    names first, in that order, then the others."""
    names = [name for name in component.order if name in component.params]
    names += [name for name in component.params if name not in names]
    tabs: dict[str, list[str]] = {}
    for name in names:
        param = component.params[name]
        if param.categ is not None:
            tabs.setdefault(param.categ, []).append(param.label)
    return tabs


def test_the_dialog_offers_what_a_lab_expects():
    exp = experiment.Experiment()
    component = PinArrayTouchComponent(exp, "trial")
    tabs = dialog(component)
    assert tabs["Stimulus"] == ["Protocol", "Stimulus", "Pin", "Pins", "Frequency (Hz)",
                                "Duration (s)", "Duty cycle", "Pulses per cycle"]
    assert tabs["Device"] == ["Device"]
    assert {"Start", "Stop", "Start on the flip", "Wait for the end"} <= set(tabs["Basic"])
    assert tabs["Data"] == ["Save delivered", "Save onset from flip", "Save strokes",
                            "Save onset/offset times"]
    assert component.params["syncScreenRefresh"].val is True  # flip-locked unless unchecked
    assert component.params["waitForEnd"].val is True


def test_the_compiled_frame_arms_the_touch_on_the_flip_that_shows_its_start():
    script = minimal(deviceLabel="touch", protocol="apparent_motion.yaml",
                     stimulus="$wave").writeScript(target="PsychoPy")
    start = script.index("if tactile.status == NOT_STARTED and tThisFlip >= 0.5") \
        if "tThisFlip >= 0.5" in script else script.index("if tactile.status == NOT_STARTED")
    armed = script.index("tactile.armOnFlip(win)")
    flipped = script.index("win.flip()", armed)
    assert start < armed < flipped  # armed in the start test, the frame's flip after it
    assert "with endOnProblem(thisExp, 'tactile'), tactile.repeat():\n" in script
    assert "tactile.stimulus = pinarray.find_condition(\n" in script
    assert "tactile.protocol, stimulus=wave, pin=None," in script
    assert "    tactile = PinArrayTouch(\n" in script and "device='touch'," in script
    assert "protocol='apparent_motion.yaml'," in script
    assert "tactile.addData(thisExp, columns=['delivered', 'onset', 'strokes'])" in script
    compile(script, "compiled", "exec")


def test_unchecked_start_on_the_flip_starts_at_once_and_columns_follow_the_data_tab():
    script = minimal(deviceLabel="touch", protocol="apparent_motion.yaml", stimulus="leftwards",
                     syncScreenRefresh=False, saveOnset=False, saveStrokes=False,
                     waitForEnd=False, stopVal="0.2").writeScript(target="PsychoPy")
    assert "tactile.present()" in script
    assert "armOnFlip" not in script
    assert "tactile.device.stop('its stop time')" in script
    assert "tactile.device.stop(\"the routine's end\")" in script
    assert "tactile.addData(thisExp, columns=['delivered'])" in script


def test_a_stimulus_the_protocol_does_not_hold_stops_the_compiling_in_the_protocols_words():
    exp = minimal(deviceLabel="touch", protocol=str(APPARENT_MOTION), stimulus="sideways")
    with pytest.raises(CodeGenerationException) as raised:
        exp.writeScript(target="PsychoPy")
    assert raised.value.source == "tactile"
    assert raised.value.message == (
        f"{APPARENT_MOTION}: no condition of the design has stimulus sideways (it holds: "
        "rightwards (right); leftwards (left); no_wave (none))")
    for known in ("rightwards", "$wave"):  # a name it holds; one the loop gives at run time
        script = minimal(deviceLabel="touch", protocol=str(APPARENT_MOTION),
                         stimulus=known).writeScript(target="PsychoPy")
        assert "tactile = PinArrayTouch(" in script


def test_the_example_psyexp_compiles_and_runs_on_the_simulated_array_writing_the_tactile_columns(
        tmp_path, monkeypatch, way):
    # The Device Manager's array: the simulated one as it lists it, or servos behind a serial
    # port (sim-serve's, in a process of its own), as it lists a port where servos answer.
    settings, served = way
    (where,) = settings.values()
    set_up_device_manager(tmp_path, monkeypatch, {
        "deviceName": f"pin array@{where}", **settings,
        "deviceClass": "pinarray.psychopy.device.PinArrayDevice"})
    # The example's folder as a lab has it: the experiment, its conditions, the protocol.
    (tmp_path / "examples").mkdir()
    for name in ("psychopy_congruency.psyexp", "psychopy_congruency.csv"):
        shutil.copy(REPO / "examples" / name, tmp_path / "examples" / name)
    (tmp_path / "protocols").mkdir()
    shutil.copy(APPARENT_MOTION, tmp_path / "protocols")
    data_file = compile_and_run(tmp_path / "examples" / "psychopy_congruency.psyexp", tmp_path)
    script = (tmp_path / "examples" / "psychopy_congruency.py").read_text()
    assert "deviceManager.addDevice(\n        deviceName='touch',\n" in script
    # the Device Manager's array, set up by the script
    assert f"{next(iter(settings))}={where!r}," in script

    header, rows = rows_of(data_file)
    assert set(TACTILE_COLUMNS + STROKE_COLUMNS) <= set(header), header
    trials = [row for row in rows if row["wave"]]
    assert len(trials) == 8  # 4 pairings, twice
    for row in trials:
        assert row["tactile.stimulus"] == row["wave"]
        assert row["tactile.ending"] == "played"
        from_flip_ms = float(row["tactile.onset_from_flip_ms"])
        assert from_flip_ms >= 0  # started by the flip, never before it
        # Delivered as scheduled only with its onset within the tolerance of its flip and
        # every goal change confirmed (how far the onset lay, and whether a simulator starved
        # of the processor by other work kept up, are the benchmark's and the machine's).
        within = from_flip_ms <= float(row["tactile.tolerance_ms"])
        if row["tactile.delivered"] == "True":
            assert within and row["tactile.missing"] == "0" and not row["tactile.problem"]
        else:
            assert row["tactile.problem"], row
            assert within or row["tactile.problem"].startswith("missed its flip: the pins "
                                                               "started")
        # The flash and the touch on one flip: PsychoPy's stamp of the flash's start is the
        # touch's flip.
        assert float(row["tactile.flip_t"]) == pytest.approx(float(row["flash.started"]),
                                                             abs=1e-6)
        for pin in (5, 6, 7):
            assert int(row[f"tactile.pin{pin}.commanded_steps"]) > 0
            assert row[f"tactile.pin{pin}.achieved_steps"]
    log = data_file.with_suffix(".log").read_text(encoding="utf-8")
    assert log.count("DATA \ttactile: ") == 8
    if served is not None:
        assert_every_servo_released(served)


def test_a_routine_ended_early_waits_for_the_touch_or_cuts_it_and_a_stop_time_cuts_it(
        tmp_path, device_manager):
    # Three routines, each ended by a Code component 0.2 s in, while an 0.8 s wave plays.
    exp = headless_experiment()
    code = getAllComponents()["CodeComponent"]
    cases = {"waits": {"waitForEnd": True}, "cuts": {"waitForEnd": False},
             "stops": {"waitForEnd": True, "stopVal": "0.1"}}
    for position, (routine_name, params) in enumerate(cases.items()):
        routine = exp.addRoutine(routineName=routine_name)
        exp.flow.addRoutine(routine, position)
        routine.append(PinArrayTouchComponent(
            exp, routine_name, name=f"tactile_{routine_name}", deviceLabel="touch",
            protocol="apparent_motion.yaml", stimulus="rightwards", startVal="0", **params))
        if routine_name != "stops":
            routine.append(code(exp, routine_name, name=f"end_{routine_name}",
                                eachFrame="if t > 0.2:\n    continueRoutine = False"))
    exp_file = tmp_path / "routines.psyexp"
    exp.saveToXML(str(exp_file))
    shutil.copy(APPARENT_MOTION, tmp_path)
    _, rows = rows_of(compile_and_run(exp_file, tmp_path))
    value = {key: value for row in rows for key, value in row.items() if value}
    assert value["tactile_waits.ending"] == "played" and value["tactile_waits.delivered"] in (
        "True", "False")  # played whole: whether within its flip's tolerance is timing's
    assert value["tactile_cuts.ending"] == "cut by the routine's end"
    assert value["tactile_cuts.delivered"] == "False"
    assert value["tactile_cuts.problem"] == "cut short by the routine's end"
    assert value["tactile_stops.ending"] == "cut by its stop time"
    assert value["tactile_stops.problem"] == "cut short by its stop time"


def test_a_touch_needs_a_pin_array_in_the_device_manager_and_real_servos_their_protocol():
    with pytest.raises(pinarray.PinArrayError, match="tactile: expected a pin array named "
                                                     "'nowhere' in PsychoPy's Device Manager, "
                                                     "found none: add it in Builder's Device "
                                                     "Manager"):
        PinArrayTouch("nowhere", protocol=APPARENT_MOTION, name="tactile")
    rig = PinArrayDevice(port="/dev/pinarray-rig")  # set up only: nothing opened yet
    try:
        with pytest.raises(pinarray.PinArrayError) as raised:
            PinArrayTouch(rig, name="tactile")
        assert str(raised.value) == (
            "tactile: the pin array /dev/pinarray-rig has real servos, which need the protocol "
            "that calibrates them (servo ids, rest, limits): give tactile one (its Protocol "
            "field)")
        assert not rig.is_open
    finally:
        rig.close()


def test_with_no_protocol_the_simulated_array_opens_with_the_default_device_until_one_gives_one():
    device = PinArrayDevice(sim="sim://?seed=7")  # set up, as the Device Manager's script does
    try:
        assert not device.is_open
        plain = PinArrayTouch(device, name="plain")  # no protocol: pinarray's default device
        assert device.is_open and device.protocol.name == "defaults"
        with pytest.raises(pinarray.PinArrayError) as raised, plain.repeat():
            plain.stimulus = pinarray.find_condition(plain.protocol, stimulus="rightwards")
        assert str(raised.value) == (
            f"plain: a stimulus of a protocol needs a protocol, and the pin array {device.url} "
            "is open with none: give plain one (its Protocol field), or Pins to build a "
            "pattern")
        # A component that gives a protocol, later in the script, opens the array for it:
        # the one without then finds its stimuli there too.
        touch = PinArrayTouch(device, protocol=APPARENT_MOTION, name="tactile")
        assert touch.device is plain.device is device and device.is_open
        assert plain.protocol.name == "apparent_motion"
        assert PinArrayTouch(device, name="again").device.protocol.name == "apparent_motion"
    finally:
        device.close()
    assert not device.is_open


def test_a_routine_that_ends_before_the_touch_starts_writes_it_as_not_delivered():
    class Row(dict):
        def addData(self, name, value):
            self[name] = value

    with PinArrayDevice(APPARENT_MOTION, sim="sim://?seed=8") as device:
        touch = PinArrayTouch(device, name="tactile")
        touch.stimulus = pinarray.find_condition(device.protocol, stimulus="leftwards")
        row = Row()
        assert touch.addData(row) is None
    assert row == {"tactile.stimulus": "leftwards", "tactile.delivered": False,
                   "tactile.problem": "never started: the routine ended before its start",
                   "tactile.ending": "not started"}


def test_the_device_managers_file_names_pinarrays_backend(device_manager, tmp_path):
    stored = json.loads((tmp_path / "devices.json").read_text())
    assert stored["touch"]["__class__"].endswith("pinArrayTouch.PinArrayDeviceBackend")
    assert stored["touch"]["profile"]["sim"] == "sim://"


@pytest.mark.parametrize("example", PICTURES, ids=lambda example: example.stem)
def test_the_docs_pictures_of_the_dialog_are_what_the_components_parameters_draw(example):
    assert PICTURES[example].read_text(encoding="utf-8") == picture(example_component(example)), (
        "run .venv-psychopy/bin/python tests/psychopy/dialog_picture.py")


@pytest.mark.parametrize("example, least", [("psychopy_congruency", 20),
                                            ("psychopy_patterns", 8)])
def test_the_docs_excerpts_of_the_compiled_scripts_are_in_the_examples_compiled(
        example, least, device_manager):
    exp = experiment.Experiment()
    exp.loadFromXML(str(REPO / "examples" / f"{example}.psyexp"))
    compiled = {line.strip() for line in exp.writeScript(target="PsychoPy").splitlines()}
    page = (REPO / "docs" / "programmers" / "psychopy.md").read_text(encoding="utf-8")
    excerpt = re.search(rf"<!-- compiled: examples/{example}.psyexp -->\n```python\n"
                        r"(.*?)```", page, re.S)
    assert excerpt is not None
    lines = [line.strip() for line in excerpt.group(1).splitlines()]
    code = [line for line in lines if line and not line.startswith("#")]
    assert len(code) > least and [line for line in code if line not in compiled] == []
