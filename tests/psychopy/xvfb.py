"""Run a command on a virtual display of its own: Xvfb, started here and stopped after.

    python tests/psychopy/xvfb.py COMMAND [ARGS...]

Xvfb picks a free display number itself (``-displayfd``), so several runs side by side do not
meet. Without Xvfb, a display already set (``DISPLAY``) is used as it is. Standard library
only: `make psychopy` and `make bench` (tests/benchmarks/bench_psychopy.py) both use it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

# How long Xvfb may take to end once asked, in seconds.
STOP_TIMEOUT_S = 20


def why_no_display() -> str | None:
    """Why a window cannot be opened here, or None when one can."""
    if shutil.which("Xvfb") or os.environ.get("DISPLAY"):
        return None
    return "no display and no Xvfb (Debian: apt-get install xvfb)"


def run_with_display(command: list[str]) -> int:
    """Run ``command`` with a display; its exit status."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        reason = why_no_display()
        if reason is not None:
            print(f"xvfb.py: {reason}", file=sys.stderr)
            return 2
        return subprocess.call(command)
    read_end, write_end = os.pipe()
    server = subprocess.Popen([xvfb, "-displayfd", str(write_end), "-screen", "0", "1024x768x24",
                               "-nolisten", "tcp"], pass_fds=(write_end,),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    try:
        with os.fdopen(read_end) as announced:
            number = announced.readline().strip()  # written once the server accepts clients
        if not number:
            print(f"xvfb.py: Xvfb ended before opening a display (status {server.poll()})",
                  file=sys.stderr)
            return 2
        return subprocess.call(command, env={**os.environ, "DISPLAY": f":{number}"})
    finally:
        server.terminate()
        try:
            server.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            server.kill()


if __name__ == "__main__":
    raise SystemExit(run_with_display(sys.argv[1:]))
