"""pinarray inside PsychoPy, for real: the plugin PsychoPy's plugin manager loads by entry
point, the device its DeviceManager finds and opens, a wave armed on a window's flip, and the
example experiment writing PsychoPy's data. Run by `make psychopy` (its own environment, a
virtual display); the onset-to-flip bound asserted below is the protocol's delivery tolerance,
a correctness bound, not a benchmark (that is `make bench`: bench_psychopy); how late each
later goal change arrived is not asserted: the simulated servos play in real time here."""

import csv
import importlib
import importlib.metadata
import subprocess
import sys

import pytest
from conftest import APPARENT_MOTION, REPO
from psychopy import plugins, visual
from psychopy.hardware.manager import DeviceManager
from psychopy.plugins import PluginStub

import pinarray
from pinarray.psychopy import PinArrayDevice

sys.path.insert(0, str(REPO / "examples"))
import psychopy_congruency  # noqa: E402

TRIALS = 6


def test_every_entry_point_psychopy_loads_resolves_to_pinarrays_own_class_not_a_stub():
    entry_points = [ep for ep in importlib.metadata.distribution("pinarray").entry_points
                    if ep.group.startswith("psychopy")]
    assert [(ep.group, ep.name) for ep in entry_points] == [("psychopy.hardware", "PinArrayDevice")]
    assert "pinarray" in plugins.listPlugins("loaded")
    assert "pinarray" not in plugins.listPlugins("failed")
    for ep in entry_points:
        target = getattr(importlib.import_module(ep.group), ep.name)
        assert target is ep.load() is PinArrayDevice
        assert not issubclass(target, PluginStub)


def test_the_device_manager_lists_the_simulated_array_and_opens_it_by_alias():
    profiles = DeviceManager.getAvailableDevices("pinarray")
    simulated = [p for p in profiles if p.get("sim") == "sim://"]
    assert simulated == [{"deviceName": "pin array@sim://", "sim": "sim://",
                          "deviceClass": "pinarray.psychopy.device.PinArrayDevice"}]
    device = DeviceManager.addDevice("pinarray", "touch", protocol=str(APPARENT_MOTION),
                                     sim="sim://")
    try:
        assert isinstance(device, PinArrayDevice)
        assert DeviceManager.getDevice("touch") is device
        assert device.isSameDevice(simulated[0])
        assert device.getDeviceProfile()["sim"] == "sim://"
        touch = device.present(pinarray.find_condition(device.protocol, stimulus="leftwards"))
        assert touch.wait().record.missing == 0 and touch.onsetFromFlip is None
    finally:
        assert DeviceManager.removeDevice("touch")
    assert device.array.close().complete  # removing it rested the pins: the report it kept


def test_a_wave_armed_on_a_flip_starts_within_the_protocols_tolerance_of_that_flip(win):
    flash = visual.Rect(win, size=0.1, fillColor="white")
    flash.draw()
    win.flip()  # drawn once before timing counts
    with PinArrayDevice(APPARENT_MOTION) as device:
        wave = pinarray.find_condition(device.protocol, stimulus="rightwards")
        tolerance_s = device.protocol.device.delivery_tolerance_ns / 1e9
        for _ in range(TRIALS):
            win.flip()
            touch = device.armOnFlip(wave, win)
            assert touch.onsetFromFlip is None  # not flipped yet
            flash.draw()
            flip_s = win.flip()
            delivery = touch.wait()
            assert touch.flipTime == pytest.approx(flip_s, abs=1e-6)  # PsychoPy's own stamp
            assert abs(touch.onsetFromFlip) <= tolerance_s, touch.describe()
            # Every goal change reached its servo (how late each did is the simulated
            # servos' real time on a shared machine: the benchmark's, not asserted here).
            assert delivery.record.missing == 0, delivery.problem


def test_an_error_in_the_trial_cuts_the_wave_short_and_rests_the_pins(win):
    device = PinArrayDevice(APPARENT_MOTION)
    with pytest.raises(KeyboardInterrupt), device:
        device.armOnFlip(pinarray.find_condition(device.protocol, stimulus="leftwards"), win)
        win.flip()
        raise KeyboardInterrupt
    report = device.close()
    assert report.complete and len(report.released_ids) == 16


def test_the_example_writes_psychopy_data_with_the_tactile_columns(tmp_path, capsys):
    assert psychopy_congruency.main(["--subject", "ci", "--observer", "--repetitions", "2",
                                     "--seed", "3", "--results", str(tmp_path)]) == 0
    with (tmp_path / "sub-ci_congruency.csv").open(newline="", encoding="utf-8-sig") as rows:
        trials = [row for row in csv.DictReader(rows) if row["flash"]]
    assert len(trials) == 8
    for row in trials:
        assert row["touch.stimulus"] == {"left": "leftwards", "right": "rightwards"}[row["wave"]]
        assert abs(float(row["touch.onset_from_flip_ms"])) <= float(row["touch.tolerance_ms"])
        assert row["touch.delivered"] in ("True", "False") and row["touch.missing"] == "0"
        assert int(row["touch.pin6.commanded_steps"]) > 0 and row["touch.pin6.achieved_steps"]
    log = (tmp_path / "sub-ci_congruency.log").read_text(encoding="utf-8")
    assert log.count("DATA \ttouch: ") == 8
    assert "8 trials" in capsys.readouterr().out


def test_pinarray_without_its_plugin_never_imports_psychopy():
    # Every module of the package but the plugin, imported where PsychoPy is installed.
    # (pkgutil.walk_packages would import the plugin's package itself to look inside it.)
    code = """if True:
        import importlib, pkgutil, sys
        import pinarray

        def walk(package):
            for module in pkgutil.iter_modules(package.__path__, package.__name__ + "."):
                if module.name in ("pinarray.psychopy", "pinarray.__main__"):
                    continue
                imported = importlib.import_module(module.name)
                if module.ispkg:
                    walk(imported)

        walk(pinarray)
        print(sorted(name for name in sys.modules if name.split(".")[0] == "psychopy"))
        """
    imported = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True).stdout
    assert imported.strip() == "[]"
