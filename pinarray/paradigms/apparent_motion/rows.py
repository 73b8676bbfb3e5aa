"""Apparent motion's rows: the wave's row and direction, the answer, whether motion was felt.

Its files keep the columns of the releases before the paradigm seam (`LEGACY_LAYOUT`): ``row``,
``direction``, ``perceived_motion`` and ``direction_correct`` are its own; the last two follow
from the answer and the wave, and are checked against them when read back.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from pinarray.errors import ResultsError
from pinarray.grid import Grid
from pinarray.journal.columns import Cell, Column
from pinarray.journal.manifest import PlanEntry, RunManifest
from pinarray.journal.records import (
    LEGACY_EVENT_LAYOUT,
    LEGACY_LAYOUT,
    TrialFields,
    TrialRecord,
    required,
)
from pinarray.journal.seam import RowsDefaults, row_levels
from pinarray.paradigms.apparent_motion.design import (
    MotionAnswer,
    MotionCondition,
    answered_directions,
    is_motion_answer,
)
from pinarray.protocol.model import DIRECTION_OF_WAVE, Condition, Direction, WaveKind

DIRECTION_MEANING = {
    Direction.LEFT: "wave travels leftwards",
    Direction.RIGHT: "wave travels rightwards",
    Direction.UP: "wave travels up a column",
    Direction.DOWN: "wave travels down a column",
    Direction.NONE: "no wave: the central pin alternates with the lateral ones",
}
ANSWER_MEANING = {
    MotionAnswer.NONE: "felt no moving dot", MotionAnswer.LEFT: "a dot moving leftwards",
    MotionAnswer.RIGHT: "a dot moving rightwards", MotionAnswer("up"): "a dot moving upwards",
    MotionAnswer("down"): "a dot moving downwards",
    MotionAnswer.UNSURE: "a moving dot, direction not named",
}
COLUMNS = (
    Column("row", Cell.INTEGER, "Grid row the apparent-motion wave runs along (1 = bottom row); "
           "n/a for localisation trials and for waves not along a row (up or down a column, or "
           "along a sequence of pins).", levels_for=row_levels),
    Column("direction", Cell.TEXT, "Direction of the stimulated wave, as the subject would name "
           "it: left or right (a row), up or down (a column), a direction a sequence of pins "
           "declares, or none (no wave); n/a for localisation trials.",
           levels=DIRECTION_MEANING),
    Column("perceived_motion", Cell.BOOLEAN, "Whether the subject felt a moving dot.",
           levels={"true": "felt motion", "false": "felt no motion"}),
    Column("direction_correct", Cell.BOOLEAN, "Whether the named direction matches the wave's; "
           "n/a when no motion was felt or there was no wave.",
           levels={"true": "named the wave's direction", "false": "did not"}),
)


def _coerce_name(record: object, name: str, kind: type[str], where: str) -> None:
    """A direction or motion answer: lowercase words joined by hyphens (left, up-right...)."""
    value = getattr(record, name)
    if value is None:
        return
    if not isinstance(value, str) or not is_motion_answer(value):
        raise ResultsError(f"{where}: {name} must be a direction's name (lowercase words joined "
                           f"by hyphens, e.g. left, up-right), none or unsure, found {value!r}")
    object.__setattr__(record, name, kind(value))


@dataclass(frozen=True, kw_only=True)
class MotionRecord(TrialRecord):
    """An apparent-motion trial: a wave going ``direction`` (or no wave), along ``row`` or,
    with ``row`` None, up or down a column or along a sequence of pins; the subject's
    ``response`` (a direction, none or unsure; None when the trial got no answer)."""

    paradigm: ClassVar[str] = "apparent_motion"
    row: int | None
    direction: Direction
    response: MotionAnswer | None = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"trial {self.trial}"
        _coerce_name(self, "direction", Direction, where)
        _coerce_name(self, "response", MotionAnswer, where)

    @property
    def perceived_motion(self) -> bool | None:
        """Whether a moving dot was felt; None when the trial got no answer."""
        return None if self.response is None else self.response != MotionAnswer.NONE

    @property
    def direction_correct(self) -> bool | None:
        """Whether the direction named is the wave's; None without a felt wave to name."""
        if not self.perceived_motion or self.direction == Direction.NONE:
            return None
        return self.response.value == self.direction.value if self.response else None


def entry_direction(entry: PlanEntry) -> Direction:
    """The direction a plan entry's wave goes, as a subject names it ("direction" holds the
    wave's kind; a wave not along a row says where it goes in "towards")."""
    if entry["row"] is not None:
        return DIRECTION_OF_WAVE[WaveKind(entry["direction"])]
    return Direction(str(entry["towards"]))


def direction_meaning(direction: Direction) -> str:
    """A direction column's level: the fixed ones, or a direction a sequence of pins declares."""
    return DIRECTION_MEANING.get(direction, f"wave travels {direction} along a sequence of pins")


