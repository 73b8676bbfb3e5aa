"""The flip-to-onset figure inside PsychoPy: a wave armed on a window's flip beside PsychoPy's
own `callOnFlip` of a bare function, in the same run (tests/psychopy/bench_flip.py).

It runs where `make psychopy` runs: in the PsychoPy environment (.venv-psychopy; PsychoPy is
kept out of .venv) on a virtual display (tests/psychopy/xvfb.py). Where either is missing the
row says so and why, and `make bench` goes on.
"""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PSYCHOPY_PYTHON = REPO / ".venv-psychopy" / "bin" / "python"
TIMEOUT_S = 300

sys.path.insert(0, str(REPO / "tests" / "psychopy"))
from xvfb import why_no_display  # noqa: E402


def run() -> None:
    reason = None
    if not (PSYCHOPY_PYTHON.parent.parent / ".installed").exists():
        reason = "the PsychoPy environment (.venv-psychopy) is not built: `make psychopy` builds it"
    elif (no_display := why_no_display()) is not None:
        reason = no_display
    if reason is None:
        ran = subprocess.run([sys.executable, str(REPO / "tests" / "psychopy" / "xvfb.py"),
                              str(PSYCHOPY_PYTHON), str(REPO / "tests" / "psychopy" / "bench_flip.py")],
                             capture_output=True, text=True, timeout=TIMEOUT_S, cwd=REPO)
        if ran.returncode == 0:
            print(ran.stdout, end="")
            return
        last = (ran.stderr.strip().splitlines() or ["(nothing on stderr)"])[-1]
        reason = f"it failed (exit status {ran.returncode}): {last}"
    print(f"wave armed on a flip vs callOnFlip of a bare function: cannot run here: {reason}")
