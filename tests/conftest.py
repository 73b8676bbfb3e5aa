"""For the whole test suite: LSL stays on this machine (see `tests.lsl_local`)."""

from tests.lsl_local import keep_lsl_on_this_machine


def pytest_configure(config):
    keep_lsl_on_this_machine()
