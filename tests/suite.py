"""`make test`: the whole suite in two runs side by side, so that a busy machine rarely fails it.

Most tests only compute (the UI through Textual's pilot, numerics, analysis): they run on
every core, twice over, at a lower priority (nice 10). The tests marked ``realtime`` drive
simulated servos behind pseudo-terminals, player processes or stimuli on the wall clock: a
simulator starved of the processor answers late, which no real servo does, so they run
beside the rest at normal priority, two at a time (they mostly wait: on the wall clock, for
a pseudo-terminal, for a process to start), and the scheduler serves them first. A real-time
test that fails is tried once more, and the report lists it as rerun ("RERUN", and "1 rerun" in
its last line): starved all the same (other programs busy beside, a CI runner shared), the
simulator answers late and the stimulus is rightly reported not delivered, which is what the
product must do and not what the test is about; a test that fails twice fails (and a race
that fails now and then may pass its second try: the report says how each first try failed).
Their report
follows the other's. Their lane collects only the files that mark
tests real-time (`realtime_files`; importing every test module cost it 4 s of processor
before its first test); the other lane, which collects everything, fails on a real-time
test anywhere else (tests/conftest.py).

    python -m tests.suite [-n WORKERS] [PYTEST ARGS...]
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import signal
import struct
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

# pytest's exit status when a selection holds no test (e.g. `-k` matching only one kind).
NO_TESTS_COLLECTED = 5
REALTIME_WORKERS = 2
# The tries a failed real-time test gets beyond its first (pytest-rerunfailures): a starved
# moment passes (the CI runner's one failure in 194 real-time tests on 2026-11-29 was a trial
# rightly reported not delivered, then repeated and delivered). So may an intermittent fault
# of the code's own, a race that signals and processes can hide: every rerun is listed, with
# how its first try failed (tests/reruns.py), so that one seen twice is looked into.
REALTIME_RERUNS = 1
BULK_NICENESS = 10
TESTS = Path(__file__).resolve().parent
PACKAGE = TESTS.parent / "pinarray"
REALTIME_MARK = re.compile(r"\bmark\.realtime\b")
# The test processes' folders (results written, figures drawn, runs killed mid-write) on a RAM
# file system where there is one with room: the tests make thousands of fsyncs (every results
# row is on disk at once), which there cost nothing (make test 165-171 s against 175-177 s on
# disk here, two pairs). Elsewhere the system's temporary folder, as before.
RAM_FOLDER = Path("/dev/shm")
RAM_ROOM_BYTES = 2 * 1024**3


def realtime_files() -> list[Path]:
    """The test files that mark tests real-time (``pytest.mark.realtime``), by their text."""
    return sorted(path for path in TESTS.rglob("test_*.py") if marks_realtime(path))


def in_realtime_lane(path: Path) -> bool:
    """Whether the real-time lane collects the test file at ``path`` (one of `realtime_files`),
    read alone: each of the other lane's processes asks of the few files that hold real-time
    tests, rather than reading all of them (tests/conftest.py)."""
    return (path.is_relative_to(TESTS) and path.name.startswith("test_")
            and path.suffix == ".py" and marks_realtime(path))


def marks_realtime(path: Path) -> bool:
    return REALTIME_MARK.search(path.read_text(encoding="utf-8")) is not None


def rewritten_by_pytest() -> list[Path]:
    """The files pytest rewrites the asserts of as it imports them: the test modules, the
    conftest files, every module of pinarray (whose pytest plugin marks it so) and those of
    the other packages that bring a pytest plugin (Hypothesis, xdist, syrupy, ...)."""
    tests = [path for path in TESTS.rglob("*.py")
             if (path.name.startswith("test_") or path.name == "conftest.py")
             and "psychopy" not in path.relative_to(TESTS).parts]  # PsychoPy's own run
    return tests + sorted(PACKAGE.rglob("*.py")) + plugin_packages_files()


def plugin_packages_files() -> list[Path]:
    """The source files of the installed packages pytest marks for rewriting because their
    distribution brings a pytest plugin, pinarray aside, found as pytest finds them.

    Rewritten copies are cached beside the installed sources, but from a fresh clone every
    test process starts at once and each rewrites what it imports of them: Hypothesis alone
    is some 80 modules, 1.2 s of processor in each of the eight processes here. Uses pytest's
    own reading of the distributions, which is not public API: if it is not found, none."""
    try:
        from _pytest.config import _iter_rewritable_modules
    except ImportError:
        return []
    from importlib.metadata import distributions
    from importlib.util import find_spec

    files = (str(file) for dist in distributions()
             if any(point.group == "pytest11" for point in dist.entry_points)
             for file in dist.files or [])
    found: list[Path] = []
    for name in sorted(set(_iter_rewritable_modules(files)) - {PACKAGE.name}):
        try:
            spec = find_spec(name)  # a top-level name: found, not imported
        except (ImportError, ValueError):  # one pytest would not find either
            continue
        if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
            continue
        origin = Path(spec.origin)
        found += sorted(origin.parent.rglob("*.py")) if spec.submodule_search_locations \
            else [origin]
    return found


def rewrite_ahead() -> int:
    """Rewrite the asserts of every file whose cached rewrite is missing or stale, on every
    core, before the test processes start; returns how many were.

    Each test process rewrites what it imports and caches it beside the source, but from a
    fresh clone all six start together and each rewrites the same 380 files (4 s of
    processor each; 5.6 s once, here). Uses pytest's own rewriting, which is not public API:
    if it is not found, nothing is done ahead and the test processes rewrite as before.
    """
    try:
        from _pytest.assertion.rewrite import PYC_TAIL  # noqa: F401
    except ImportError:
        return 0
    stale = [path for path in rewritten_by_pytest() if not _rewrite_cached(path)]
    if stale:
        with ProcessPoolExecutor(len(os.sched_getaffinity(0))) as pool:
            list(pool.map(_rewrite, stale, chunksize=8))
    return len(stale)


def _cached_rewrite(source: Path) -> Path:
    from _pytest.assertion.rewrite import PYC_TAIL
    return source.parent / "__pycache__" / (source.name[:-3] + PYC_TAIL)


def _rewrite_cached(source: Path) -> bool:
    """As pytest judges its cache: the source's modification time and size in the header."""
    try:
        with open(_cached_rewrite(source), "rb") as cached:
            header = cached.read(16)
        status = source.stat()
    except OSError:
        return False
    return (len(header) == 16 and header[:4] == importlib.util.MAGIC_NUMBER
            and struct.unpack("<LL", header[8:]) == (int(status.st_mtime) & 0xFFFFFFFF,
                                                     status.st_size & 0xFFFFFFFF))


