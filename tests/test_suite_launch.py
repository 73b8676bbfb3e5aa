"""`make test` the same however it is started: a launcher's ignored signals are not the test
processes' (tests/suite.py, `terminal_keys`)."""

import signal
import subprocess
import sys

from tests.runs import REPO

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
