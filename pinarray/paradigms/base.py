"""The paradigm seam as one type: what a room implements (`Paradigm`).

Its three faces are each defined by the layer that uses it, so that the layer needs nothing
above itself:

- the design (`pinarray.protocol.seam.ParadigmDesign`): its ``design`` keys read and checked,
  its conditions and how each becomes drives, the answers it takes, how the experimenter's
  pad and answer sheets take them, the words for a condition;
- the rows (`pinarray.journal.seam.ParadigmRows`, the ``rows`` attribute): its record type and
  columns, their checks on write and on read-back, its live lines on the run screen;
- the analysis (`pinarray.analysis.seam.ParadigmAnalysis`, the ``analysis`` attribute): its
  simulated observer, its findings (every estimate with its status), tables and figures.

A room is a package whose ``PARADIGM`` is one; pinarray finds its own through
`pinarray.registry` and a lab's through the entry-point group ``pinarray.paradigms``
(docs/programmers/paradigms.md). The promises are kept by the seam, not by each room: every
condition's drives pass the bus and servo checks at validate, every cell read back is checked,
every estimate has a status, and a resumed run plays the same trials.
"""

from __future__ import annotations

import importlib
from functools import cached_property
from types import ModuleType
from typing import TYPE_CHECKING, Protocol, cast, runtime_checkable

from pinarray.protocol.seam import ParadigmDesign

if TYPE_CHECKING:
    from pinarray.analysis.seam import ParadigmAnalysis
    from pinarray.journal.seam import ParadigmRows


@runtime_checkable
class Paradigm(ParadigmDesign, Protocol):
    """A paradigm: its design (this protocol's members), its rows and its analysis.

    ``rows`` and ``analysis`` are best imported when first asked for (a cached property), so
    that ``pinarray validate`` loads the design alone."""

    @property
    def rows(self) -> ParadigmRows:
        """Its results: record type, columns, checks on write and on read-back."""
        ...

    @property
    def analysis(self) -> ParadigmAnalysis:
        """Its simulated subject and its findings: estimates, tables, figures."""
        ...


class Room:
    """A room's rows and analysis, each imported when first asked for: ``ROWS`` of the
    module ``rows`` and ``ANALYSIS`` of the module ``analysis`` beside the class's own (the
    room's package). A room's paradigm is its design class with this mixed in::

        class TapCountParadigm(Room, TapCountDesign):
            pass

        PARADIGM = TapCountParadigm()
    """

    rows_module = "rows"
    analysis_module = "analysis"

    def _beside(self, module: str) -> ModuleType:
        package = type(self).__module__
        if not hasattr(importlib.import_module(package), "__path__"):  # a module, not a package
            package = package.rpartition(".")[0]
        return importlib.import_module(f"{package}.{module}")

    @cached_property
    def rows(self) -> ParadigmRows:
        return cast("ParadigmRows", self._beside(self.rows_module).ROWS)

    @cached_property
    def analysis(self) -> ParadigmAnalysis:
        return cast("ParadigmAnalysis", self._beside(self.analysis_module).ANALYSIS)


def missing_faces(paradigm: object) -> list[str]:
    """What ``paradigm`` lacks of the seam, by name (empty when it is a `Paradigm`): for a
    lab's test of its own room."""
    from pinarray.analysis.seam import ParadigmAnalysis
    from pinarray.journal.seam import ParadigmRows
    from pinarray.protocol.seam import DESIGN_MEMBERS

    missing = [m for m in DESIGN_MEMBERS if not hasattr(paradigm, m)]
    if not isinstance(getattr(paradigm, "rows", None), ParadigmRows):
        missing.append("rows")
    if not isinstance(getattr(paradigm, "analysis", None), ParadigmAnalysis):
        missing.append("analysis")
    return missing
