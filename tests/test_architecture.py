"""The rules of the house that no tool checks; the rest of the gate runs in `make lint`.

The gate: import-linter's contracts (pyproject.toml, ``[tool.importlinter]``: the layering
docs/programmers/architecture.md draws), ruff's banned calls, relative imports and print rules
(``[tool.ruff.lint]``, with the places each is allowed), and the syntax-tree checks below, for
what neither tool sees: an import spelled as a string, a signal handler installed through an
event loop, a call to `input`, and sleeping or installing signal handlers in the files ruff lets
use its banned calls (the roots talk to people; clock.py sleeps; stop.py installs signal
handlers). tests/test_gate_planting.py plants a violation of every rule and sees the gate fail.
"""

import ast
import functools
import re
from collections.abc import Iterator
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "pinarray"

# The composition roots: they parse arguments and talk to people; nothing imports them.
ROOTS = ("cli", "tui", "__main__")


def _is_root(package: Path, path: Path) -> bool:
    return path.relative_to(package).parts[0].removesuffix(".py") in ROOTS


def _calls(path: Path, *words: str) -> Iterator[tuple[str, ast.Call]]:
    """Every call in ``path`` with the dotted name it calls, through the file's import aliases
    (``import signal as s``, ``from importlib import import_module as load``); a method of an
    object the file did not import is named by its attribute (``.add_signal_handler``).

    Only a file whose text holds one of ``words`` is parsed: a call of a name the file never
    spells cannot be a call of it.
    """
    text = path.read_text(encoding="utf-8")
    if any(word in text for word in words):
        yield from _calls_in_text(text)


# By the text itself: tests/test_gate_planting.py runs the gate on twenty copies of the
# package that differ in one planted file, and parsing every file again cost 0.5 s a copy.
@functools.cache
def _calls_in_text(text: str) -> tuple[tuple[str, ast.Call], ...]:
    tree = ast.parse(text)
    aliases: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            aliases |= {a.asname or a.name.split(".")[0]: a.name if a.asname else a.name.split(".")[0]
                        for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            aliases |= {a.asname or a.name: f"{node.module}.{a.name}" for a in node.names}
    calls = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        parts: list[str] = []
        func = node.func
        while isinstance(func, ast.Attribute):
            parts.insert(0, func.attr)
            func = func.value
        if isinstance(func, ast.Name):
            calls.append((".".join([aliases.get(func.id, func.id), *parts]), node))
        elif parts:
            calls.append(("." + parts[-1], node))
    return tuple(calls)


def _where(package: Path, path: Path, node: ast.AST) -> str:
    return f"{path.relative_to(package.parent)}:{node.lineno}"


def dynamic_imports_of_the_roots(package: Path) -> list[str]:
    """``importlib.import_module("pinarray.tui.app")`` or ``__import__("pinarray.cli")`` below the
    roots: an import the import graph does not see."""
    found = []
    for path in sorted(package.rglob("*.py")):
        if _is_root(package, path):
            continue
        for name, call in _calls(path, "import_module", "__import__"):
            if name.rsplit(".", 1)[-1] not in ("import_module", "__import__") or not call.args:
                continue
            target = call.args[0]
            if (isinstance(target, ast.Constant) and isinstance(target.value, str)
                    and target.value.split(".")[:2] in [["pinarray", root] for root in ROOTS]):
                found.append(f"{_where(package, path, call)} imports {target.value} by name")
    return found


# The command's start and end, where stop.py is more than may load: the package's first lines
# put Ctrl-C's one-line handler in place, `main` puts Python's back, and says a Ctrl-C that
# comes once the command's work is done.
START_UP = ("__init__.py", "cli/__init__.py")


def waits_and_signal_handlers_out_of_place(package: Path) -> list[str]:
    """A signal handler installed through an event loop outside stop.py; in the files ruff lets
    use the standard streams (the roots) or its banned calls (clock.py, stop.py), `time.sleep`
    outside clock.py and `signal.signal` outside stop.py; `_signal.signal` outside the
    command's start and end; below the roots, `input`."""
    found = []
    for path in sorted(package.rglob("*.py")):
        relative = str(path.relative_to(package))
        exempt_from_ruff = _is_root(package, path) or relative in ("clock.py", "stop.py")
        for name, call in _calls(path, "signal", "sleep", "input"):
            where = _where(package, path, call)
            if relative not in START_UP and name == "_signal.signal":
                found.append(f"{where} installs a signal handler (stop.py installs them)")
            elif relative != "stop.py" and (name.endswith(".add_signal_handler")
                                            or exempt_from_ruff and name == "signal.signal"):
                found.append(f"{where} installs a signal handler (stop.py installs them)")
            elif exempt_from_ruff and relative != "clock.py" and name == "time.sleep":
                found.append(f"{where} sleeps (wait through a Clock from clock.py)")
            elif not _is_root(package, path) and name in ("input", "builtins.input"):
                found.append(f"{where} asks for input (only the roots talk to people)")
    return found


def test_nothing_below_the_composition_roots_imports_them_by_name():
    assert dynamic_imports_of_the_roots(PACKAGE) == []


def test_only_clock_and_stop_wait_and_handle_signals_and_only_the_roots_ask_for_input():
    assert waits_and_signal_handlers_out_of_place(PACKAGE) == []


def test_one_module_talks_to_the_vendor_sdk_if_any_does():
    importers = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                 if "scservo_sdk" in p.read_text(encoding="utf-8")
                 and "import" in p.read_text(encoding="utf-8").split("scservo_sdk")[0][-40:]]
    assert len(importers) <= 1, importers


def test_architecture_md_has_a_row_for_every_package_and_top_level_module_and_none_for_the_gone():
    rows = [line.split("|")[1:-1] for line in
            (PACKAGE.parent / "docs" / "programmers" / "architecture.md").read_text(encoding="utf-8").splitlines()
            if line.startswith("| `")]
    named = {name for row in rows for name in re.findall(r"`([^`]+)`", row[0])}
    paths = {name for row in rows for cell in row for name in re.findall(r"`([^`]+)`", cell)
             if re.fullmatch(r"[\w/]+(\.py|/)", name)}  # a path, not `sim://`
    packages = {f"{p.parent.relative_to(PACKAGE)}/" for p in PACKAGE.rglob("__init__.py")
                if p.parent != PACKAGE}
    modules = {p.name for p in PACKAGE.glob("*.py")}
    assert sorted((packages | modules) - named) == [], "without a row in the table"
    assert sorted(p for p in paths if not (PACKAGE / p).exists()) == [], "gone from pinarray/"
