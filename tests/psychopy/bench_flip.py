"""The flip-to-onset figure, run by `make bench` (tests/benchmarks/bench_psychopy.py) in the
PsychoPy environment on a virtual display: a wave armed on a flip on the simulated array (in
real time), beside PsychoPy's own `win.callOnFlip` of a bare function, in the same rounds.

Printed, never asserted: min / median / max over the rounds, in ms from PsychoPy's stamp of
the flip, and each row's median over the reference's (absolute values: the onset may fall
before the stamp, which PsychoPy takes after the buffers are swapped).
"""

import statistics
from pathlib import Path

from psychopy import clock, logging, plugins, visual

import pinarray
from pinarray.psychopy import PinArrayDevice

APPARENT_MOTION = Path(__file__).resolve().parents[2] / "protocols" / "apparent_motion.yaml"
ROUNDS = 15


def stamp(into: list[float]) -> None:
    """The bare function: the time it runs, on PsychoPy's time base."""
    into.append(clock.getTime())


def main() -> None:
    plugins.activatePlugins()
    logging.console.setLevel(logging.ERROR)  # the figures only
    win = visual.Window(size=(400, 300), units="height", color="grey")
    flash = visual.Rect(win, size=0.1, fillColor="white")
    reference, time_zero, first_write = [], [], []
    with PinArrayDevice(APPARENT_MOTION) as device:
        wave = pinarray.find_condition(device.protocol, stimulus="rightwards")
        for round_ in range(ROUNDS + 1):  # the first is a warm-up
            called: list[float] = []
            flash.draw()
            win.callOnFlip(stamp, called)
            flip_s = win.flip() + logging.defaultClock.getLastResetTime()
            win.flip()
            touch = device.armOnFlip(wave, win)
            flash.draw()
            win.flip()
            delivery = touch.wait()
            if round_:
                reference.append((called[0] - flip_s) * 1e3)
                time_zero.append(touch.onsetFromFlip * 1e3)
                first_write.append(touch.onsetFromFlip * 1e3 + delivery.onset_write_late_ns / 1e6)
    win.close()
    base = abs(statistics.median(reference))
    print(f"from PsychoPy's stamp of the flip, ms; {ROUNDS} rounds on a virtual display (no "
          "vertical sync); the simulated array in real time; ratio: |median| / |median| of the "
          "reference")
    print(f"{'':<52} {'min':>8} {'median':>8} {'max':>8} {'ratio':>8}")
    for name, values in (("callOnFlip of a bare function (reference)", reference),
                         ("wave armed on the flip: its time zero", time_zero),
                         ("wave armed on the flip: first goal write returned", first_write)):
        print(f"{name:<52} {min(values):>8.3f} {statistics.median(values):>8.3f} "
              f"{max(values):>8.3f} {abs(statistics.median(values)) / base:>7.0f}x")


if __name__ == "__main__":
    main()
