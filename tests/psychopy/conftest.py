"""The PsychoPy plugin's tests: PsychoPy imported first, as in a lab's script (importing it sets
a default timeout on every new socket: the condition under which the player's channel once
failed every stimulus); one window for the session (a display is needed: xvfb.py); and both
ways to the pins: the in-process simulator and a serial port served by ``pinarray sim-serve``
in a process of its own, the independent emulator whose log tells what reached the servos."""

from psychopy import plugins, visual  # noqa: I001  # first, before pinarray

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from builder import set_up_device_manager

from pinarray.psychopy.components.pinArrayTouch import PinArrayDeviceBackend

REPO = Path(__file__).resolve().parents[2]
APPARENT_MOTION = REPO / "protocols" / "apparent_motion.yaml"
LOCALISATION = REPO / "protocols" / "localisation.yaml"
TORQUE_ENABLE, GOAL_POSITION = 40, 42

plugins.activatePlugins()  # as a Builder script begins


def pytest_configure(config):
    # In the process that hands the tests to the test processes (-n) and runs none of them:
    # pytest-rerunfailures' status server there (127.0.0.1, one connection per test process)
    # takes PsychoPy's default timeout too, and dropped a test process that asked nothing for
    # 10 s (a run of `make psychopy` ended in an internal error). The tests keep the timeout.
    if not hasattr(config, "workerinput") and config.getoption("numprocesses", None):
        socket.setdefaulttimeout(None)


@pytest.fixture(scope="session")
def win() -> Iterator[visual.Window]:
    window = visual.Window(size=(400, 300), units="height", color="grey")
    yield window
    window.close()


@dataclass
class Served:
    """``pinarray sim-serve`` in a process of its own, logging every packet's arrival."""

    process: subprocess.Popen[str]
    path: str
    log: Path

    def stop(self) -> list[list[str]]:
        """Stop serving; the arrivals, one row each (arrival_ns, servo_id, instruction,
        address, data_hex, delivered)."""
        if self.process.poll() is None:
            self.process.terminate()
            self.process.communicate(timeout=30)
        lines = self.log.read_text().splitlines()[1:] if self.log.exists() else []
        return [line.split("\t") for line in lines]

    def torque_off_at_ns(self) -> dict[int, int | None]:
        """Stops serving; per servo, when its torque last went off for good, as the servo saw
        it (monotonic ns; None: still on, or never off after its last goal)."""
        last: dict[int, int | None] = {}
        for arrival_ns, servo, instruction, address, data, delivered in self.stop():
            if delivered != "1" or not address:
                continue
            if instruction == "WRITE" and int(address) == TORQUE_ENABLE:
                last[int(servo)] = int(arrival_ns) if data == "00" else None
            elif int(address) == GOAL_POSITION:  # a goal turns an STS servo's torque on
                step = 2 * (int(data[:2], 16) + 1)  # a sync write: length, then id + data each
                servos = ([int(servo)] if instruction == "WRITE"
                          else [int(data[k:k + 2], 16) for k in range(2, len(data), step)])
                for servo_id in servos:
                    last[servo_id] = None
        return last


@pytest.fixture(params=["sim", "pty"])
def way(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[dict[str, Any],
                                                                          Served | None]]:
    """Each way to the pins: the device's keyword arguments, and the served bus (pty only)."""
    if request.param == "sim":
        yield {"sim": "sim://"}, None
        return
    log = tmp_path / "arrivals.tsv"
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", "--ids", "1-16", "--arrivals", str(log)],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    served = Served(process, process.stdout.readline().split(" on ")[1].split()[0], log)
    try:
        yield {"port": served.path}, served
    finally:
        served.stop()


@pytest.fixture
def device_manager(tmp_path, monkeypatch):
    """The Device Manager holding the simulated array as it lists it, named 'touch'."""
    profile = next(p for p in PinArrayDeviceBackend.getAvailableDevices() if "sim" in p)
    return set_up_device_manager(tmp_path, monkeypatch, profile)
