"""The schedule compiler: time and memory against a naive integer-exact numpy train, throughput
on many pins and large arrays, where a float schedule drifts from the exact one, dense sampling,
how fast `pinarray validate` starts against a bare interpreter, and a 24 h train written to a
file by `pinarray compile --allow-long`.

Targets (issue 17): a 24 h, 10 Hz train within 1.5x the naive train's time and 40 B per pulse;
16 pins for 1 h at >= 10 M pulses/s; `validate` within 5x a bare interpreter's start.
Issue 22: `compile --allow-long --out FILE.npz` of the 24 h, 10 Hz seed train within 2x a naive
integer numpy train saved with `np.savez`, and the whole command under 600 MB peak RSS.
"""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys
import tempfile
from collections.abc import Callable
from fractions import Fraction
from math import lcm
from pathlib import Path

import numpy as np

from pinarray.cli import main
from pinarray.grid import Grid
from pinarray.protocol import NS_PER_S, Device, PinCalibration, PinDrive, ServoSettings, Train
from pinarray.schedule import compile_drives, pulse_indices, render_dense, train_pulses
from tests.benchmarks._timing import (
    SPREAD_HEADER,
    interleaved_seconds,
    median,
    peak_bytes,
    ratio,
    spread,
)

ROOT = Path(__file__).resolve().parents[2]
HOUR_S = 3600
DAY_S = 24 * HOUR_S


def _device(size: int = 4) -> Device:
    grid = Grid(size, size)
    pins = tuple(
        PinCalibration(p, p, 2048, 2000, 2200, ((1_500_000, 2048), (2_000_000, 2162)))
        for p in grid.pins
    )
    return Device(grid, ServoSettings(), pins)


def _seed_train(frequency_hz, seconds: int, phase=Fraction(0)) -> Train:
    return Train(Fraction(frequency_hz), seconds * NS_PER_S, phase=phase)


