"""Run time against error: the simulated array's fidelity ladder on the shipped protocols.

For each of the five protocols a lab starts from, its fixed-seed batch (``pinarray batch FILE
--observer default --seed 7``, virtual time) as a whole process at each level of
`pinarray.hardware.feetech.sim_levels` (``--sim 'sim://?fidelity=L'``), beside its compute
floor in the same rounds: a process that loads the protocol, plans it, compiles every trial
and encodes its frames, and nothing else. Wall seconds, min / median / max, and the median
over the floor's. The PWM protocol's board has one level (every I2C message).

Error against the wire level's run of the same batch: rows whose verdict differs (status and
its reason), the largest stroke difference (steps, achieved stroke), lag difference (ms,
motion_lag), onset difference (ms, stimulus_onset), the motion samples written (beside the
wire's), and whether every file is the wire's byte for byte (wall-clock stamps, process ids,
the folder and the URL's fidelity key aside).

Targets (issue 48), on the seed batch (localisation): at the wire level within 1.0 s, at the
cheapest level with no verdict disagreement within 0.4 s (medians, beside the floor).

``python -m tests.benchmarks.bench_fidelity --docs FILE.svg`` also prints the table as
Markdown and draws it (docs/rig/simulator.md shows both).
"""

from __future__ import annotations

import csv
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from tests.benchmarks._timing import SPREAD_HEADER, interleaved_seconds, median, spread
from tests.runs import REPO

PROTOCOLS = ("localisation", "apparent_motion", "staircase_motion", "quest_stroke",
             "localisation_pwm")
BOARD = "localisation_pwm"  # a PCA9685 board: one level
LEVELS = ("wire", "packet", "motion")
SEED = 7
WIRE_TARGET_S, CHEAPEST_TARGET_S = 1.0, 0.4

FLOOR = """
import sys
from pathlib import Path
from pinarray.clock import VirtualClock
from pinarray.plan import make_plan
from pinarray.player.families import open_array
from pinarray.player.playback import prepare_trial
from pinarray.protocol.load import load_protocol
from pinarray.schedule import compile_trial
protocol = load_protocol(Path(sys.argv[1]))
plan = make_plan(protocol, int(sys.argv[2]))
array = open_array(protocol.device, None, None, VirtualClock())  # not connected: its encoder
frames = 0
for planned in plan.trials:
    schedule = compile_trial(protocol, planned)
    frames += len(prepare_trial(array, schedule.targets, schedule.pulses).frames)
assert frames > 0
"""

