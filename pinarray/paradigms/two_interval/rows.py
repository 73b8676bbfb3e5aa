"""Two intervals' rows: the compared parameter, the standard and the comparison, their order.

Its files keep the columns of the releases before the paradigm seam (`LEGACY_LAYOUT`):
``compared_parameter``, ``standard``, ``comparison`` and ``interval_order`` are its own; it
fills ``pins`` (the stimulus's) and ``correct`` (the interval with the higher value named),
which follows from them and is checked when read back, as they are against the run's plan (an
adaptive design's comparison is its intensity).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, ClassVar

from pinarray.errors import ResultsError
from pinarray.grid import Grid
from pinarray.journal.columns import Cell, Column, number_text, pins_cell, pins_text
from pinarray.journal.manifest import PlanEntry, RunManifest
from pinarray.journal.records import (
    LEGACY_EVENT_LAYOUT,
    LEGACY_LAYOUT,
    TrialFields,
    TrialRecord,
    check_pins,
    coerce,
    required,
)
from pinarray.journal.seam import RowsDefaults
from pinarray.paradigms.two_interval.design import (
    FIRST,
    SECOND,
    IntervalOrder,
    TwoIntervalCondition,
)
from pinarray.protocol.model import Condition

COLUMNS = (
    Column("compared_parameter", Cell.TEXT, "Two intervals: the parameter the intervals differ "
           "in, with its unit as the protocol names it (frequency_hz, duration_ms, soa_ms); n/a "
           "for the other paradigms."),
    Column("standard", Cell.NUMBER, "Two intervals: the standard's value, in the unit "
           "compared_parameter names."),
    Column("comparison", Cell.NUMBER, "Two intervals: the comparison's value, in the unit "
           "compared_parameter names (an adaptive design's: its intensity)."),
    Column("interval_order", Cell.TEXT, "Two intervals: which interval held the standard.",
           levels={IntervalOrder.STANDARD_FIRST: "the standard in the first interval, the "
                                                 "comparison in the second",
                   IntervalOrder.COMPARISON_FIRST: "the comparison in the first interval, the "
                                                   "standard in the second"}),
)


@dataclass(frozen=True, kw_only=True)
class TwoIntervalRecord(TrialRecord):
    """A two-interval trial: ``compared`` (``frequency_hz``...) at ``standard`` and at
    ``comparison`` in ``interval_order``, on ``pins``; the subject's ``response`` names the
    interval that had more of it, ``first`` or ``second`` (None when the trial got no
    answer)."""

    paradigm: ClassVar[str] = "two_interval"
    compared: str
    standard: float
    comparison: float
    interval_order: IntervalOrder
    pins: tuple[int, ...]
    response: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        coerce(self, "interval_order", IntervalOrder, where)
        check_pins(self.pins, where)
        if self.response not in (None, FIRST, SECOND):
            raise ResultsError(f"{where}: a two-interval response must be {FIRST} or {SECOND}, "
                               f"found {self.response!r}")

    @property
    def comparison_first(self) -> bool:
        """Whether the comparison played in the first interval."""
        return self.interval_order is IntervalOrder.COMPARISON_FIRST

    @property
    def chose_comparison(self) -> bool | None:
        """Whether the interval named is the comparison's; None without an answer."""
        if self.response is None:
            return None
        return (self.response == FIRST) == self.comparison_first

    @property
    def correct(self) -> bool | None:
        """Whether the interval named had the higher value."""
        chose = self.chose_comparison
        return None if chose is None else chose == (self.comparison > self.standard)


def _label(task: str, compared: str, comparison: float) -> str:
    return f"{task}_{number_text(comparison)}{compared.rpartition('_')[2]}"


class TwoIntervalRows(RowsDefaults):
    """Two intervals' rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "two_interval"
    sidecar_needs = ("compared_parameter", "standard", "comparison")
    record_type = TwoIntervalRecord
    columns = COLUMNS
    layout = LEGACY_LAYOUT
    event_layout = LEGACY_EVENT_LAYOUT
    marker = "interval_order"
    instructions = ("Rest your fingertip on the pins. Each trial plays two intervals; say which "
                    "one, first or second, had more of what you were asked.")

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, TwoIntervalRecord)
        return {"compared_parameter": record.compared, "standard": record.standard,
                "comparison": record.comparison, "interval_order": record.interval_order,
                "pins": pins_text(record.pins), "response": record.response,
                "correct": record.correct}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        cells = dict(values)
        return TwoIntervalRecord(
            **fields, compared=required(cells, "compared_parameter", where),
            standard=required(cells, "standard", where),
            comparison=required(cells, "comparison", where),
            interval_order=values["interval_order"],
            pins=pins_cell(required(cells, "pins", where), where),
            response=values.get("response"))

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, TwoIntervalCondition)
        return TwoIntervalRecord(
            **fields, compared=condition.parameter.value, standard=float(condition.standard),
            comparison=float(condition.comparison), interval_order=condition.order,
            pins=pins, response=response)

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, TwoIntervalRecord)
        return _label(record.task, record.compared, record.comparison)

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        levels: dict[str, str] = {}
        for entry in plan:
            compared = str(entry["compare"])
            comparison = float(Fraction(str(entry["comparison"])))
            standard = float(Fraction(str(entry["standard"])))
            levels.setdefault(_label(task, compared, comparison),
                              f"two intervals: {compared} {number_text(comparison)} against "
                              f"the standard {number_text(standard)}")
        return dict(sorted(levels.items()))

    def check_entry(self, entry: PlanEntry) -> None:
        str(entry["compare"])
        Fraction(str(entry["standard"]))
        Fraction(str(entry["comparison"]))
        IntervalOrder(entry["interval_order"])

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, TwoIntervalRecord)
        standard = float(Fraction(str(entry["standard"])))
        if record.compared != entry["compare"] or record.standard != standard:
            return (f"the plan compares {entry['compare']} against {number_text(standard)}, "
                    f"the row {record.compared} against {number_text(record.standard)}")
        if record.interval_order != entry["interval_order"]:
            return (f"the plan's order is {entry['interval_order']}, the row says "
                    f"{record.interval_order}")
        adaptive = record.adaptive
        comparison = (float(Fraction(str(entry["comparison"]))) if adaptive is None
                      else adaptive.intensity)
        if comparison is not None and record.comparison != comparison:
            return (f"the trial presents the comparison {number_text(comparison)}, the row "
                    f"says {number_text(record.comparison)}")
        return None

    def check_together(self, records: Sequence[TrialRecord]) -> tuple[int, str] | None:
        # The design plays one stimulus, so every trial moves the same pins; the plan does
        # not list them (its entries are the same since 0.3): the pins most rows hold are
        # the run's, and a row that says others was edited.
        pins = Counter(r.pins for r in records if isinstance(r, TwoIntervalRecord))
        if len(pins) < 2:
            return None
        (common, _), = pins.most_common(1)
        for index, record in enumerate(records):
            if isinstance(record, TwoIntervalRecord) and record.pins != common:
                return index, (f"the run's other trials play pins {pins_text(common)}, the row "
                               f"says {pins_text(record.pins)}")
        return None


ROWS = TwoIntervalRows()
