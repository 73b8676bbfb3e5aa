"""How long `pinarray validate` and the player process take from start to exit, beside
``python -c pass`` (and numpy's import, which the player process does without).

Each command is a whole process, run in turn with the others (after one warm-up each), so a
noisy neighbour slows them alike; the ratio is of the medians. CPU seconds are the children's
own accounting (``getrusage``), steadier than wall time on a shared machine. Printed, never
asserted; `tests/test_startup.py` checks what `validate` imports instead.
"""

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

from tests.benchmarks._timing import SPREAD_HEADER, median, spread

REPO = Path(__file__).resolve().parents[2]
PROTOCOL = "protocols/localisation.yaml"
SCRIPT = Path(sys.executable).parent / "pinarray"  # the console script `pip install` wrote
RUNS = 10  # a start-up is a tenth of a second: more rounds than the usual five
VALIDATE_TARGET = 3.0  # issue 48 (issue 35's was 5x)
# The player process given servos (what it loads before it answers Ready), one per array a lab
# opens and some 86 in make test: 12x with numpy (218 ms of processor, median of 25 on a busy
# machine), 6.3x without (113 ms).
PLAYER_TARGET = 8.0
PLAYER = "player process given servos (python -c: its imports)"
NUMPY = "python -c 'import numpy'"


def _run(command: list[str]) -> tuple[float, float]:
    """(wall, cpu) seconds of one run of ``command``."""
    from pinarray.player.process import PLAYER_ENV

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    subprocess.run(command, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   check=True, timeout=60, env={**os.environ, **PLAYER_ENV})
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def run() -> None:
    python = sys.executable
    commands = {
        "python -c pass": [python, "-c", "pass"],
        f"python -m pinarray validate {PROTOCOL}": [python, "-m", "pinarray", "validate",
                                                   PROTOCOL],
        "python -m pinarray --help (every command)": [python, "-m", "pinarray", "--help"],
        "python -c 'import pinarray' (the public face, lazily)": [python, "-c",
                                                                   "import pinarray"],
        # What `pinarray.player.process` starts, up to Ready (`child.load_playback`), in the
        # environment it starts it in (PLAYER_ENV: numpy's thread pools, were it loaded).
        PLAYER: [python, "-c", "import pinarray.player.child as c; c.load_playback()"],
        NUMPY: [python, "-c", "import numpy"],
    }
    if SCRIPT.exists():
        commands[f"pinarray validate {PROTOCOL}"] = [str(SCRIPT), "validate", PROTOCOL]
    for command in commands.values():
        _run(command)
    wall: dict[str, list[float]] = {name: [] for name in commands}
    cpu: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(RUNS):
        for name, command in commands.items():
            seconds = _run(command)
            wall[name].append(seconds[0])
            cpu[name].append(seconds[1])

    reference = "python -c pass"
    print(f"{RUNS} runs each; ms; ratio: median / median of `{reference}` in the same rounds")
    if os.environ.get("PYTHONDONTWRITEBYTECODE"):
        print("(PYTHONDONTWRITEBYTECODE is set: every run compiles pinarray's sources again)")
    print(f"{'command':<56} {'wall':>4} {SPREAD_HEADER} {'ratio':>6}  {'cpu':>4} "
          f"{SPREAD_HEADER} {'ratio':>6}")
    for name in commands:
        wall_ratio = median(wall[name]) / median(wall[reference])
        cpu_ratio = median(cpu[name]) / median(cpu[reference])
        print(f"{name:<56} {'':>4} {spread(wall[name])} {wall_ratio:>5.2f}x  {'':>4} "
              f"{spread(cpu[name])} {cpu_ratio:>5.2f}x")
    validate = f"pinarray validate {PROTOCOL}" if SCRIPT.exists() else (
        f"python -m pinarray validate {PROTOCOL}")
    ratios = [median(wall[validate]) / median(wall[reference]),
              median(cpu[validate]) / median(cpu[reference])]
    met = "met" if max(ratios) < VALIDATE_TARGET else "NOT met"
    print(f"target: `{validate}` under {VALIDATE_TARGET:g}x `{reference}` (wall and cpu "
          f"medians): {met}")
    ratio = median(cpu[PLAYER]) / median(cpu[reference])
    met = "met" if ratio < PLAYER_TARGET and median(cpu[PLAYER]) < median(cpu[NUMPY]) else "NOT met"
    print(f"target: the {PLAYER} under {PLAYER_TARGET:g}x `{reference}` and under `{NUMPY}` "
          f"alone (cpu medians): {ratio:.2f}x, {met}")
