"""Loaded by the examples tests/psychopy starts (``PYTHONPATH``): where such a process exits.

In full runs, now and then, the PsychoPy example ended with exit status 0 having printed
nothing, never alone. With ``PINARRAY_EXIT_TRACE`` set to a file, every ``sys.exit`` call (the
way `psychopy.core.quit` ends a script) is written there with its stack, and, at the exit,
where standard output points: a failing test shows the file.
"""

import atexit
import os
import sys
import traceback

_TRACE = os.environ.get("PINARRAY_EXIT_TRACE")


def _note(text: str) -> None:
    with open(_TRACE, "a", encoding="utf-8") as trace:  # type: ignore[arg-type]
        trace.write(f"[process {os.getpid()}, {' '.join(sys.argv)[:100]}] {text}")


if _TRACE:
    _exit = sys.exit

    def _traced_exit(status: object = None) -> None:
        _note(f"sys.exit({status!r}) called from:\n" + "".join(traceback.format_stack()[:-1]))
        _exit(status)

    def _at_exit() -> None:
        try:
            where = os.readlink("/proc/self/fd/1")
        except OSError as error:
            where = str(error)
        _note(f"at exit: standard output is {where}\n")

    sys.exit = _traced_exit
    atexit.register(_at_exit)
