"""Sampling the pins' motion costs no verified goal: lateness and delivery with and without it.

The seed's localisation train at 10 Hz on one pin, and a wave over three pins, played on the
in-process simulator in real time (the host's own write times: what sampling could delay),
alternately with and without sampling, in one run, ``ROUNDS`` times each. Per setting: the
frames' write lateness (p99 of each trial; min, median, max over the rounds, in ms), the goal
changes confirmed of those scheduled, the samples taken per moving pin per second, and the
ratio of each round's lateness with sampling to the one without (the reference, same run).
``PINARRAY_BENCH_SECONDS`` (default 20) sets the seconds of stimulus per setting.
"""

from __future__ import annotations

import os
import statistics

from pinarray.clock import MonotonicClock
from pinarray.hardware.feetech.transport import open_bus
from pinarray.player.playback import play_prepared, prepare_trial
from tests.hardware.lab import device_setup, pulse_train

SECONDS = float(os.environ.get("PINARRAY_BENCH_SECONDS", "20"))
TRIAL_S = 2
ROUNDS = max(1, int(SECONDS // TRIAL_S))


def _row(name: str, values: list[float]) -> str:
    return f"{name:<34} {min(values):>8.3f} {statistics.median(values):>8.3f} {max(values):>8.3f}"


def run() -> None:
    bus = open_bus("sim://?ids=1-16", device_setup(), MonotonicClock())
    for pins in ([6], [2, 7, 12]):
        trial = prepare_trial(bus, pulse_train(pins, 10, 10 * TRIAL_S, up_steps=2162))
        lateness: dict[bool, list[float]] = {False: [], True: []}
        delivered: dict[bool, list[float]] = {False: [], True: []}
        rates: list[float] = []
        for _ in range(ROUNDS):
            for sampling in (False, True):
                report = play_prepared(bus, trial, bus.clock, sample_motion=sampling,
                                       release_at_end=False)
                lateness[sampling].append(report.deadline_error_ns(99) / 1e6)
                d = report.delivery
                delivered[sampling].append((d.confirmed + d.healed) / d.scheduled)
                if sampling:
                    rates.extend(len(t.time_ns) / (trial.end_ns / 1e9) for t in report.trace)
        print(f"\n{len(pins)} moving pin(s), 10 Hz, {ROUNDS} x {TRIAL_S} s per setting"
              f"{'':>4}min   median      max")
        for sampling in (False, True):
            what = "with sampling" if sampling else "without sampling"
            print(_row(f"p99 write lateness, ms, {what}", lateness[sampling]))
            print(_row(f"goals confirmed (share), {what}", delivered[sampling]))
        print(_row("samples per moving pin per s", rates))
        ratios = [w / max(wo, 1e-3) for w, wo in zip(lateness[True], lateness[False], strict=True)]
        print(_row("ratio: p99 lateness with / without", ratios))
    bus.rest_and_release()
    bus.close()


if __name__ == "__main__":
    run()