def answer_meaning(answer: str) -> str:
    """A response level: the usual answers' words, or a direction a sequence names."""
    return ANSWER_MEANING.get(MotionAnswer(answer), f"a dot moving {answer}")


class ApparentMotionRows(RowsDefaults):
    """Apparent motion's rows (`pinarray.journal.seam.ParadigmRows`)."""

    name = "apparent_motion"
    record_type = MotionRecord
    columns = COLUMNS
    layout = LEGACY_LAYOUT
    event_layout = LEGACY_EVENT_LAYOUT
    marker = "direction"
    instructions = ("Rest your fingertip on the pins. After each stimulus, say whether you felt "
                    "a dot moving and, if so, which way it went (left, right, up, down: the "
                    "directions the experimenter named), or unsure; say 'none' if you felt no "
                    "movement.")

    def cells(self, record: TrialRecord) -> dict[str, Any]:
        assert isinstance(record, MotionRecord)
        return {"row": record.row, "direction": record.direction, "response": record.response,
                "perceived_motion": record.perceived_motion,
                "direction_correct": record.direction_correct}

    def record(self, fields: TrialFields, values: Mapping[str, Any], where: str) -> TrialRecord:
        return MotionRecord(**fields, row=values.get("row"),
                            direction=required(dict(values), "direction", where),
                            response=values.get("response"))

    def row(self, condition: Condition, fields: TrialFields, response: str | None,
            pins: tuple[int, ...], grid: Grid) -> TrialRecord:
        assert isinstance(condition, MotionCondition)
        return MotionRecord(**fields, row=condition.row, direction=condition.direction,
                            response=None if response is None else MotionAnswer(response))

    def trial_type(self, record: TrialRecord) -> str:
        assert isinstance(record, MotionRecord)
        return f"{record.task}_{record.direction.value}"

    def trial_types(self, task: str, plan: Sequence[PlanEntry]) -> dict[str, str]:
        levels: dict[str, str] = {}
        for entry in plan:
            direction = entry_direction(entry)
            levels.setdefault(f"{task}_{direction.value}", f"apparent motion: {direction.value} "
                                                          f"({direction_meaning(direction)})")
        return dict(sorted(levels.items()))

    def _offered(self, manifest: RunManifest) -> list[MotionAnswer]:
        directions = [entry_direction(e) for e in manifest.plan]
        return [*map(MotionAnswer, answered_directions(directions)), MotionAnswer.NONE,
                MotionAnswer.UNSURE]

    def levels(self, manifest: RunManifest) -> dict[str, dict[str, str]]:
        directions = [entry_direction(e) for e in manifest.plan]
        return {"response": {str(a): answer_meaning(a) for a in self._offered(manifest)},
                "direction": {str(d): direction_meaning(d) for d in dict.fromkeys(directions)}}

    def offered(self, manifest: RunManifest) -> tuple[str, ...] | None:
        # The design's directions are not in the manifest, and its plan may not draw every
        # wave the design offers an answer for: the plan's directions, the usual four words,
        # none and unsure are what a row may say.
        usual = (Direction.LEFT, Direction.RIGHT, Direction.UP, Direction.DOWN)
        return tuple(dict.fromkeys([*map(str, usual), *map(str, self._offered(manifest))]))

    def check_entry(self, entry: PlanEntry) -> None:
        kind = WaveKind(entry["direction"])
        if entry["row"] is not None:
            if isinstance(entry["row"], bool):
                raise TypeError("a row is a number")
            int(entry["row"])
            return
        towards = str(entry["towards"])
        if not is_motion_answer(towards):
            raise ValueError(towards)
        del kind
        tuple(int(p) for p in entry["pins"])

    def check_row(self, record: TrialRecord, entry: PlanEntry,
                  manifest: RunManifest) -> str | None:
        assert isinstance(record, MotionRecord)
        direction = entry_direction(entry)
        if record.direction != direction:
            return f"the plan's wave goes {direction}, the row says {record.direction}"
        if record.row != entry["row"]:
            return f"the plan's wave runs along row {entry['row']}, the row says {record.row}"
        return None

    def live_lines(self, counted: Sequence[TrialRecord]) -> list[str]:
        waves = [r for r in counted
                 if isinstance(r, MotionRecord) and r.direction != Direction.NONE]
        named = [r for r in waves if r.direction_correct is not None]
        return [f"motion felt {sum(1 for r in waves if r.perceived_motion)}/{len(waves)} wave "
                "trials",
                f"direction right {sum(1 for r in named if r.direction_correct)}/{len(named)}"]

    def last_line(self, record: TrialRecord) -> str:
        assert isinstance(record, MotionRecord)
        return f", {record.direction} wave → {record.response}"


ROWS = ApparentMotionRows()