def _rewrite(source: Path) -> None:
    from types import SimpleNamespace

    from _pytest.assertion import rewrite
    try:
        source_status, code = rewrite._rewrite_test(source, None)
    except (OSError, SyntaxError, ValueError):
        return  # left to the test process that imports it, which says what is wrong
    if rewrite.try_makedirs(_cached_rewrite(source).parent):
        rewrite._write_pyc(SimpleNamespace(trace=lambda message: None), code, source_status,
                           _cached_rewrite(source))


def hypothesis_constants_ahead() -> int:
    """Have Hypothesis read the literals of each module of pinarray whose reading it has not
    kept, before the test processes start; returns how many it read.

    Hypothesis tries the literals of the code under test as examples: each test process reads
    those of every module of pinarray it imports (228 as the tests are collected) and keeps
    them in .hypothesis/constants/, by the hash of the source. From a fresh clone all six
    test processes read them all at once: 1 s of processor each here, against 1.4-1.7 s once
    in this process (2 s on both cores). Uses Hypothesis's internals, which are not public
    API: were they to move, nothing is read ahead and the test processes read as before.
    """
    unread = [path for path in sorted(PACKAGE.rglob("*.py")) if not _constants_kept(path)]
    if not unread:
        return 0
    from types import ModuleType

    try:
        from hypothesis.internal.constants_ast import constants_from_module
    except ImportError:
        return 0
    for path in unread:
        module = ModuleType(path.stem)  # not imported: Hypothesis reads only its source file
        module.__file__ = str(path)
        constants_from_module(module)
    return len(unread)


def _constants_kept(source: Path) -> bool:
    """As Hypothesis finds what it read: a file named by the source's hash (SHA-1, 16 digits)."""
    folder = Path(os.environ.get("HYPOTHESIS_STORAGE_DIRECTORY", ".hypothesis")) / "constants"
    return (folder / hashlib.sha1(source.read_bytes()).hexdigest()[:16]).exists()


def temporary_root() -> str | None:
    """Where this run's temporary folder goes: `RAM_FOLDER` if it is writable and has room,
    else None (the system's temporary folder)."""
    try:
        status = os.statvfs(RAM_FOLDER)
    except OSError:
        return None
    room = status.f_bavail * status.f_frsize
    return str(RAM_FOLDER) if room >= RAM_ROOM_BYTES and os.access(RAM_FOLDER, os.W_OK) else None


