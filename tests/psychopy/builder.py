"""What the Builder tests share: experiments made as Builder makes them, Builder's Device Manager
on this machine, and an experiment compiled as Builder compiles it and run as its Runner runs
it, its data file read back."""

import csv
import subprocess
import sys
from pathlib import Path

from psychopy import experiment, prefs
from psychopy.experiment.loops import TrialHandler
from psychopy.preferences.devices import DeviceConfig

from pinarray.psychopy.components.pinArrayTouch import (
    PinArrayDeviceBackend,
    PinArrayTouchComponent,
)


def headless_experiment():
    """An experiment with no routine yet, set up to run unattended: no info dialog, a small
    window, the keyboard through pyglet, no psydat file."""
    exp = experiment.Experiment()
    exp.settings.params["Show info dlg"].val = False
    exp.settings.params["Full-screen window"].val = False
    exp.settings.params["Window size (pixels)"].val = [200, 150]
    exp.settings.params["keyboardBackend"].val = "Pyglet"
    exp.settings.params["Save psydat file"].val = False
    return exp


def assert_every_servo_released(served) -> None:
    """As the servos of ``served`` (sim-serve's) saw it: every one released once the script
    ended."""
    released = served.torque_off_at_ns()
    assert sorted(released) == list(range(1, 17)) and all(released.values()), released


def minimal(**params):
    """An experiment of one routine in a loop, holding one Pin array touch."""
    exp = experiment.Experiment()
    routine = exp.addRoutine(routineName="trial")
    exp.flow.addRoutine(routine, 0)
    exp.flow.addLoop(TrialHandler(exp=exp, name="trials"), 0, -1)
    routine.append(PinArrayTouchComponent(exp, "trial", name="tactile", **params))
    return exp


def set_up_device_manager(folder: Path, monkeypatch, profile: dict) -> DeviceConfig:
    """Builder's Device Manager on this machine, as a lab sets it up: the array of
    ``profile`` (one `getAvailableDevices` lists) named 'touch' (the Device Manager's file
    kept in ``folder``, not the user's)."""
    devices = DeviceConfig(folder / "devices.json")
    backend = PinArrayDeviceBackend(profile)
    backend.name = "touch"
    devices["touch"] = backend
    devices.save()
    monkeypatch.setattr(prefs, "_devices", DeviceConfig(folder / "devices.json"), raising=False)
    return devices


def run_compiled(exp_file: Path, edit=lambda script: script) -> subprocess.CompletedProcess:
    """Compile ``exp_file`` as Builder does (`Experiment.loadFromXML`, `writeScript`; the
    script passed through ``edit``), and run it in a process of its own (as Builder's Runner
    does)."""
    exp = experiment.Experiment()
    exp.loadFromXML(str(exp_file))
    script = exp_file.with_suffix(".py")
    script.write_text(edit(exp.writeScript(target="PsychoPy")), encoding="utf-8")
    return subprocess.run([sys.executable, str(script)], cwd=script.parent, capture_output=True,
                          text=True, timeout=300)


def data_file_of(exp_file: Path) -> Path:
    data_files = sorted((exp_file.parent / "data").glob("*.csv"))
    assert len(data_files) == 1, data_files
    return data_files[0]


def compile_and_run(exp_file: Path, folder: Path) -> Path:
    """Compile and run ``exp_file`` (`run_compiled`), which must end well, and return its data
    file."""
    run = run_compiled(exp_file)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return data_file_of(exp_file)


def rows_of(data_file: Path) -> tuple[list[str], list[dict[str, str]]]:
    with data_file.open(newline="", encoding="utf-8-sig") as opened:
        reader = csv.DictReader(opened)
        rows = list(reader)
    return list(reader.fieldnames or []), rows
