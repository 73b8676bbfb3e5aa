"""The layering ARCHITECTURE.md draws, checked on the import graph of the package.

Each rule names a part of the package and the parts it may import. Imports inside functions
count too: a lazy import is still an edge.
"""

import ast
import functools
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "pinarray"

# part -> the parts (besides itself) it may import. A part is a top-level module or package of
# `pinarray`; "errors" etc. name `pinarray.errors`.
FOUNDATION = {"errors", "units", "grid", "clock", "stop"}
ALLOWED = {
    "errors": set(),
    "units": set(),
    "grid": {"errors"},
    "clock": {"errors"},
    "stop": {"errors", "clock"},
    "text_files": {"errors"},
    "softness": {"errors"},
    "protocol": {"errors", "units", "grid", "text_files"},
    "hardware": {"errors", "units", "clock", "stop"},
    "schedule": {"errors", "units", "protocol"},
    "plan": {"errors", "units", "protocol"},
    "player": FOUNDATION | {"hardware", "schedule", "protocol", "plan"},
    "journal": FOUNDATION | {"protocol", "plan", "text_files"},
    "session": FOUNDATION | {"protocol", "plan", "schedule", "journal", "hardware", "player"},
    "analysis": FOUNDATION | {"protocol", "plan", "journal", "text_files"},
    # Scanner triggers, volume logs and LSL markers around a session: above it, below the roots.
    "imaging": FOUNDATION | {"protocol", "plan", "schedule", "journal", "session", "hardware",
                             "player"},
    # One sitting at the array (rig, scanner, run, retries, close), driven by the UI and batch.
    "sitting": FOUNDATION | {"protocol", "plan", "journal", "session", "hardware", "player",
                             "imaging"},
}
# The composition roots may import anything; nothing imports them (the CLI starts the UI).
ROOTS = {"cli", "tui", "__main__"}


def part_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def imports_of(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "pinarray":  # `from pinarray import grid`: modules only
                found |= {f"pinarray.{alias.name}" for alias in node.names
                          if (PACKAGE / alias.name).is_dir()
                          or (PACKAGE / f"{alias.name}.py").exists()}
            elif node.module.startswith("pinarray."):
                found.add(node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("pinarray.")}
    return found


@functools.cache  # one parse of the package for every rule
def edges() -> list[tuple[str, str, str]]:
    """(importing part, imported part, file) for every import that crosses parts."""
    result = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        source = part_of(module)
        for target in imports_of(path):
            imported = part_of(target)
            if imported != source and imported != "__init__":
                result.append((source, imported, str(path.relative_to(PACKAGE.parent))))
    return result


def test_every_part_of_the_package_has_a_place_in_the_layering():
    parts = {part_of(".".join(p.relative_to(PACKAGE.parent).with_suffix("").parts))
             for p in PACKAGE.rglob("*.py")}
    unplaced = parts - set(ALLOWED) - ROOTS - {"__init__"}
    assert not unplaced, f"add {sorted(unplaced)} to ALLOWED (and to ARCHITECTURE.md)"


@pytest.mark.parametrize("part", sorted(ALLOWED))
def test_each_part_imports_only_what_lies_below_it(part):
    crossing = [(target, where) for source, target, where in edges()
                if source == part and target not in ALLOWED[part]]
    assert not crossing, f"{part} may not import: " + ", ".join(
        f"{target} (in {where})" for target, where in crossing)


def test_nothing_imports_the_composition_roots():
    offending = [(source, target, where) for source, target, where in edges()
                 if target in ROOTS and source not in ROOTS]
    assert not offending, offending


def test_only_the_composition_roots_parse_arguments_or_talk_to_people():
    offending = []
    for path in PACKAGE.rglob("*.py"):
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if part_of(module) in ROOTS:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if "argparse" in names:
                    offending.append(f"{path.name}:{node.lineno} imports argparse")
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) in ("print", "input"):
                offending.append(f"{path.name}:{node.lineno} calls {node.func.id}")
    assert not offending, offending


def test_one_module_handles_signals():
    handlers = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                if "signal.signal(" in p.read_text(encoding="utf-8")
                or "add_signal_handler(" in p.read_text(encoding="utf-8")]
    assert handlers == ["stop.py"], handlers


def test_one_module_talks_to_the_vendor_sdk_if_any_does():
    importers = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                 if "scservo_sdk" in p.read_text(encoding="utf-8")
                 and "import" in p.read_text(encoding="utf-8").split("scservo_sdk")[0][-40:]]
    assert len(importers) <= 1, importers
