"""The gate holds: each way around the rules of the house, planted in a copy of the package, makes
the gate fail and name it there (and the copy as it is passes, so these tests can fail).

The gate is what `make lint` and tests/test_architecture.py run: ruff, import-linter's
`lint-imports` and the syntax-tree checks, all on the copy with the copy's pyproject.toml.
Every violation is planted in one copy, each in a module of its own or at the end of the one it
changes, and the gate runs once over it (a copy and a gate per violation cost 0.5 s of processor
each): each test finds what the gate said about its own violation, by the file and lines it was
planted at, so that one violation cannot answer for another.
"""

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.test_architecture import (
    dynamic_imports_of_the_roots,
    waits_and_signal_handlers_out_of_place,
)

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def gate(project: Path) -> list[str]:
    """What the gate finds wrong in ``project``: each of ruff's lines, each syntax-tree finding
    and each part of lint-imports' report of broken contracts, one string each ([] when it
    passes)."""
    found: list[str] = []
    ruff = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache",
                           "--output-format", "concise", "pinarray"],
                          cwd=project, capture_output=True, text=True, timeout=120)
    if ruff.returncode:
        found += (ruff.stdout + ruff.stderr).splitlines()
    found += dynamic_imports_of_the_roots(project / "pinarray")
    found += waits_and_signal_handlers_out_of_place(project / "pinarray")
    # lint-imports puts its working directory first on the path: the copy is the one analysed.
    contracts = subprocess.run([LINT_IMPORTS, "--no-cache"], cwd=project, capture_output=True,
                               text=True, timeout=120, env={**os.environ, "COLUMNS": "400"})
    if contracts.returncode:
        found += report_parts(contracts.stdout + contracts.stderr)
    return found


def report_parts(report: str) -> list[str]:
    """lint-imports' report cut at each heading (a line underlined with dashes): a broken
    contract's part holds its name and the chains of imports that break it."""
    lines = report.splitlines()
    starts = [n for n in range(len(lines) - 1)
              if lines[n].strip() and re.fullmatch(r"-+", lines[n + 1])]
    return ["\n".join(lines[a:b]) for a, b in zip(starts, [*starts[1:], len(lines)], strict=True)]


@dataclass(frozen=True)
class Place:
    """Where a violation was planted: a file of the copy and the lines it took."""

    path: str  # relative to the copy's root: pinarray/hardware/planted_0.py
    lines: range

    @property
    def module(self) -> str:
        return self.path.removesuffix(".py").removesuffix("/__init__").replace("/", ".")

    def named_in(self, said: str) -> bool:
        """Whether ``said`` (a line of ruff's or of the syntax-tree checks, or a part of
        lint-imports' report) is about this place."""
        at = re.match(r"(\S+?\.py):(\d+)[: ]", said)
        if at:
            return at[1] == self.path and int(at[2]) in self.lines
        # A chain of imports starts where the import was written: "- importer -> imported (l.N)".
        for importer, numbers in re.findall(r"^-\s+([\w.]+) -> [\w.]+ \(([l.\d, ]+)\)$", said,
                                            flags=re.MULTILINE):
            if importer == self.module and any(int(n) in self.lines
                                               for n in re.findall(r"\d+", numbers)):
                return True
        return False


def copy_of_the_package(folder: Path) -> Path:
    shutil.copytree(ROOT / "pinarray", folder / "pinarray",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", folder)
    return folder


def test_the_package_as_it_is_passes_the_gate(tmp_path):
    assert gate(copy_of_the_package(tmp_path)) == []


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
        ["sleeps (wait through a Clock from clock.py)"]),
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
        ["installs a signal handler (stop.py installs them)"]),
    "a signal handler installed by the commands": (
        "cli/planted.py", "import signal as s\n\ns.signal(s.SIGINT, print)\n",
        ["installs a signal handler (stop.py installs them)"]),
    "a signal handler through the built-in _signal": (  # past ruff's ban of signal.signal
        "hardware/planted.py", "import _signal\n\n_signal.signal(_signal.SIGINT, print)\n",
        ["installs a signal handler (stop.py installs them)"]),
    "importlib.import_module of the UI": (
        "journal/planted.py",
        "import importlib\n\nimportlib.import_module('pinarray.tui.app')\n",
        ["imports pinarray.tui.app by name"]),
    "__import__ of the commands": (
        "analysis/planted.py", "__import__('pinarray.cli')\n",
        ["imports pinarray.cli by name"]),
    "an import of a part in the package's __init__": (
        "__init__.py", "\nimport pinarray.grid\n",
        ["The package's __init__ imports no part but the version and, lazily, the public face; the units import none"]),
    "a relative import of a part in the package's __init__": (
        "__init__.py", "\nfrom . import errors\n",
        ["The package's __init__ imports no part but the version and, lazily, the public face; the units import none"]),
}


def plant(project: Path, where: str, code: str, number: int) -> Place:
    """``code`` at the end of the package's ``where``; a module that does not exist is a new
    one, numbered apart from the other new ones (planted_0.py, planted_1.py, ...)."""
    target = project / "pinarray" / where
    if not target.exists():
        target = target.with_name(f"{target.stem}_{number}.py")
    text = target.read_text(encoding="utf-8") if target.exists() else ""
    target.write_text(text + code, encoding="utf-8")
    first = text.count("\n") + 1  # every file and every planted code ends its last line
    return Place(str(target.relative_to(project)), range(first, first + code.count("\n")))


@pytest.fixture(scope="module")
def planted(tmp_path_factory) -> tuple[dict[str, Place], list[str]]:
    """Every violation planted in one copy: where each is, and what the gate said."""
    project = copy_of_the_package(tmp_path_factory.mktemp("planted"))
    places = {violation: plant(project, where, code, number)
              for number, (violation, (where, code, _)) in enumerate(PLANTED.items())}
    return places, gate(project)


@pytest.mark.parametrize("violation", PLANTED)
def test_the_gate_fails_on_and_names_a_planted(violation, planted):
    places, said = planted
    place = places[violation]
    about_it = [re.sub(r"\s+", " ", part) for part in said if place.named_in(part)]
    for message in PLANTED[violation][2]:
        assert any(message in part for part in about_it), (
            f"the gate did not say {message!r} about {place.path}, lines {place.lines.start}-"
            f"{place.lines.stop - 1}: {about_it or 'nothing'}")