def naive_exact_train(train: Train) -> tuple[np.ndarray, np.ndarray]:
    """The reference: every index through the rational formula at once, then one mask.

    Integer-exact like the compiler (for slots whose products fit in int64, as all here do),
    written the obvious way: one schedule-length array per step.
    """
    offset_slots = train.phase * train.pulses_per_cycle
    k = np.arange(
        -int(offset_slots),
        int(train.duration_ns / train.slot_ns - offset_slots) + 1,
        dtype=np.int64,
    )
    slot, offset = train.slot_ns, offset_slots * train.slot_ns
    d = lcm(slot.denominator, offset.denominator)
    a, b = slot.numerator * (d // slot.denominator), offset.numerator * (d // offset.denominator)
    starts = (2 * (k * a + b) + d) // (2 * d)
    widths = np.where(
        k % train.pulses_per_cycle < train.up_pulses, train.up_width_ns, train.down_width_ns
    )
    keep = (starts >= 0) & (starts + widths <= train.duration_ns)
    return starts[keep], widths[keep]


def naive_many_pins(drives: list[PinDrive]) -> tuple[np.ndarray, ...]:
    """The reference for several pins: a naive train per pin, joined and sorted by time, pin."""
    parts = [(d.pin, *naive_exact_train(d.train)) for d in drives]
    pin = np.concatenate([np.full(len(s), p, np.int16) for p, s, _ in parts])
    start = np.concatenate([s + d.delay_ns for (_, s, _), d in zip(parts, drives, strict=True)])
    width = np.concatenate([w for _, _, w in parts])
    order = np.lexsort((pin, start))
    return pin[order], start[order], width[order]


def float_product_starts(train: Train) -> np.ndarray:
    """A plain float schedule: index times a float slot, plus a float offset, rounded halves up."""
    slot_ns = float(train.slot_ns)
    offset_ns = float(train.phase * train.pulses_per_cycle * train.slot_ns)
    return np.floor(pulse_indices(train) * slot_ns + offset_ns + 0.5).astype(np.int64)


def float_sum_starts(train: Train) -> np.ndarray:
    """A float schedule by accumulation: each start is the last one plus a float slot."""
    k = pulse_indices(train)
    slot_ns = float(train.slot_ns)
    first_ns = k[0] * slot_ns + float(train.phase * train.pulses_per_cycle * train.slot_ns)
    starts = np.full(len(k), slot_ns)
    starts[0] = first_ns
    return np.floor(np.cumsum(starts) + 0.5).astype(np.int64)


def _day_long_train() -> None:
    train = _seed_train(10, DAY_S)
    device = _device()
    drives = [PinDrive(1, train)]
    pulses = len(compile_drives(drives, device).pulses)
    times = interleaved_seconds(
        {
            "compile": lambda: compile_drives(drives, device),
            "naive": lambda: naive_exact_train(train),
            "float": lambda: float_product_starts(train),
        }
    )
    memory = {
        "compile": peak_bytes(lambda: compile_drives(drives, device)),
        "naive": peak_bytes(lambda: naive_exact_train(train)),
        "float": peak_bytes(lambda: float_product_starts(train)),
    }
    labels = {
        "compile": "compile_drives (pulses + targets)",
        "naive": "naive integer-exact train (reference)",
        "float": "plain float np.arange starts only",
    }
    print(f"24 h seed train at 10 Hz on 1 pin: {pulses:,} pulses; ms over 5 interleaved runs")
    print(f"{'what':<38} {SPREAD_HEADER} {'vs naive':>9} {'B/pulse':>8}   target")
    for key, label in labels.items():
        target = "<= 1.5x, <= 40 B" if key == "compile" else ""
        print(
            f"{label:<38} {spread(times[key])} {ratio(times[key], times['naive']):>9} "
            f"{memory[key] / pulses:>8.1f}   {target}"
        )


def _durations() -> None:
    device = _device()
    print("\ncompile time against duration (1 pin, 10 Hz seed train); naive = reference")
    print(
        f"{'duration':>9} {'pulses':>11} {'targets':>9} {SPREAD_HEADER} {'naive med':>9} "
        f"{'ratio':>6} {'Mpulses/s':>10}"
    )
    for seconds in (10, 60, 600, HOUR_S, DAY_S):
        train = _seed_train(10, seconds)
        drives = [PinDrive(1, train)]
        schedule = compile_drives(drives, device)
        times = interleaved_seconds(
            {
                "compile": lambda d=drives: compile_drives(d, device),
                "naive": lambda t=train: naive_exact_train(t),
            }
        )
        print(
            f"{seconds:>8}s {len(schedule.pulses):>11,} {len(schedule.targets):>9,} "
            f"{spread(times['compile'], digits=2)} {median(times['naive']) * 1e3:>9.2f} "
            f"{ratio(times['compile'], times['naive']):>6} "
            f"{len(schedule.pulses) / median(times['compile']) / 1e6:>10.1f}"
        )


def _many_pins() -> None:
    print("\nseveral pins for 1 h at 10 Hz; naive = a naive train per pin, joined, lexsorted")
    print(
        f"{'case':<34} {'pulses':>11} {SPREAD_HEADER} {'naive med':>9} {'ratio':>6} "
        f"{'Mpulses/s':>10} {'B/pulse':>8}"
    )
    device = _device()
    train = _seed_train(10, HOUR_S)
    cases = {
        "1 pin": [PinDrive(1, train)],
        "4 pins, one train": [PinDrive(p, train) for p in range(1, 5)],
        "16 pins, one train (target 10M/s)": [PinDrive(p, train) for p in range(1, 17)],
        "16 pins, 16 phases": [
            PinDrive(p, _seed_train(10, HOUR_S, Fraction(p, 16))) for p in range(1, 17)
        ],
        "16 pins, a wave 100 ms apart": [
            PinDrive(p, train, (p - 1) * 100_000_000) for p in range(1, 17)
        ],
    }
    for label, drives in cases.items():
        pulses = len(compile_drives(drives, device).pulses)
        times = interleaved_seconds(
            {
                "compile": lambda d=drives: compile_drives(d, device),
                "naive": lambda d=drives: naive_many_pins(d),
            }
        )
        memory = peak_bytes(lambda d=drives: compile_drives(d, device))
        print(
            f"{label:<34} {pulses:>11,} {spread(times['compile'])} "
            f"{median(times['naive']) * 1e3:>9.1f} {ratio(times['compile'], times['naive']):>6} "
            f"{pulses / median(times['compile']) / 1e6:>10.1f} {memory / pulses:>8.1f}"
        )


def _array_size() -> None:
    print("\nidle pins cost nothing: 1 active pin, 1 h at 10 Hz, on arrays of growing size")
    print(f"{'array':>7} {SPREAD_HEADER} {'vs 4x4':>7}")
    drives = [PinDrive(1, _seed_train(10, HOUR_S))]
    devices = {size: _device(size) for size in (4, 16, 64)}
    times = interleaved_seconds(
        {size: (lambda d=device: compile_drives(drives, d)) for size, device in devices.items()}
    )
    for size in devices:
        print(f"{size:>3}x{size:<3} {spread(times[size])} {ratio(times[size], times[4]):>7}")


def _exactness() -> None:
    print("\nwhere exact arithmetic matters: start errors of float schedules against the exact one")
    print("  product = float(k) * float(slot) + float(offset), rounded halves up")
    print("  sum     = previous start + float(slot), accumulated (a drifting clock)")
    print(
        f"{'frequency':>10} {'phase':>6} {'length':>7} {'pulses':>11} {'product wrong':>14} "
        f"{'max ns':>7} {'first wrong at':>15} {'sum max us':>11}"
    )
    rows = [
        ("10", 0),
        ("1/3", 0),
        ("0.1", 0),
        ("7", 0),
        ("20.48", 0),
        ("29.97", 0),
        ("29.97", Fraction(1, 3)),
        ("59.94", 0),
        ("17.3", Fraction(1, 3)),
        ("3.14159", 0),
        ("1.01", Fraction(1, 3)),
        ("333.3", Fraction(1, 3)),
    ]
    for frequency, phase in rows:
        # at most 10 M pulses a row, a day where that allows
        seconds = min(DAY_S, int(1e6 / float(Fraction(frequency))))
        train = Train(
            Fraction(frequency), seconds * NS_PER_S, 10, 5, 40_000, 30_000, Fraction(phase)
        )
        exact = train_pulses(train)[0]
        product = float_product_starts(train)[: len(exact)] - exact
        drift = float_sum_starts(train)[: len(exact)] - exact
        wrong = np.flatnonzero(product)
        first = f"{exact[wrong[0]] / 3.6e12:.2f} h" if len(wrong) else "never"
        print(
            f"{frequency:>10} {str(Fraction(phase)):>6} {seconds / 3600:>6.1f}h {len(exact):>11,} "
            f"{len(wrong):>14,} {int(np.abs(product).max()):>7} {first:>15} "
            f"{np.abs(drift).max() / 1e3:>11.3f}"
        )


def _edge_error_ns(schedule, pin: int, rate_hz: int) -> int:
    dense = render_dense(schedule.pulses, [pin], rate_hz, schedule.end_ns)[0]
    rising = np.flatnonzero(np.diff(dense.astype(np.int8)) == 1) + 1
    if dense[0]:
        rising = np.concatenate(([0], rising))
    starts = schedule.pulses.start_ns[schedule.pulses.pin == pin]
    return int(np.max(rising * (NS_PER_S // rate_hz) - starts))


def _dense() -> None:
    device = _device()
    # 70 pulses/s: a 14.285714... ms slot no sample grid hits
    train = Train(Fraction(7), 60 * NS_PER_S)
    for label, pins in (("1 pin", [1]), ("16 pins", list(range(1, 17)))):
        drives = [PinDrive(p, train) for p in pins]
        schedule = compile_drives(drives, device)
        calls = {"exact": lambda d=drives: compile_drives(d, device)}
        for rate_hz in (1_000, 10_000, 100_000):
            calls[rate_hz] = lambda r=rate_hz, s=schedule, p=pins: render_dense(
                s.pulses, p, r, s.end_ns
            )
        times = interleaved_seconds(calls)
        print(
            f"\n60 s seed train at 7 Hz, {label}: {len(schedule.pulses):,} pulses; "
            "exact events = reference"
        )
        print(f"{'method':<16} {SPREAD_HEADER} {'vs exact':>9} {'max edge error':>15}")
        print(f"{'exact events':<16} {spread(times['exact'], digits=2)} {'1.00x':>9} {'0 ns':>15}")
        for rate_hz in (1_000, 10_000, 100_000):
            error_ns = _edge_error_ns(schedule, pins[0], rate_hz)
            print(
                f"{f'dense {rate_hz // 1000} kHz':<16} {spread(times[rate_hz], digits=2)} "
                f"{ratio(times[rate_hz], times['exact']):>9} {f'{error_ns / 1e3:g} us':>15}"
            )


LONG_PROTOCOL = """\
protocol: long
stimuli:
  buzz:
    frequency_hz: 10
    duration_s: 600
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 2, 3, 4, 5, 6, 7, 8]
  frequencies_hz: [10]
  order: sequential
"""


def _start_up_and_outputs() -> None:
    python = sys.executable
    localisation = str(ROOT / "protocols" / "localisation.yaml")
    commands = {
        "python -c pass (reference)": [python, "-c", "pass"],
        "pinarray --help": [python, "-m", "pinarray", "--help"],
        "pinarray validate --help": [python, "-m", "pinarray", "validate", "--help"],
        "pinarray validate localisation": [python, "-m", "pinarray", "validate", localisation],
    }
    times = interleaved_seconds(
        {
            label: (lambda c=command: subprocess.run(c, capture_output=True, check=True))
            for label, command in commands.items()
        },
        runs=7,
    )
    reference = times["python -c pass (reference)"]
    print("\nstart-up, 7 interleaved runs each (target: validate <= 5x a bare interpreter)")
    print(f"{'command':<34} {SPREAD_HEADER} {'vs python':>10}")
    for label in commands:
        print(f"{label:<34} {spread(times[label])} {ratio(times[label], reference):>10}")

    with tempfile.TemporaryDirectory() as folder:
        protocol = Path(folder) / "long.yaml"
        protocol.write_text(LONG_PROTOCOL)
        outputs = {suffix: str(Path(folder) / f"pulses.{suffix}") for suffix in ("csv", "npz")}
        times = interleaved_seconds(
            {
                suffix: (
                    lambda o=out: subprocess.run(
                        [python, "-m", "pinarray", "compile", str(protocol), "--out", o],
                        capture_output=True,
                        check=True,
                    )
                )
                for suffix, out in outputs.items()
            }
        )
        sizes = {suffix: Path(out).stat().st_size for suffix, out in outputs.items()}
    print("\n`pinarray compile` of 8 trials x 10 min at 10 Hz (480,000 pulses), whole command")
    print(f"{'output':<10} {SPREAD_HEADER} {'vs csv':>7} {'MB':>7}")
    for suffix in outputs:
        print(
            f"{suffix:<10} {spread(times[suffix])} {ratio(times[suffix], times['csv']):>7} "
            f"{sizes[suffix] / 1e6:>7.1f}"
        )


DAY_PROTOCOL = """\
protocol: endurance
description: The seed train for 24 h on one pin (a servo endurance run).
stimuli:
  seed_train:
    frequency_hz: 10
    duration_s: 86400
    pulses_per_cycle: 10
    duty_cycle: 0.5
    pulse_width_ms: {up: 2.0, down: 1.5}
design:
  paradigm: localisation
  stimulus: seed_train
  pins: [1]
  frequencies_hz: [10]
"""


def save_naive_day(path: str) -> None:
    """The reference: the 24 h train's four columns, naive and whole in memory, `np.savez`'d."""
    starts, widths = naive_exact_train(_seed_train(10, DAY_S))
    savez: Callable[..., None] = np.savez  # its stubs type **arrays as its flags
    savez(
        path,
        trial=np.ones(len(starts), np.int32),
        pin=np.ones(len(starts), np.int16),
        start_ns=starts,
        width_ns=widths,
    )


# Run by a bare interpreter, which starts the command and reports its children's peak: a child
# forked from this process (hundreds of MB by now) would count this one's pages as its own.
_PEAK_RSS = (
    "import resource, subprocess, sys\n"
    "subprocess.run(sys.argv[1:], capture_output=True, check=True)\n"
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def _peak_rss_mb(command: list[str]) -> float:
    """Peak resident memory of ``command`` run to its end, in MB."""
    measured = subprocess.run(
        [sys.executable, "-c", _PEAK_RSS, *command], capture_output=True, text=True, check=True
    )
    return int(measured.stdout) * 1024 / 1e6  # ru_maxrss is in KiB on Linux


def _day_long_file() -> None:
    python = sys.executable
    with tempfile.TemporaryDirectory() as folder:
        protocol, ours, naive = (str(Path(folder) / n) for n in ("day.yaml", "ours.npz", "ref.npz"))
        Path(protocol).write_text(DAY_PROTOCOL)
        argv = ["compile", protocol, "--seed", "1", "--allow-long", "--out", ours]

        def compile_npz() -> None:
            with contextlib.redirect_stderr(io.StringIO()):
                assert main(argv) == 0

        times = interleaved_seconds(
            {"compile": compile_npz, "naive": lambda: save_naive_day(naive)}
        )
        with np.load(ours) as mine, np.load(naive) as reference:
            same = sorted(mine.files) == sorted(reference.files) and all(
                mine[name].dtype == reference[name].dtype
                and np.array_equal(mine[name], reference[name])
                for name in reference.files
            )
            pulses = len(reference["start_ns"])
        size_mb = Path(ours).stat().st_size / 1e6
        commands = {
            "python -c 'import numpy' (reference)": [python, "-c", "import numpy"],
            "pinarray compile --allow-long .npz": [python, "-m", "pinarray", *argv],
            "naive + np.savez, as a process": [
                python, "-c",
                f"import sys; sys.path.insert(0, {str(ROOT)!r}); "
                "from tests.benchmarks.bench_schedule import save_naive_day; "
                f"save_naive_day({naive!r})",
            ],
        }
        rss = {label: [_peak_rss_mb(c) for _ in range(5)] for label, c in commands.items()}
        wall = interleaved_seconds(
            {
                label: (lambda c=command: subprocess.run(c, capture_output=True, check=True))
                for label, command in commands.items()
            }
        )
    print(
        f"\n`pinarray compile --allow-long` of the 24 h seed train at 10 Hz to .npz: {pulses:,} "
        f"pulses, {size_mb:.0f} MB, same arrays as the reference: {'yes' if same else 'NO'}"
    )
    print("in this process, ms over 5 interleaved runs (target: <= 2x the reference)")
    print(f"{'what':<38} {SPREAD_HEADER} {'vs naive':>9}")
    labels = {
        "compile": "main(['compile', ..., '--allow-long'])",
        "naive": "naive integer train + np.savez (ref.)",
    }
    for key, label in labels.items():
        print(f"{label:<38} {spread(times[key])} {ratio(times[key], times['naive']):>9}")
    print("whole processes, 5 runs each: peak RSS (MB; target: compile < 600) and wall time (ms)")
    print(f"{'command':<38} {'RSS min':>8} {'median':>8} {'max':>8} {'wall med':>9}")
    for label in commands:
        low, middle, high = min(rss[label]), median(rss[label]), max(rss[label])
        print(
            f"{label:<38} {low:>8.0f} {middle:>8.0f} {high:>8.0f} "
            f"{median(wall[label]) * 1e3:>9.0f}"
        )


def run() -> None:
    _day_long_train()
    _durations()
    _many_pins()
    _array_size()
    _exactness()
    _dense()
    _start_up_and_outputs()
    _day_long_file()
