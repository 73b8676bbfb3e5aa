"""Which paradigms there are, by the name a protocol's ``paradigm:`` gives: a registry.

A paradigm is one room (`pinarray.paradigms`): a package that implements the paradigm seam
(`pinarray.paradigms.base.Paradigm`). pinarray's own rooms are listed here, by module; a
lab's own paradigm, in a package of its own, is found by its entry point in the group
``pinarray.paradigms`` (``name = "package.module:PARADIGM"``), e.g. in its pyproject.toml::

    [project.entry-points."pinarray.paradigms"]
    vibration_count = "pinarray_vibration_count:PARADIGM"

Rooms are imported when first asked for, and entry points are read only when a name is not
one of pinarray's own (or every paradigm is asked for), so reading a protocol of a shipped
paradigm costs one import. An entry point whose name pinarray ships, is no paradigm's name, or
was given by a package found earlier is left out, and kept with why (`ignored`: the commands
say it). Nothing here knows what a paradigm does: the layers that use one
check it implements their part of the seam (`pinarray.protocol.seam`, `pinarray.journal.seam`,
`pinarray.analysis.seam`). Pure Python.

A lab's package is imported behind one boundary (`room`): whatever its import raises is a
`PinArrayError` naming it, ``SystemExit`` included (a command would otherwise end at once,
status 0, having done nothing). Two exceptions pass through, because they may be the person at
the keyboard: pinarray's own stop (`pinarray.errors.Interrupted`, a signal under the stop
handlers) and ``KeyboardInterrupt`` where Ctrl-C raises it (SIGINT at Python's default
handler: validate, plan, analyse). There a plug-in raising it cannot be told from Ctrl-C
without a handler of the registry's own (signal handlers are `pinarray.stop`'s alone), and
Ctrl-C must stop any command; where the stop handlers take SIGINT (a run), it can only be the
package's, and is said as its fault.
"""

from __future__ import annotations

import importlib
import re
import signal
from functools import cache
from typing import NamedTuple

from pinarray.errors import Interrupted, PinArrayError

GROUP = "pinarray.paradigms"
# pinarray's own rooms, each module's `PARADIGM`, in the order results files older than the
# seam tell their rows apart (a row names at most one of them).
BUILT_IN = {
    "identification": "pinarray.paradigms.identification",
    "two_interval": "pinarray.paradigms.two_interval",
    "temporal_order": "pinarray.paradigms.temporal_order",
    "localisation": "pinarray.paradigms.localisation",
    "apparent_motion": "pinarray.paradigms.apparent_motion",
    "two_point": "pinarray.paradigms.two_point",
}
# The order people read them in (validate's list of what a design may name).
LISTED = ("localisation", "apparent_motion", "identification", "two_interval", "temporal_order",
          "two_point")
NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")


class Ignored(NamedTuple):
    """An installed plug-in the registry leaves out: its name, its package, and why."""

    name: str
    package: str
    why: str

    def warning(self) -> str:
        """The one line a command says of it (after ``pinarray: warning: ``)."""
        return f"paradigm plug-in {self.name} from {self.package} ignored: {self.why}"


def _plug_ins() -> dict[str, str]:
    """Installed packages' paradigms: name -> entry point value (read once, `_entry_points`)."""
    return _entry_points()[0]


@cache
def _entry_points() -> tuple[dict[str, str], tuple[Ignored, ...]]:
    """Installed packages' paradigms (name -> entry point value), and those left out: a name
    pinarray ships (a plug-in cannot replace a shipped paradigm), one that is no paradigm's
    name, or one a package found earlier already gives."""
    from importlib.metadata import entry_points

    found: dict[str, tuple[str, str]] = {}
    ignored: list[Ignored] = []
    for point in entry_points(group=GROUP):
        package = point.dist.name if point.dist is not None else "an unnamed package"
        if point.name in BUILT_IN:
            ignored.append(Ignored(point.name, package, "pinarray ships a paradigm of that "
                                   "name, which a package cannot replace; rename the entry point"))
        elif not NAME.fullmatch(point.name):
            ignored.append(Ignored(point.name, package, "expected a paradigm's name (a lowercase "
                                   "letter, then at most 31 lowercase letters, digits or _), "
                                   f"found {point.name!r}"))
        elif point.name in found:
            ignored.append(Ignored(point.name, package, f"{found[point.name][1]} gives a "
                                   "paradigm of that name too, and was found first"))
        else:
            found[point.name] = (point.value, package)
    return ({name: value for name, (value, _) in sorted(found.items())}, tuple(ignored))


def ignored() -> tuple[Ignored, ...]:
    """The installed plug-ins left out, once the installed packages' entry points have been
    read (nothing is read for them: a command says what its paradigms' reading found)."""
    if not _entry_points.cache_info().currsize:
        return ()
    return _entry_points()[1]


def why_not(name: str) -> str:
    """Why a paradigm called ``name`` cannot be had, for a refusal: the paradigms there are,
    and the installed plug-in of that name that was left out, if any."""
    said = f"expected a paradigm ({', '.join(names())}), found {name!r}"
    for plug_in in _entry_points()[1]:
        if plug_in.name == name:
            return f"{said}: the {plug_in.warning()}"
    return said


def names() -> tuple[str, ...]:
    """Every paradigm a protocol may name: pinarray's own, then the installed plug-ins'."""
    return (*LISTED, *_plug_ins())


def is_known(name: str) -> bool:
    """Whether ``name`` is a paradigm (pinarray's own, or an installed plug-in's)."""
    return name in BUILT_IN or name in _plug_ins()


@cache
def room(name: str) -> object:
    """The paradigm called ``name``, its room imported on first use; a `PinArrayError` naming
    the paradigms there are when there is none, or the plug-in when it cannot be loaded."""
    if name in BUILT_IN:
        return importlib.import_module(BUILT_IN[name]).PARADIGM
    value = _plug_ins().get(name)
    if value is None:
        raise PinArrayError(why_not(name))
    module, _, attribute = value.partition(":")
    try:
        found = importlib.import_module(module)
        for part in attribute.split(".") if attribute else ():
            found = getattr(found, part)
    except BaseException as problem:  # a lab's package: whatever it raises, said in one line
        if isinstance(problem, Interrupted) or (isinstance(problem, KeyboardInterrupt)
                                                and _ctrl_c_raises()):
            raise  # maybe the person at the keyboard (the module says why)
        raise PinArrayError(f"paradigm {name!r}: its package ({value}, entry point group "
                            f"{GROUP}) cannot be loaded: {type(problem).__name__}: "
                            f"{problem}") from None
    if getattr(found, "name", None) != name:
        raise PinArrayError(f"paradigm {name!r}: the entry point ({value}) gives "
                            f"{type(found).__name__}, whose name is "
                            f"{getattr(found, 'name', None)!r}, not {name!r}")
    return found


def _ctrl_c_raises() -> bool:
    """Whether Ctrl-C raises KeyboardInterrupt here (SIGINT at Python's default handler)."""
    try:
        return signal.getsignal(signal.SIGINT) is signal.default_int_handler
    except ValueError:  # not the main interpreter: take it as the default
        return True


def plug_ins() -> tuple[str, ...]:
    """The installed plug-ins' paradigm names (none imported)."""
    return tuple(_plug_ins())
