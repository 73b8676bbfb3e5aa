"""The paradigm seam, as the analysis sees it: a simulated subject, and what the rows show.

Each paradigm's room (`pinarray.paradigms`) gives its simulated subject for a fixed design
(`ParadigmAnalysis.observer`) and analyses its counted rows (`ParadigmAnalysis.findings`):
its estimates, its sections of ``summary.md``, its tables, figures and printout (`Findings`).
The analysis knows a paradigm only through it, found by name (`analysis_of`).

What every paradigm promises of its estimates is kept here, once for all: an `Estimate`
carries its status, ``estimated`` (a value, and its interval where one can be had),
``bounded`` (no value: the answers state one bound) or ``not resolved`` (neither: the
answers do not place it), with the words that say why; numbers it does not have are NaN,
never a number the answers do not support (`Estimate.__post_init__` refuses one). Every
paradigm's estimates are listed together in ``estimates.csv`` (`pinarray.analysis.report`).
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from pinarray import registry
from pinarray.errors import PinArrayError

if TYPE_CHECKING:
    from pinarray.analysis.load import LoadedTrial, RunSelection
    from pinarray.analysis.power import PowerModel
    from pinarray.analysis.subjects import IntervalSettings
    from pinarray.grid import Grid
    from pinarray.journal.records import TrialRecord
    from pinarray.protocol.model import Condition
    from pinarray.protocol.model import Protocol as PinProtocol


class EstimateStatus(StrEnum):
    """Whether the answers place an estimate: a value, one bound, or neither."""

    ESTIMATED = "estimated"
    BOUNDED = "bounded"
    NOT_RESOLVED = "not resolved"


@dataclass(frozen=True)
class Estimate:
    """One reported value with its 95 % interval, its status, and the words for it.

    ``value`` is a number only when ``status`` is estimated (its interval may still be NaN:
    a mean over one subject); a bounded estimate has no value and exactly the bound the
    answers state (the other NaN); one not resolved has no number at all. ``words`` say it in
    the lab's terms (``estimated``, ``below the lowest value tested``, ``not fitted``...).
    """

    value: float
    ci_low: float
    ci_high: float
    status: EstimateStatus
    words: str

    def __post_init__(self) -> None:
        low, high = not math.isnan(self.ci_low), not math.isnan(self.ci_high)
        match self.status:
            case EstimateStatus.ESTIMATED:
                fine = not math.isnan(self.value)
            case EstimateStatus.BOUNDED:
                fine = math.isnan(self.value) and low != high
            case _:
                fine = math.isnan(self.value) and not (low or high)
        if not fine:
            raise PinArrayError(f"an estimate {self.status.value} ({self.words}) cannot hold "
                                f"value {self.value} in [{self.ci_low}, {self.ci_high}]")

    @property
    def numbers(self) -> tuple[float, float, float]:
        return self.value, self.ci_low, self.ci_high

    @classmethod
    def of(cls, value: float, ci_low: float = math.nan, ci_high: float = math.nan,
           words: str = "") -> Estimate:
        """A value with its interval (NaN: none to be had); not resolved where it is NaN."""
        if math.isnan(value):
            return cls(math.nan, math.nan, math.nan, EstimateStatus.NOT_RESOLVED,
                       words or "not resolved")
        return cls(value, ci_low, ci_high, EstimateStatus.ESTIMATED, words or "estimated")


@dataclass(frozen=True)
class Reported:
    """An estimate as a table lists it: whose (``subject``; ``all``: the across-subject
    mean), of which task, what it measures (``measure``, in ``unit``), from how many trials."""

    task: str
    subject: str
    measure: str
    unit: str
    trials: int
    estimate: Estimate


@runtime_checkable
class Findings(Protocol):
    """What one paradigm's counted rows show: its estimates, its words, tables and figures.

    Attributes
    ----------
    paradigm : str
        Whose (its room's name).
    trials : int
        The counted trials analysed (main trials with status ok).
    estimates : tuple of Reported
        Every estimate it reports, each with its status.
    """

    @property
    def paradigm(self) -> str: ...

    @property
    def trials(self) -> int: ...

    @property
    def estimates(self) -> tuple[Reported, ...]: ...

    def counted(self) -> str:
        """Its trials as the summary's first line counts them (``26 localisation trials``)."""
        ...

    def methods(self) -> list[str]:
        """Its lines of the summary's Methods section (bullets; none: nothing to add)."""
        ...

    def sections(self) -> list[str]:
        """Its sections of ``summary.md`` (Markdown lines)."""
        ...

    def lines(self) -> list[str]:
        """What ``pinarray analyse`` prints of it."""
        ...

    def tables(self, out: Path) -> list[Path]:
        """Its CSV tables (and their sidecars), written into ``out``."""
        ...

    def figures(self, out: Path) -> list[Path]:
        """Its figures, PNG and PDF, written into ``out`` (matplotlib, headless)."""
        ...

    def captions(self) -> dict[str, str]:
        """Each figure's caption, by the figure file's stem."""
        ...


@dataclass(frozen=True)
class Context:
    """What an analysis is given beside a paradigm's rows: the runs that count, the interval
    settings, the grid, and the pins a subject could name (None: every pin of the grid)."""

    runs: RunSelection
    settings: IntervalSettings
    grid: Grid
    answer_pins: tuple[int, ...] | None = None


@runtime_checkable
class Answerer(Protocol):
    """A simulated subject of a fixed design: who it is is drawn once, from its seed, when it
    is made; each answer is drawn from ``rng``, which the seam sets before every trial
    (`trial_answers`), so that an answer depends on the seed and the trial alone."""

    rng: Any  # numpy.random.Generator (numpy is not imported to read a protocol)

    def __call__(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``."""
        ...


def trial_answers(subject: Answerer, seed: int | None) -> Callable[[int, Condition], str]:
    """``subject``'s answer to each trial, drawn from a generator of the trial's own, made from
    ``seed`` and the trial's number: a run killed and resumed gets the same answers as one
    that ran through with the same seed, whatever was presented again (None: a seed drawn
    once, so a subject answers at random but alike to a trial asked twice)."""
    import numpy as np

    base = seed if seed is not None else int(np.random.SeedSequence().generate_state(1)[0])

    def answer(trial: int, condition: Condition) -> str:
        subject.rng = np.random.default_rng((base, trial))
        return subject(condition)

    return answer


@runtime_checkable
class ParadigmAnalysis(Protocol):
    """What a paradigm is to the analysis: its simulated subject and its findings."""

    name: str

    def findings(self, trials: Sequence[LoadedTrial], context: Context) -> Findings:
        """What its counted ``trials`` (its rows, each with its run) show."""
        ...

    def observer(self, protocol: PinProtocol, model: str, seed: int | None) -> Answerer:
        """A simulated subject answering a fixed design of it: ``model`` is ``default`` or
        ``name=value`` overrides (a `PinArrayError` naming a key it does not know)."""
        ...

    def session_lines(self, records: Sequence[TrialRecord]) -> list[str]:
        """One sitting's numbers, short lines for the end-of-session screen (its counted
        rows; none: nothing to say)."""
        ...

    def power(self, protocol: PinProtocol, model: str) -> PowerModel | None:
        """Simulated studies of a fixed design of it for ``pinarray power`` (subjects of the
        ``--observer`` model and the findings they may show); None: it has none."""
        ...


class AnalysisDefaults:
    """What a paradigm's analysis need not say: its simulated subject from the room's
    ``observer`` module (its function ``observer``, imported when first asked for), its
    sitting's right answers, no power."""

    def observer(self, protocol: PinProtocol, model: str, seed: int | None) -> Answerer:
        package = type(self).__module__.rpartition(".")[0]
        observer: Callable[[PinProtocol, str, int | None], Answerer] = \
            importlib.import_module(f"{package}.observer").observer
        return observer(protocol, model, seed)

    def session_lines(self, records: Sequence[TrialRecord]) -> list[str]:
        return correct_lines(records)

    def power(self, protocol: PinProtocol, model: str) -> PowerModel | None:
        return None


def correct_lines(records: Sequence[TrialRecord]) -> list[str]:
    """The counted rows' right answers, of those that have one (a row's ``correct``)."""
    judged = [c for c in (getattr(r, "correct", None) for r in records if r.counts)
              if c is not None]
    if not judged:
        return []
    return [f"correct {sum(judged)}/{len(judged)} ({100 * sum(judged) / len(judged):.1f} %)"]


def observer_of(name: str) -> Callable[[PinProtocol, str, int | None], Answerer]:
    """How the paradigm called ``name`` makes its simulated subject (`ParadigmAnalysis.observer`).

    pinarray's own paradigms all keep `AnalysisDefaults.observer`, their room's ``observer``
    module's function: that module is imported alone, and a run answered by a simulated
    subject loads none of their analyses (tables, power, statistics). A plug-in's comes from
    its analysis."""
    if name in registry.BUILT_IN:
        package = registry.BUILT_IN[name]
        observer: Callable[[PinProtocol, str, int | None], Answerer] = \
            importlib.import_module(f"{package}.observer").observer
        return observer
    return analysis_of(name).observer


@cache  # a protocol's check is slow (typing's), and a results file asks once per row
def analysis_of(name: str) -> ParadigmAnalysis:
    """The analysis of the paradigm called ``name`` (the registry's), checked."""
    room = registry.room(name)
    analysis = getattr(room, "analysis", None)
    if not isinstance(analysis, ParadigmAnalysis):
        raise PinArrayError(f"paradigm {name!r} does not implement the paradigm seam: its room "
                            "gives no analysis (ParadigmAnalysis)")
    return analysis
