"""The public face as text: one line per public name and member, for the signature test.

``python -m tests.public_api --update`` writes tests/public_api.txt from the package as it is,
headed by the version it describes; tests/test_public_api.py compares the package with that
file and holds the versioning rule (`required_bump`). Names are written without the modules
they live in: moving a type inside the package changes nothing a script sees.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import re
import sys
from pathlib import Path
from types import ModuleType

SNAPSHOT = Path(__file__).with_name("public_api.txt")
# Where the promise is made: the names `import pinarray` gives and the mock array's.
FACES = ("pinarray", "pinarray.testing")


def _plain(text: str) -> str:
    """``pinarray.protocol.model.Protocol`` -> ``Protocol``; ``<class 'int'>`` -> ``int``."""
    text = re.sub(r"<class '([\w.]+)'>", r"\1", text)
    return re.sub(r"\b(?:[A-Za-z_]\w*\.)+([A-Za-z_]\w*)", r"\1", text)


def _annotation(annotation: object) -> str:
    """An annotation as written (a string under ``from __future__ import annotations``)."""
    return _plain(annotation if isinstance(annotation, str)
                  else inspect.formatannotation(annotation))


def _signature(obj: object) -> str:
    """``(self, stimulus: Presentable, *, at_ns: int | None = None) -> Delivery``, however the
    module writes its annotations."""
    signature = inspect.signature(obj)  # type: ignore[arg-type]
    plain = signature.replace(
        parameters=[p.replace(annotation=_annotation(p.annotation))
                    if p.annotation is not p.empty else p
                    for p in signature.parameters.values()],
        return_annotation=(_annotation(signature.return_annotation)
                           if signature.return_annotation is not signature.empty
                           else signature.empty))
    # The annotations are text now: drop the quotes repr puts around them (defaults keep theirs).
    return re.sub(r": '([^']*)'", r": \1", re.sub(r" -> '([^']*)'$", r" -> \1", str(plain)))


def _members(cls: type) -> list[str]:
    """A class's public surface: its fields, enum members, methods and properties, as the
    class itself defines them (inherited ones are the base's promise)."""
    lines = []
    name = cls.__name__
    if issubclass(cls, enum.Enum):
        lines += [f"{name}.{member.name} = {member.value!r}" for member in cls]
    if dataclasses.is_dataclass(cls):
        hints = {f.name: f.type for f in dataclasses.fields(cls)}
        lines += [f"{name}.{field}: {_annotation(kind)}" for field, kind in hints.items()]
    for attribute, value in vars(cls).items():
        if attribute.startswith("_") and attribute not in ("__call__", "__enter__", "__exit__"):
            continue
        if isinstance(value, property):
            kind = inspect.signature(value.fget).return_annotation if value.fget else "?"
            lines.append(f"{name}.{attribute}: property -> {_annotation(kind)}")
        elif isinstance(value, staticmethod | classmethod):
            lines.append(f"{name}.{attribute}{_signature(value.__func__)}")
        elif inspect.isfunction(value):
            lines.append(f"{name}.{attribute}{_signature(value)}")
        elif not dataclasses.is_dataclass(cls) and not issubclass(cls, enum.Enum) \
                and not callable(value):
            lines.append(f"{name}.{attribute}: {type(value).__name__}")
    return lines


def describe(module: ModuleType) -> list[str]:
    """Every public name of ``module`` (its ``__all__``) and member, one line each."""
    lines = []
    for name in sorted(module.__all__):
        obj = getattr(module, name)
        where = f"{module.__name__}.{name}"
        if inspect.isclass(obj):
            bases = [b.__name__ for b in obj.__bases__ if b is not object]
            lines.append(f"class {where}({', '.join(bases)})")
            lines += [f"  {line}" for line in _members(obj)]
        elif inspect.isfunction(obj):
            lines.append(f"def {where}{_signature(obj)}")
        else:  # a type alias: what it stands for
            lines.append(f"alias {where} = {_plain(repr(obj))}")
    return lines


def current() -> list[str]:
    import importlib

    return [line for face in FACES for line in describe(importlib.import_module(face))]


def read_snapshot() -> tuple[str, list[str]]:
    """(the version the snapshot describes, its lines)."""
    first, *lines = SNAPSHOT.read_text(encoding="utf-8").splitlines()
    return first.removeprefix("version "), lines


def _key(line: str) -> str:
    """What a line is about: ``def pinarray.load_protocol``, ``  PinArray.present``."""
    return re.split(r"[(:=]", line, maxsplit=1)[0].rstrip()


def changes(old: list[str], new: list[str]) -> tuple[list[str], list[str]]:
    """(what breaks a script: names gone or changed, what is new), as lines."""
    old_by_key = {_key(line): line for line in old}
    new_by_key = {_key(line): line for line in new}
    breaking = [f"- {line}" for key, line in old_by_key.items()
                if new_by_key.get(key) != line]
    added = [f"+ {line}" for key, line in new_by_key.items() if key not in old_by_key]
    return breaking, added


def version_tuple(version: str) -> tuple[int, int, int]:
    major, minor, patch = (int(part) for part in version.split("."))
    return major, minor, patch


def required_bump(before: str, breaking: bool, added: bool) -> str | None:
    """What the version must do past ``before`` for such a change, or None if it has.

    Semantic versioning, with the usual reading before 1.0: a breaking change raises the
    minor number there (the major one from 1.0), a new name at least the patch number (the
    minor one from 1.0).
    """
    import pinarray

    old, now = version_tuple(before), version_tuple(pinarray.__version__)
    if breaking:
        needed = (old[0], old[1] + 1, 0) if old[0] == 0 else (old[0] + 1, 0, 0)
    elif added:
        needed = (old[0], old[1], old[2] + 1) if old[0] == 0 else (old[0], old[1] + 1, 0)
    else:
        return None
    return None if now >= needed else ".".join(map(str, needed))


if __name__ == "__main__" and sys.argv[1:] == ["--update"]:
    import pinarray

    SNAPSHOT.write_text("\n".join([f"version {pinarray.__version__}", *current()]) + "\n",
                        encoding="utf-8")
    print(f"wrote {SNAPSHOT} for pinarray {pinarray.__version__}")
