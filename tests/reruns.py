"""A pytest plugin for the runs that try a failed real-time test again (`make test`'s real-time
lane, tests/suite.py; `make psychopy`): how each rerun test failed its first try, at the end of
the report, so that a rerun is never silent. Loaded with ``-p tests.reruns``."""

import pytest

_reruns: list[pytest.TestReport] = []


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.outcome == "rerun":  # pytest-rerunfailures' outcome for a failed try
        _reruns.append(report)


def pytest_terminal_summary(terminalreporter) -> None:
    if _reruns:
        terminalreporter.section("how each rerun test failed before its rerun")
        for report in _reruns:
            crash = getattr(report.longrepr, "reprcrash", None)
            why = crash.message.splitlines()[0] if crash is not None else str(report.longrepr)
            terminalreporter.line(f"{report.nodeid} ({report.when}): {why}")
