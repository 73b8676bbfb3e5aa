"""`make test` the same however it is started: a launcher's ignored signals are not the test
processes' (tests/suite.py, `terminal_keys`); a real-time test starved once is tried again, and
the report says so and why."""

import signal
import subprocess
import sys

from tests.runs import REPO
from tests.suite import pytest_command

# What a test process sees once the suite has set up: a child's exit status, and Ctrl-C and
# Ctrl-\ as Python sets them up in a terminal.
AS_A_TEST_PROCESS = """\
import signal, subprocess, sys
from tests.suite import terminal_keys

terminal_keys()
print(subprocess.run([sys.executable, "-c", "raise SystemExit(3)"]).returncode,
      signal.getsignal(signal.SIGINT) is signal.default_int_handler,
      signal.getsignal(signal.SIGQUIT) == signal.SIG_DFL)
"""


def ignoring_what_a_launcher_may_ignore() -> None:
    # Ctrl-C and Ctrl-\: a shell's background job; SIGCHLD: some supervisors and containers.
    for number in (signal.SIGINT, signal.SIGQUIT, signal.SIGCHLD):
        signal.signal(number, signal.SIG_IGN)


def test_a_suite_started_with_signals_ignored_reads_exit_statuses_and_takes_ctrl_c():
    done = subprocess.run([sys.executable, "-c", AS_A_TEST_PROCESS], cwd=REPO,
                          preexec_fn=ignoring_what_a_launcher_may_ignore,
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.split() == ["3", "True", "True"], done.stderr


def test_the_helpers_checks_hold_under_python_o_as_the_tests_own_do():
    # pytest rewrites an assert into a test of its own, which `python -O` keeps; a helper
    # module imported unrewritten has plain ones, which it removes (tests/conftest.py).
    import tests.hardware.lab
    import tests.runs

    assert "@pytest_ar" in vars(tests.hardware.lab) and "@pytest_ar" in vars(tests.runs)


# A real-time test that fails its first try only (as one starved by a busy machine does), and
# one that fails every try (as a fault of the code's own does).
STARVED_ONCE_AND_BROKEN = """\
import pytest

tries = []


@pytest.mark.realtime
def test_starved_once():
    tries.append(1)
    assert len(tries) > 1, "the stimulus was not delivered as scheduled: 9.0 ms late"


@pytest.mark.realtime
def test_broken():
    assert False, "a fault of the code's own"
"""


def test_a_real_time_test_failing_once_is_tried_again_and_the_report_says_why(tmp_path):
    probe = tmp_path / "test_probe.py"
    probe.write_text(STARVED_ONCE_AND_BROKEN)
    command = pytest_command("realtime", 1, [
        "-c", str(REPO / "pyproject.toml"), "-p", "no:cacheprovider",
        str(probe)], str(tmp_path / "base"))
    done = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=120)
    report = done.stdout
    assert done.returncode == 1, report  # the broken one fails, after its rerun
    assert "1 failed, 1 passed, 2 rerun" in report.splitlines()[-1]
    assert ("::test_starved_once (call): AssertionError: the stimulus was not "
            "delivered as scheduled: 9.0 ms late") in report
    assert "::test_broken (call): AssertionError: a fault of the code's own" in report
