"""`pinarray` commands run in the test's own process, as the command line runs them.

A command in a process of its own costs a Python start-up and pinarray's imports (about one
second of processor, against a third of one for a whole simulated batch run in this process):
tests whose point is not a separate process run the command here. Those whose point is one (a
kill, a signal, a second process holding a run, a hang that must not hang the suite) fork one
from this process (`Forked`), which costs neither; those whose point is the interpreter's start
or the real entry point's exit status (`python -m pinarray`) start a fresh one, as a lab would.
"""

import contextlib
import io
import os
import signal
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


class Forked:
    """``pinarray ARGV`` in a process of its own, forked from this one (so without a Python
    start-up and pinarray's imports), as `subprocess.Popen` would run it: for tests whose point
    is a separate process, killed, signalled or holding a run, and not the interpreter's start.
    Its output goes to files, read once it has ended (``communicate``)."""

    def __init__(self, folder: Path, *argv: str | os.PathLike[str],
                 cwd: Path | None = None) -> None:
        import multiprocessing

        folder.mkdir(parents=True, exist_ok=True)
        self._out, self._err = folder / "stdout", folder / "stderr"
        self.args = ["pinarray", *map(str, argv)]
        self._process = multiprocessing.get_context("fork").Process(
            target=_run_forked, args=(self.args[1:], self._out, self._err, cwd), daemon=True)
        self._process.start()
        self.pid = self._process.pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None and not self._process.is_alive():
            self.returncode = self._process.exitcode
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        self._process.join(timeout)
        if self.poll() is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0)
        return self.returncode  # type: ignore[return-value]

    def send_signal(self, number: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, number)

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        self.wait(timeout)
        return self._out.read_text(), self._err.read_text()


def pinarray_forked(folder: Path, *argv: str | os.PathLike[str], timeout: float,
                    cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``pinarray ARGV`` in a forked process (`Forked`) waited for as `subprocess.run` waits:
    one still running after ``timeout`` seconds (a hang) is killed, and TimeoutExpired raised."""
    forked = Forked(folder, *argv, cwd=cwd)
    try:
        out, err = forked.communicate(timeout)
    except subprocess.TimeoutExpired:
        forked.send_signal(signal.SIGKILL)
        forked.wait(30)
        raise
    return subprocess.CompletedProcess(forked.args, forked.wait(), out, err)


def _run_forked(argv: list[str], out: Path, err: Path, cwd: Path | None) -> None:
    import sys

    if cwd is not None:
        os.chdir(cwd)
    # The test process's standard streams are pytest's: the command writes to its own files.
    for number, path in ((1, out), (2, err)):
        handle = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(handle, number)
        os.close(handle)
    sys.stdout = open(1, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
    sys.stderr = open(2, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
    sys.exit(main(argv))