# Plug-ins the real-time lane's tests do not use, left out of its processes: the UI's snapshot
# plug-in imports Textual, Jinja and syrupy as pytest starts (0.35 s of processor in each of the
# lane's three processes), and no real-time test draws a snapshot.
REALTIME_UNUSED_PLUGINS = ("textual-snapshot", "syrupy")
# One BLAS thread in each of the real-time lane's processes (the player process has one so in
# any case: pinarray.player.process.PLAYER_ENV): its tests multiply no matrices, and OpenBLAS
# starts a thread per core as numpy loads, a quarter of numpy's start-up (some 30 ms of
# processor) in each of the lane's hundreds of `pinarray` commands and scripts.
REALTIME_ENV = {"OPENBLAS_NUM_THREADS": "1"}


def terminal_keys() -> None:
    """Ctrl-C, Ctrl-\\ and a hang-up as in a terminal, and children's ends heard, for every test
    process (a command keeps a terminal's signal ignored where whoever started it ignored it:
    ``nohup make test`` would otherwise fail every test of a hang-up).

    A shell that starts `make test` in the background (a CI runner's script, ``make test &``,
    ``nohup``) hands it Ctrl-C and Ctrl-\\ ignored, and the children inherit that: a lab
    script's Ctrl-C would never raise KeyboardInterrupt there, and the tests of it would fail
    for the way they were started. A launcher that ignores SIGCHLD (some process supervisors
    and container entry points) has every child reaped by the kernel as it ends: each exit
    status then reads as 0 (Python's subprocess on ECHILD), a wait for one child waits for all
    of them, and this process's own wait on the two lanes saw 0, so `make test` passed with
    21 tests of the usual selection failing."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    for number in (signal.SIGQUIT, signal.SIGHUP, signal.SIGCHLD):
        if signal.getsignal(number) == signal.SIG_IGN:
            signal.signal(number, signal.SIG_DFL)


def pytest_command(marker: str, workers: int, args: list[str], basetemp: str) -> list[str]:
    # A temporary folder of this run's own: pytest's default one is cleaned of older runs' folders
    # by every worker as it starts, a walk over thousands of results files on a busy machine.
    realtime = marker == "realtime"
    unused = REALTIME_UNUSED_PLUGINS if realtime else ()
    reruns = ["--reruns", str(REALTIME_RERUNS), "-rR", "-p", "tests.reruns"] if realtime else []
    return [sys.executable, "-m", "pytest", "-m", marker, "-n", str(workers), "--dist", "loadgroup",
            *(f"-pno:{plugin}" for plugin in unused), *reruns, f"--basetemp={basetemp}", *args]


def main(argv: list[str]) -> int:
    terminal_keys()
    workers = 2 * len(os.sched_getaffinity(0))
    if argv[:1] == ["-n"]:
        workers, argv = int(argv[1]), argv[2:]
    # Named files or folders are the caller's choice; else the real-time lane's own files.
    named = any(Path(arg.split("::")[0]).exists() for arg in argv if not arg.startswith("-"))
    realtime_argv = argv if named else [*argv, *map(str, realtime_files())]
    if not sys.dont_write_bytecode:
        rewrite_ahead()
    hypothesis_constants_ahead()
    with tempfile.TemporaryFile("w+") as realtime_log, \
            tempfile.TemporaryDirectory(prefix="pinarray-tests-", dir=temporary_root()) as temporary:
        realtime = subprocess.Popen(
            pytest_command("realtime", min(REALTIME_WORKERS, workers), realtime_argv,
                           os.path.join(temporary, "realtime")),
            stdout=realtime_log, stderr=subprocess.STDOUT, env={**os.environ, **REALTIME_ENV})
        bulk = subprocess.Popen(pytest_command("not realtime", workers, argv,
                                               os.path.join(temporary, "bulk")),
                                preexec_fn=lambda: os.nice(BULK_NICENESS))
        statuses = [bulk.wait(), realtime.wait()]
        realtime_log.seek(0)
        print("\n---- the real-time tests, run beside the others at normal priority ----",
              flush=True)
        sys.stdout.write(realtime_log.read())
    ran = [status for status in statuses if status != NO_TESTS_COLLECTED]
    return max(ran, default=NO_TESTS_COLLECTED)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
