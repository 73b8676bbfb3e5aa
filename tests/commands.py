"""`pinarray` commands run in the test's own process, as the command line runs them.

A command in a process of its own costs a Python start-up and pinarray's imports (about one
second of processor, against a third of one for a whole simulated batch run in this process):
tests whose point is not a separate process run the command here. Those whose point is one (a
kill, a signal, a second process holding a run, the real entry point's exit status) start a
process as a lab would.
"""

import contextlib
import io
import os
import subprocess
from pathlib import Path

from pinarray.cli import main


def pinarray_here(*argv: str | os.PathLike[str],
                  cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``pinarray ARGV`` in this process (in ``cwd`` if given): its exit status and what it
    printed, as `subprocess.run` gives them for a process of its own."""
    words = [str(word) for word in argv]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(cwd or os.getcwd()), contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        try:
            status = main(words)
        except SystemExit as stop:  # argparse's own exits: --help, a usage error
            status = 0 if stop.code is None else stop.code if isinstance(stop.code, int) else 1
    return subprocess.CompletedProcess(["pinarray", *words], status, out.getvalue(),
                                       err.getvalue())
