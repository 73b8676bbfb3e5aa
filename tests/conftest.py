"""For the whole test suite: LSL stays on this machine (see `tests.lsl_local`)."""

import shutil

from tests.lsl_local import keep_lsl_on_this_machine

_CONFIG = None


def pytest_configure(config):
    global _CONFIG
    _CONFIG = keep_lsl_on_this_machine()


def pytest_unconfigure(config):
    if _CONFIG is not None:
        shutil.rmtree(_CONFIG.parent, ignore_errors=True)
