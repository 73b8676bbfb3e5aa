"""The PsychoPy figures, run by `make bench` (tests/benchmarks/bench_psychopy.py) in the
PsychoPy environment on a virtual display, PsychoPy imported first, on both ways to the pins
(the in-process simulator in real time; a serial port served by `pinarray sim-serve` in a
process of its own, the player process playing):

- what arming a touch on a flip costs the frame loop (`armOnFlip`'s call), beside registering a
  bare function with PsychoPy's own `win.callOnFlip`, in the same rounds;
- the touch's onset from PsychoPy's stamp of its flip, beside `callOnFlip` of a bare function;
- `core.quit()` with a 10 s train playing: the last servo's torque-off as the served servos
  saw it, from the call (the pseudo-terminal only: there the servos are another process's).

Printed, never asserted: min / median / max over the rounds, and each row's median over its
reference's (absolute values: an onset may fall before a stamp).
"""

from psychopy import clock, core, logging, plugins, visual  # noqa: I001  # first, before pinarray

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pinarray
from pinarray.psychopy import PinArrayDevice

REPO = Path(__file__).resolve().parents[2]
APPARENT_MOTION = REPO / "protocols" / "apparent_motion.yaml"
LOCALISATION = REPO / "protocols" / "localisation.yaml"
ROUNDS = 15
QUITS = 3


def stamp(into: list[float]) -> None:
    """The bare function: the time it runs, on PsychoPy's time base."""
    into.append(clock.getTime())


def serve(log: Path) -> tuple[subprocess.Popen, str]:
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", "--ids", "1-16", "--arrivals", str(log)],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    return process, process.stdout.readline().split(" on ")[1].split()[0]


def torque_offs(process: subprocess.Popen, log: Path) -> dict[int, list[int]]:
    process.terminate()
    process.communicate(timeout=30)
    offs: dict[int, list[int]] = {}
    for line in log.read_text().splitlines()[1:]:
        arrival, servo, instruction, address, data, delivered = line.split("\t")
        if instruction == "WRITE" and address == "40" and data == "00" and delivered == "1":
            offs.setdefault(int(servo), []).append(int(arrival))
    return offs


def flips(win, flash, settings) -> dict[str, list[float]]:
    """Rounds of a wave armed on a flip, beside the bare function, in ms."""
    figures: dict[str, list[float]] = {"arm": [], "register": [], "reference": [], "onset": []}
    with PinArrayDevice(APPARENT_MOTION, **settings) as device:
        wave = pinarray.find_condition(device.protocol, stimulus="rightwards")
        for round_ in range(ROUNDS + 1):  # the first is a warm-up
            called: list[float] = []
            started = time.perf_counter()
            win.callOnFlip(stamp, called)
            registered = time.perf_counter() - started
            flash.draw()
            flip_s = win.flip() + logging.defaultClock.getLastResetTime()
            win.flip()
            started = time.perf_counter()
            touch = device.armOnFlip(wave, win)
            armed = time.perf_counter() - started
            flash.draw()
            win.flip()
            touch.wait()
            if round_:
                figures["register"].append(registered * 1e3)
                figures["arm"].append(armed * 1e3)
                figures["reference"].append((called[0] - flip_s) * 1e3)
                figures["onset"].append(touch.onsetFromFlip * 1e3)
    return figures


def last_off_ms(offs: dict[int, list[int]], asked_ns: int) -> float:
    """The last servo's first torque-off after ``asked_ns``, in ms from it."""
    return max(min(t for t in times if t >= asked_ns) - asked_ns for times in offs.values()) / 1e6


def quits(win, folder: Path) -> tuple[list[float], list[float]]:
    """Through sim-serve, ms to the last torque-off: the device's array stopped with its pins
    at rest (the reference), then core.quit() with a train playing."""
    reference, result = [], []
    for k in range(QUITS):
        log = folder / f"arrivals{k}.tsv"
        process, path = serve(log)
        device = PinArrayDevice(LOCALISATION, port=path)
        try:
            idle_ns = time.monotonic_ns()
            device.array.stop()
            device.armOnFlip(pinarray.find_condition(device.protocol, pin=6, frequency_hz=3), win)
            win.flip()
            core.wait(0.5, hogCPUperiod=0)
            asked_ns = time.monotonic_ns()
            try:
                core.quit()
            except SystemExit:
                pass
        finally:
            device.close()
        offs = torque_offs(process, log)
        reference.append(last_off_ms(offs, idle_ns))
        result.append(last_off_ms(offs, asked_ns))
    return reference, result


def row(name: str, values: list[float], base: float) -> None:
    print(f"{name:<60} {min(values):>8.3f} {statistics.median(values):>8.3f} "
          f"{max(values):>8.3f} {abs(statistics.median(values)) / base:>7.1f}x")


def main() -> None:
    import tempfile

    plugins.activatePlugins()
    logging.console.setLevel(logging.ERROR)  # the figures only
    win = visual.Window(size=(400, 300), units="height", color="grey")
    flash = visual.Rect(win, size=0.1, fillColor="white")
    with tempfile.TemporaryDirectory() as folder:
        process, path = serve(Path(folder) / "arrivals.tsv")
        try:
            ways = {"the simulator": flips(win, flash, {"sim": "sim://"}),
                    "a serial port": flips(win, flash, {"port": path})}
        finally:
            process.terminate()
            process.communicate(timeout=30)
        idle_ms, quit_ms = quits(win, Path(folder))
    win.close()
    print(f"ms; {ROUNDS} rounds a way on a virtual display (no vertical sync); ratio: |median| / "
          "|median| of the reference above it")
    print(f"{'':<60} {'min':>8} {'median':>8} {'max':>8} {'ratio':>8}")
    for way, figures in ways.items():
        register = statistics.median(figures["register"])
        row("callOnFlip(bare function): the call (reference)", figures["register"], register)
        row(f"armOnFlip on {way}: the call", figures["arm"], register)
        reference = abs(statistics.median(figures["reference"]))
        row("callOnFlip(bare function): runs after the stamp (reference)", figures["reference"],
            reference)
        row(f"armOnFlip on {way}: the touch's onset after the stamp", figures["onset"],
            reference)
    print(f"through a serial port, {QUITS} rounds: the last servo's torque-off as the served "
          "servos saw it, ms from the call")
    idle = statistics.median(idle_ms)
    row("stop() of the device's array, pins at rest (reference)", idle_ms, idle)
    row("core.quit() with a 10 s train playing", quit_ms, idle)


if __name__ == "__main__":
    main()
