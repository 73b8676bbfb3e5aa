"""The public face is a promise: listed, documented, and versioned.

What `pinarray.__all__` and `pinarray.testing.__all__` list is what a lab's script may use.
Each name is documented (numpydoc: the docs site's reference is built from these docstrings,
strictly), `import pinarray` hands out exactly the names listed, and a change to any public
signature fails here until the version says so (semantic versioning) and CHANGELOG.md tells
it: then ``python -m tests.public_api --update`` records the new face.
"""

import ast
import dataclasses
import inspect
import re
from pathlib import Path

import pytest

import pinarray
import pinarray.testing
from tests.public_api import changes, current, read_snapshot, required_bump

REPO = Path(__file__).resolve().parents[1]


def public_objects():
    for face in (pinarray, pinarray.testing):
        for name in face.__all__:
            yield f"{face.__name__}.{name}", getattr(face, name)


def test_every_public_signature_is_the_one_recorded_or_the_version_says_it_changed():
    recorded_version, recorded = read_snapshot()
    breaking, added = changes(recorded, current())
    needed = required_bump(recorded_version, bool(breaking), bool(added))
    assert needed is None, (
        f"the public face changed since {recorded_version} without the version saying so: "
        f"pinarray.__version__ must be at least {needed} (semantic versioning), with the "
        "change in CHANGELOG.md; then run python -m tests.public_api --update\n"
        + "\n".join(breaking + added))


def test_the_changelog_tells_what_this_version_changed():
    changelog = (REPO / "CHANGELOG.md").read_text(encoding="utf-8")
    assert re.search(rf"^## {re.escape(pinarray.__version__)}\b", changelog, re.MULTILINE)


def test_a_breaking_change_needs_the_minor_number_before_1_0_and_a_new_name_the_patch(
        monkeypatch):
    monkeypatch.setattr(pinarray, "__version__", "0.3.0")
    assert required_bump("0.2.0", breaking=True, added=False) is None
    assert required_bump("0.3.0", breaking=True, added=False) == "0.4.0"
    assert required_bump("0.3.0", breaking=False, added=True) == "0.3.1"
    monkeypatch.setattr(pinarray, "__version__", "1.2.0")
    assert required_bump("1.2.0", breaking=True, added=True) == "2.0.0"
    assert required_bump("1.1.5", breaking=False, added=True) is None
    assert required_bump("1.2.0", breaking=False, added=False) is None


def test_import_pinarray_hands_out_exactly_the_names_it_lists_each_from_the_home_it_names():
    tree = ast.parse((REPO / "pinarray" / "__init__.py").read_text(encoding="utf-8"))
    checked = {alias.asname or alias.name for node in ast.walk(tree)
               if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("pinarray.api")
               for alias in node.names}
    homes = {name: module for module, names in pinarray._HOMES.items() for name in names}
    assert sorted(pinarray.__all__) == sorted(homes) == sorted(checked)
    for name, module in homes.items():
        assert name in __import__(module, fromlist=["__all__"]).__all__, (name, module)
        assert getattr(pinarray, name) is not None
    assert set(pinarray.__all__) <= set(dir(pinarray))
    with pytest.raises(AttributeError, match="no attribute 'present'"):
        pinarray.present  # noqa: B018


@pytest.mark.parametrize(("name", "obj"), list(public_objects()))
def test_every_public_name_and_member_has_a_docstring_and_every_field_is_described(name, obj):
    if not (inspect.isclass(obj) or inspect.isfunction(obj)):
        return  # a type alias: its docstring is the text after it, which the docs build checks
    doc = obj.__doc__ or ""
    generated = dataclasses.is_dataclass(obj) and doc.startswith(f"{obj.__name__}(")
    assert doc.strip() and not generated, f"{name} has no docstring"
    if not inspect.isclass(obj):
        return
    undocumented = [member for member, value in vars(obj).items()
                    if not member.startswith("_")
                    and (inspect.isfunction(value) or isinstance(value, property))
                    and not inspect.getdoc(value)]
    assert undocumented == [], f"{name}: members without a docstring"
    if dataclasses.is_dataclass(obj):
        mentioned = {word for kind in obj.__mro__ for word in re.findall(r"\w+", kind.__doc__ or "")}
        missing = [f.name for f in dataclasses.fields(obj) if f.name not in mentioned]
        assert missing == [], f"{name}: fields its docstring does not describe"
