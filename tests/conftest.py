"""For the whole test suite: LSL stays on this machine (see `tests.lsl_local`); no Hypothesis
example is judged by how long it took (a wall-time limit fails on a busy machine; timing
belongs in `make bench`); the longest tests start first, so that on several workers none of
them is left running alone at the end; the garbage collector runs less often, and never again over what collection imported."""

import contextlib
import gc
from pathlib import Path

import pytest

# The helper modules' asserts (tests/runs.py, tests/hardware/lab.py: every servo at rest and
# released, ...) rewritten as pytest rewrites the test modules', before any of them is
# imported: a plain assert vanishes under `python -O` (PYTHONOPTIMIZE=1 in a lab's
# environment), and those checks would pass whatever happened. pytest's own stay.
_TESTS = Path(__file__).resolve().parent
pytest.register_assert_rewrite(*sorted(
    ".".join(("tests", *path.relative_to(_TESTS).with_suffix("").parts))
    for path in _TESTS.rglob("*.py")
    if not path.name.startswith("test_") and path.name not in ("conftest.py", "__init__.py")))

from hypothesis import settings  # noqa: E402
from hypothesis.internal import entropy  # noqa: E402

from tests.lsl_local import keep_lsl_on_this_machine  # noqa: E402

# The PsychoPy plugin's tests run in PsychoPy's environment (`make psychopy`), not here.
collect_ignore = ["psychopy"]

# Python's default (700, 10, 10) collects after every 700 new objects: a UI test builds and
# drops widgets by the thousand, and spent about a fifth of its processor time collecting
# (tests/tui/test_run_controls.py: 21.7-23.1 s of CPU, 17.3-19.4 s with these). Only the
# test processes: the UI and the batch keep their own.
gc.set_threshold(10_000, 10, 10)

settings.register_profile("pinarray", deadline=None)
settings.load_profile("pinarray")

# Around every example Hypothesis saves, seeds and restores the global random generators; once
# numpy is imported, numpy's global one too, which cost 0.28 ms of the 0.38 ms per example here
# (a few seconds of processor over the suite). Nothing here draws from numpy's global generator
# (seeded Generators only; ruff's NPY002 refuses the legacy calls, pyproject.toml), so Hypothesis
# is told it already holds one. The name is Hypothesis's own, not public API: were it to move,
# numpy's generator is managed again and only the time is lost.
if getattr(entropy, "NP_RANDOM", None) is None:
    entropy.NP_RANDOM = object()


# Around each argument it draws (and each data.draw) Hypothesis copies the global `random`
# generator's whole state twice (random.getstate, 625 numbers), to warn if a strategy drew from
# it: 35 us an argument, about 1.5 s of processor over the bulk tests here. Nothing here draws
# from that generator (seeded random.Random instances only, as the simulators' faults), so the
# warning is left out. The names are Hypothesis's own, not public API: were they to move, the
# warning is back and only the time is lost.
@contextlib.contextmanager
def _random_left_unwatched(fmt, *args):
    yield


def _leave_random_unwatched():
    from importlib import import_module

    for name in ("hypothesis.control", "hypothesis.strategies._internal.core"):
        try:
            module = import_module(name)
        except ImportError:
            continue
        if hasattr(module, "deprecate_random_in_strategy"):
            module.deprecate_random_in_strategy = _random_left_unwatched


_leave_random_unwatched()


def pytest_configure(config):
    keep_lsl_on_this_machine()


def pytest_collection_finish(session):
    # What the test modules imported lives as long as the process: out of the collector's
    # sight, every full collection (pytest makes five as each worker ends) costs a fraction.
    gc.freeze()


def pytest_sessionfinish(session):
    # As the process ends pytest collects five times over, to report what a finalizer raised
    # (0.9 s of processor per worker): one collection here finds it as well (the hook that
    # reports it is still in place), and the five that follow walk nothing.
    gc.collect()
    gc.freeze()


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: item.get_closest_marker("long") is None)  # stable: keeps order
    if config.getoption("markexpr") == "not realtime":  # the bulk lane of tests/suite.py
        from tests.suite import in_realtime_lane

        marked = {item.path for item in items if item.get_closest_marker("realtime")}
        outside = {path for path in marked if not in_realtime_lane(path)}
        strays = [item.nodeid for item in items if item.get_closest_marker("realtime")
                  and item.path in outside]
        if strays:
            raise pytest.UsageError(
                f"real-time test(s) the real-time lane of tests/suite.py would not collect "
                f"(mark them with pytest.mark.realtime in their file): {', '.join(strays)}")
