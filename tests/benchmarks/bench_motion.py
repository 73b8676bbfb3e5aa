"""Sampling the pins' motion costs no verified goal, and measures every moving pin, up to 16.

The seed's localisation train at 10 Hz on one pin, a wave over three pins, the shapes
protocol's square (8 pins, the factory return delay of 500 us) and all 16 pins (after
`pinarray servos return-delay`: 100 us), played on the in-process simulator at 1 Mbit/s in
real time (the host's own write times: what sampling could delay), alternately with and
without sampling, in one run, ``ROUNDS`` times each. Per setting: the frames' write lateness
(p99 of each trial; min, median, max over the rounds, in ms), the goal changes confirmed of
those scheduled, the share of the moving pins' cycles measured (every one: 1.000; issue 46,
where 6 or more pins used to go unmeasured), the samples taken per moving pin per second
with, as the reference, the one pin's measured in the same run and the ratio, and the ratio
of each round's lateness with sampling to the one without (the reference, same run).
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
SQUARE = [5, 6, 7, 9, 11, 13, 14, 15]  # protocols/shapes.yaml's square
SETTINGS = [  # what moves, on which simulated bus
    ("1 moving pin", [6], "sim://?ids=1-16"),
    ("3 moving pins (a wave's)", [2, 7, 12], "sim://?ids=1-16"),
    ("8 moving pins (the square), 500 us", SQUARE, "sim://?ids=1-16"),
    ("16 moving pins, 100 us return delay", list(range(1, 17)),
     "sim://?ids=1-16&return_delay_us=100"),
]


def _row(name: str, values: list[float]) -> str:
    return f"{name:<40} {min(values):>8.3f} {statistics.median(values):>8.3f} {max(values):>8.3f}"


def run() -> None:
    reference_rates: list[float] = []
    for label, pins, url in SETTINGS:
        bus = open_bus(url, device_setup(), MonotonicClock())
        trial = prepare_trial(bus, pulse_train(pins, 10, 10 * TRIAL_S, up_steps=2162))
        lateness: dict[bool, list[float]] = {False: [], True: []}
        delivered: dict[bool, list[float]] = {False: [], True: []}
        measured: list[float] = []
        rates: list[float] = []
        for _ in range(ROUNDS):
            for sampling in (False, True):
                report = play_prepared(bus, trial, bus.clock, sample_motion=sampling,
                                       release_at_end=False)
                lateness[sampling].append(report.deadline_error_ns(99) / 1e6)
                d = report.delivery
                delivered[sampling].append((d.confirmed + d.healed) / d.scheduled)
                if sampling and d.strokes is not None:
                    judged = sum(p.cycles for p in d.strokes.pins)
                    measured.append(judged / sum(p.cycles + p.unmeasured_cycles
                                                 for p in d.strokes.pins))
                    rates.extend(len(t.time_ns) / (trial.end_ns / 1e9) for t in report.trace)
        if not reference_rates:
            reference_rates = rates
        print(f"\n{label}, 10 Hz, {ROUNDS} x {TRIAL_S} s per setting"
              f"{'':>4}min   median      max")
        for sampling in (False, True):
            what = "with sampling" if sampling else "without sampling"
            print(_row(f"p99 write lateness, ms, {what}", lateness[sampling]))
            print(_row(f"goals confirmed (share), {what}", delivered[sampling]))
        print(_row("cycles measured (share)", measured))
        print(_row("samples per moving pin per s", rates))
        print(_row("reference: 1 pin's samples per s", reference_rates))
        print(f"{'ratio: samples per pin / 1 pin (medians)':<40} "
              f"{statistics.median(rates) / statistics.median(reference_rates):>8.3f}")
        ratios = [w / max(wo, 1e-3) for w, wo in zip(lateness[True], lateness[False], strict=True)]
        print(_row("ratio: p99 lateness with / without", ratios))
        bus.rest_and_release()
        bus.close()


if __name__ == "__main__":
    run()