_STAMP = re.compile(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?[+-]\d\d:\d\d")
_PID = re.compile(rb'"pid": \d+')
_LEVEL = re.compile(rb"[?&]fidelity=\w+")


@dataclass(frozen=True)
class Error:
    """One level's batch against the wire level's."""

    rows: int
    verdicts_differ: int
    stroke_steps: float
    lag_ms: float
    onset_ms: float
    samples: int
    wire_samples: int
    same_files: bool


def batch(protocol: str, level: str | None, results: Path) -> None:
    """The protocol's fixed-seed batch at ``level`` (None: the default), into ``results``."""
    shutil.rmtree(results, ignore_errors=True)
    sim = [] if level is None else ["--sim", f"sim://?fidelity={level}"]
    subprocess.run([sys.executable, "-m", "pinarray", "batch", f"protocols/{protocol}.yaml",
                    "--observer", "default", "--subject", "bench", "--seed", str(SEED),
                    "--results", str(results), *sim],
                   cwd=REPO, check=True, stdout=subprocess.DEVNULL, timeout=600)


def floor(protocol: str) -> None:
    subprocess.run([sys.executable, "-c", FLOOR, f"protocols/{protocol}.yaml", str(SEED)],
                   cwd=REPO, check=True, timeout=600)


def _rows(results: Path) -> list[dict[str, str]]:
    (beh,) = results.glob("sub-*/ses-*/beh/*_beh.tsv")
    with beh.open(newline="") as handle:
        return list(csv.DictReader(handle, delimiter="\t"))


def _number(text: str) -> float | None:
    return None if text == "n/a" else float(text)


def _largest(rows: list[tuple[dict[str, str], dict[str, str]]], column: str,
             scale: float) -> float:
    """The largest difference in ``column`` (times ``scale``); inf where one side has none."""
    worst = 0.0
    for ours, theirs in rows:
        a, b = _number(ours[column]), _number(theirs[column])
        if (a is None) != (b is None):
            return float("inf")
        if a is not None and b is not None:
            worst = max(worst, abs(a - b) * scale)
    return worst


def _files(results: Path) -> dict[str, bytes]:
    """Every file's bytes, the run's wall-clock stamps, process ids, folder and level aside."""
    found = {}
    for path in sorted(results.rglob("*")):
        if path.is_file():
            data = _LEVEL.sub(b"", _PID.sub(b"", _STAMP.sub(b"", path.read_bytes())))
            found[str(path.relative_to(results))] = data.replace(str(results).encode(), b"")
    return found


def error(results: Path, wire: Path) -> Error:
    ours, theirs = _rows(results), _rows(wire)
    paired = list(zip(ours, theirs, strict=False))
    differ = abs(len(ours) - len(theirs)) + sum(
        (a["status"], a["status_reason"]) != (b["status"], b["status_reason"]) for a, b in paired)

    def samples(rows: list[dict[str, str]]) -> int:
        return sum(int(r["motion_samples"]) for r in rows if r["motion_samples"] != "n/a")

    return Error(len(ours), differ, _largest(paired, "stroke_achieved", 1.0),
                 _largest(paired, "motion_lag", 1e3), _largest(paired, "stimulus_onset", 1e3),
                 samples(ours), samples(theirs), _files(results) == _files(wire))


def measure(protocol: str, work: Path) -> tuple[dict[str, list[float]], dict[str, Error]]:
    """Seconds of each level's batch and of the floor, and each level's error."""
    levels = (None,) if protocol == BOARD else LEVELS
    folders = {level: work / f"{protocol}-{level}" for level in levels}
    calls = {str(level or "board"): (lambda level=level: batch(protocol, level, folders[level]))
             for level in levels}
    calls["floor"] = lambda: floor(protocol)
    times = interleaved_seconds(calls)
    errors = {} if protocol == BOARD else {
        level: error(folders[level], folders["wire"]) for level in LEVELS}
    return times, errors


def _cell(value: float, unit: str = "") -> str:
    return "unmatched" if value == float("inf") else f"{value:g}{unit}"


def table(measured: dict[str, tuple[dict[str, list[float]], dict[str, Error]]]) -> list[str]:
    """The rows printed: per protocol, each level's seconds beside the floor's, and its error."""
    lines = [f"{'protocol':<17} {'level':<7} {'s':>2} {SPREAD_HEADER} {'/floor':>7}  "
             f"{'verdicts':>9} {'stroke':>7} {'lag':>8} {'onset':>8} {'samples':>15} files"]
    for protocol, (times, errors) in measured.items():
        reference = median(times["floor"])
        for name, seconds in times.items():
            ratio = f"{median(seconds) / reference:.2f}x"
            text = f"{protocol:<17} {name:<7} {'':>2} {spread(seconds, 1, 3)} {ratio:>7}"
            found = errors.get(name)
            if found is not None:
                agree = f"{found.rows - found.verdicts_differ}/{found.rows}"
                text += (f"  {agree:>9} {_cell(found.stroke_steps):>7} "
                         f"{_cell(found.lag_ms, 'ms'):>8} {_cell(found.onset_ms, 'ms'):>8} "
                         f"{found.samples:>7}/{found.wire_samples:<7} "
                         f"{'same' if found.same_files else 'differ'}")
            lines.append(text)
    return lines


def targets(times: dict[str, list[float]], errors: dict[str, Error]) -> list[str]:
    wire = median(times["wire"])
    agreeing = [level for level in LEVELS if errors[level].verdicts_differ == 0]
    cheapest = min(agreeing, key=lambda level: median(times[level]))
    seconds = median(times[cheapest])
    return [
        f"target: the seed batch at the wire level within {WIRE_TARGET_S:g} s: "
        f"{wire:.3f} s median, {'met' if wire <= WIRE_TARGET_S else 'NOT met'}",
        f"target: at the cheapest level with no verdict disagreement ({cheapest}) within "
        f"{CHEAPEST_TARGET_S:g} s: {seconds:.3f} s median, "
        f"{'met' if seconds <= CHEAPEST_TARGET_S else 'NOT met'} (floor {median(times['floor']):.3f} s)",
    ]


def markdown(measured: dict[str, tuple[dict[str, list[float]], dict[str, Error]]]) -> list[str]:
    lines = ["| protocol | level | s (median) | over the floor | verdicts agree | stroke error "
             "(steps) | lag error (ms) | onset error (ms) | samples (wire's) | files |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for protocol, (times, errors) in measured.items():
        reference = median(times["floor"])
        for name, seconds in times.items():
            found = errors.get(name)
            cells = (["", "", "", "", "", ""] if found is None else [
                f"{found.rows - found.verdicts_differ}/{found.rows}", _cell(found.stroke_steps),
                _cell(found.lag_ms), _cell(found.onset_ms),
                f"{found.samples} ({found.wire_samples})",
                "same" if found.same_files else "differ"])
            lines.append(f"| {protocol} | {name} | {median(seconds):.3f} | "
                         f"{median(seconds) / reference:.2f}x | " + " | ".join(cells) + " |")
    return lines


def plot(measured: dict[str, tuple[dict[str, list[float]], dict[str, Error]]],
         path: Path) -> None:
    """Each protocol's levels, run time over its floor (bars) and samples written (labels)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(8, 3.6))
    names = ("wire", "packet", "motion", "board")
    width = 0.25
    for index, (times, errors) in enumerate(measured.values()):
        reference = median(times["floor"])
        shown = [n for n in names if n in times]
        for k, name in enumerate(shown):
            x = index + (k - (len(shown) - 1) / 2) * width
            height = median(times[name]) / reference
            axes.bar(x, height, width * 0.9, color=f"C{names.index(name)}",
                     label=name if index in (0, len(measured) - 1) else None)
            found = errors.get(name)
            if found is not None and found.verdicts_differ == 0:
                axes.text(x, height, "=" if found.same_files else "v", ha="center",
                          va="bottom", fontsize=8)
    axes.axhline(1.0, color="black", linewidth=0.8)
    axes.set_xticks(range(len(measured)), [p.replace("_", "\n") for p in measured], fontsize=8)
    axes.set_ylabel("run time / compute floor")
    handles, labels = axes.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))
    axes.legend(unique.values(), unique.keys(), fontsize=8, frameon=False)
    axes.set_title("fixed-seed batches by level (=: the wire's files, byte for byte; "
                   "v: the same verdicts)", fontsize=9)
    figure.tight_layout()
    figure.savefig(path, metadata={"Date": None})
    plt.close(figure)


def run(docs: Path | None = None) -> None:
    print(f"fixed-seed batches (seed {SEED}, --observer default, virtual time) as whole "
          "processes, each level beside the floor (load, plan, compile, encode) in the same "
          "rounds; wall s; error against the wire level's run")
    measured = {}
    with tempfile.TemporaryDirectory() as work:
        for protocol in PROTOCOLS:
            measured[protocol] = measure(protocol, Path(work))
    for line in table(measured):
        print(line)
    print("\n".join(targets(*measured["localisation"])))
    if docs is not None:
        print("\n".join(markdown(measured)))
        plot(measured, docs)


if __name__ == "__main__":
    run(Path(sys.argv[2]) if sys.argv[1:2] == ["--docs"] else None)
