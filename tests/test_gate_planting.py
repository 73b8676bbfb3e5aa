"""The gate holds: each way around the rules of the house, planted in a copy of the package, makes
the gate fail and name it (and the copy as it is passes, so these tests can fail).

The gate is what `make lint` and tests/test_architecture.py run: ruff, import-linter's
`lint-imports` and the syntax-tree checks, all on the copy with the copy's pyproject.toml.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.test_architecture import (
    dynamic_imports_of_the_roots,
    waits_and_signal_handlers_out_of_place,
)

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def gate(project: Path, names: tuple[str, ...] = ()) -> str:
    """What the gate finds wrong in ``project``, one string ("" when it passes).

    Its checks run cheapest first; once every one of ``names`` has been said, the dearest
    (lint-imports, which reads the whole package) is not run: the gate has failed already.
    """
    found: list[str] = []

    def said() -> str:
        return re.sub(r"\s+", " ", "\n".join(found))

    ruff = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache",
                           "--output-format", "concise", "pinarray"],
                          cwd=project, capture_output=True, text=True, timeout=120)
    if ruff.returncode:
        found.append(ruff.stdout + ruff.stderr)
    found += dynamic_imports_of_the_roots(project / "pinarray")
    found += waits_and_signal_handlers_out_of_place(project / "pinarray")
    if names and all(name in said() for name in names):
        return said()
    # lint-imports puts its working directory first on the path: the copy is the one analysed.
    contracts = subprocess.run([LINT_IMPORTS, "--no-cache"], cwd=project, capture_output=True,
                               text=True, timeout=120, env={**os.environ, "COLUMNS": "400"})
    if contracts.returncode:
        found.append(contracts.stdout + contracts.stderr)
    return said()


@pytest.fixture
def project(tmp_path):
    shutil.copytree(ROOT / "pinarray", tmp_path / "pinarray",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    return tmp_path


def test_the_package_as_it_is_passes_the_gate(project):
    assert gate(project) == ""


# (where, what is planted, what the gate must say); a path that does not exist is a new module.
PLANTED = {
    "a relative import up out of the hardware": (
        "hardware/planted.py", "from ..session import trials\n",
        ["TID252", "Dependencies point down the layers"]),
    "the analysis importing the journal's writer": (
        "analysis/planted.py", "from pinarray.journal import writer\n",
        ["Analysis reads result files through the journal's reader: not its writer"]),
    "numpy in the protocol": (
        "protocol/planted.py", "import numpy\n", ["The protocol is pure data: no numpy"]),
    "the pin grid in the adaptive procedures": (
        "adaptive/planted.py", "from pinarray import grid\n",
        ["Adaptive procedures are pure numbers: of the package, only the errors and the units"]),
    "the adaptive procedures imported below them, by the units": (
        "units.py", "\nimport pinarray.adaptive.staircase\n",
        ["Dependencies point down the layers"]),
    "time.sleep in the hardware": (
        "hardware/planted.py", "import time\n\ntime.sleep(0.001)\n", ["TID251 `time.sleep`"]),
    "time.sleep in the commands": (
        "cli/planted.py", "from time import sleep\n\nsleep(0.001)\n",
        ["cli/planted.py:3 sleeps"]),
    "sys.stdout.write in the session": (
        "session/planted.py", "import sys\n\nsys.stdout.write('hello')\n",
        ["TID251 `sys.stdout`"]),
    "builtins.print in the session": (
        "session/planted.py", "import builtins\n\nbuiltins.print('hello')\n", ["T201 `print`"]),
    "print imported from builtins as p in the session": (
        "session/planted.py", "from builtins import print as p\n\np('hello')\n",
        ["T201 `print`"]),
    "a signal handler through from signal import signal": (
        "player/planted.py", "from signal import SIGINT, signal\n\nsignal(SIGINT, print)\n",
        ["TID251 `signal.signal`"]),
    "a signal handler through signal.signal": (
        "imaging/planted.py", "import signal\n\nsignal.signal(signal.SIGINT, print)\n",
        ["TID251 `signal.signal`"]),
    "a signal handler through the event loop": (
        "session/planted.py",
        "import asyncio\nimport signal\n\n"
        "asyncio.get_event_loop().add_signal_handler(signal.SIGINT, print)\n",
        ["session/planted.py:4 installs a signal handler"]),
    "a signal handler installed by the commands": (
        "cli/planted.py", "import signal as s\n\ns.signal(s.SIGINT, print)\n",
        ["cli/planted.py:3 installs a signal handler"]),
    "importlib.import_module of the UI": (
        "journal/planted.py",
        "import importlib\n\nimportlib.import_module('pinarray.tui.app')\n",
        ["journal/planted.py:3 imports pinarray.tui.app by name"]),
    "__import__ of the commands": (
        "analysis/planted.py", "__import__('pinarray.cli')\n",
        ["analysis/planted.py:1 imports pinarray.cli by name"]),
    "an import of a part in the package's __init__": (
        "__init__.py", "\nimport pinarray.grid\n",
        ["The package's __init__ imports no part but the version and, lazily, the public face; the units import none"]),
    "a relative import of a part in the package's __init__": (
        "__init__.py", "\nfrom . import errors\n",
        ["The package's __init__ imports no part but the version and, lazily, the public face; the units import none"]),
}


@pytest.mark.parametrize("violation", PLANTED)
def test_the_gate_fails_on_and_names_a_planted(violation, project):
    where, code, expected = PLANTED[violation]
    target = project / "pinarray" / where
    text = target.read_text(encoding="utf-8") if target.exists() else ""
    target.write_text(text + code, encoding="utf-8")
    found = gate(project, tuple(expected))
    for message in expected:
        assert message in found, f"the gate did not say {message!r}: {found or 'it passed'}"
