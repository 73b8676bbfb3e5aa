"""A trial's condition in the lab's words: one line, or the cells of a plan's table. Pure."""

from __future__ import annotations

from pinarray.protocol.model import (
    Condition,
    LocalisationCondition,
    MotionCondition,
    Paradigm,
)
from pinarray.protocol.paradigms import (
    IdentificationCondition,
    IntervalOrder,
    TemporalOrderCondition,
    TwoIntervalCondition,
)

# The columns a plan's table gives each paradigm's conditions (`condition_cells`).
COLUMNS = {
    Paradigm.LOCALISATION: ("pin", "frequency_hz"),
    Paradigm.APPARENT_MOTION: ("row", "direction"),
    Paradigm.IDENTIFICATION: ("pattern", "pins"),
    Paradigm.TWO_INTERVAL: ("first", "second", "interval_order"),
    Paradigm.TEMPORAL_ORDER: ("pins", "soa_ms"),
}


def _pins(pins: tuple[int, ...]) -> str:
    return " ".join(map(str, pins))


def _value(value: object) -> str:
    return f"{float(value):g}"  # type: ignore[arg-type]


def condition_cells(condition: Condition) -> tuple[str, ...]:
    """The condition's cells under its paradigm's `COLUMNS`."""
    match condition:
        case LocalisationCondition():
            return str(condition.pin), _value(condition.frequency_hz)
        case MotionCondition():
            return ("-" if condition.row is None else str(condition.row),
                    condition.direction.value)
        case IdentificationCondition():
            return condition.pattern, _pins(condition.pins)
        case TwoIntervalCondition():
            first, second = condition.values_in_order
            return _value(first), _value(second), condition.order.value
        case TemporalOrderCondition():
            return _pins(condition.pins), _value(condition.soa_ms)
    raise AssertionError(condition)


def describe_condition(condition: Condition) -> str:
    """One line: ``pin 6 at 10 Hz``, ``left wave``, ``pattern L on pins 1 5 9 13 14``,
    ``10 Hz, then 12 Hz (comparison second)``, ``pin 6, then pin 7 40 ms later``."""
    match condition:
        case LocalisationCondition():
            return f"pin {condition.pin} at {_value(condition.frequency_hz)} Hz"
        case MotionCondition():
            return f"{condition.direction} wave"
        case IdentificationCondition():
            return f"pattern {condition.pattern} on pins {_pins(condition.pins)}"
        case TwoIntervalCondition():
            first, second = condition.values_in_order
            unit = condition.parameter.unit
            where = ("second" if condition.order is IntervalOrder.STANDARD_FIRST else "first")
            return (f"{condition.parameter.quantity} {_value(first)} {unit}, then "
                    f"{_value(second)} {unit} (comparison {where})")
        case TemporalOrderCondition():
            a, b = condition.pins
            if not condition.soa_ns:
                return f"pins {a} and {b} together"
            leading, trailing = (a, b) if condition.soa_ns > 0 else (b, a)
            return f"pin {leading}, then pin {trailing} {_value(abs(condition.soa_ms))} ms later"
    raise AssertionError(condition)
