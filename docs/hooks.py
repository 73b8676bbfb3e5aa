"""MkDocs hook: every public name is documented, or the strict build fails.

mkdocstrings renders what has a docstring and quietly skips what has none; this hook loads the
package as the reference does (griffe, statically) and warns for each name in
`pinarray.__all__` and `pinarray.testing.__all__` (and each public method, property and type
alias among them) without a docstring. Under ``strict: true`` a warning fails the build.
"""

from __future__ import annotations

import logging

import griffe

log = logging.getLogger("mkdocs.plugins.pinarray")
FACES = ("pinarray", "pinarray.testing")


def _undocumented(package: griffe.Module) -> list[str]:
    found = []
    for face in FACES:
        module = package if face == "pinarray" else package[face.split(".", 1)[1]]
        for name in module.exports or ():
            obj = module[name]
            target = obj.final_target if obj.is_alias else obj
            if not (target.docstring and target.docstring.value.strip()):
                found.append(f"{face}.{name}")
                continue
            if target.is_class:
                for member_name, member in target.members.items():
                    if member_name.startswith("_") or member.is_alias:
                        continue
                    is_property = "property" in getattr(member, "labels", set())
                    if (member.is_function or is_property) and not member.docstring:
                        found.append(f"{face}.{name}.{member_name}")
    return found


def on_pre_build(config: object) -> None:
    package = griffe.load("pinarray", search_paths=["."], resolve_aliases=True,
                          resolve_external=False)
    for name in _undocumented(package):
        log.warning("the public name %s has no docstring", name)
