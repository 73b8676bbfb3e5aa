"""A command started in its own process, interrupted while it waits at a prompt."""

import os
import select
import signal
import subprocess
import sys
import time


def interrupted_at_prompt(argv: list[str], prompt: bytes,
                          signum: int = signal.SIGINT) -> tuple[int, bytes, bytes]:
    """Run ``pinarray ARGV``, send ``signum`` once ``prompt`` shows; (status, stdout, stderr)."""
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", *argv],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        seen = b""
        give_up = time.monotonic() + 60
        while prompt not in seen and time.monotonic() < give_up:
            if select.select([process.stdout], [], [], 1)[0]:
                seen += os.read(process.stdout.fileno(), 4096)
        assert prompt in seen, seen
        process.send_signal(signum)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    return process.returncode, seen + out, err
