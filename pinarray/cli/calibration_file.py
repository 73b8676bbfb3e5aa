"""A pin's new calibration written into its protocol file, keeping every comment and the layout.

A YAML library that loads and dumps a file loses its comments, its key order and its number
spellings (PyYAML does; ruamel.yaml keeps most, at the price of a dependency). A protocol is
the lab's document, so the file is edited as text instead: the parser reports where each
node starts and ends (`pinarray.protocol.yaml_tree` keeps libyaml's marks), and only the
characters of the values that change are replaced (``rest_steps``, each ``positions`` value,
``limits_steps`` if the new positions need wider limits; ``rest_us`` and ``limits_us`` on a PWM
board, whose positions are pulse widths). A key the pin does not have yet is
added after the pin's last entry, in the style of its mapping (flow ``{...}`` or block), and a
pin with no entry gets one under ``device: pins:``. Line ends (LF, CRLF, CR), the byte-order
mark and the encoding stay as they were.

The edited text is then read as a protocol again and must give exactly the intended
calibration for the pin and nothing else changed; only then are its bytes returned.

A little over 400 lines, in three parts (the new numbers, where to edit, the check) kept in
one file because each relies on the others' rules.
"""

from __future__ import annotations

import bisect
import codecs
from collections.abc import Iterator
from dataclasses import dataclass
from decimal import Decimal
from typing import NamedTuple

from yaml import MappingNode, Node, ScalarNode, SequenceNode

from pinarray.errors import PinArrayError, ProtocolError, ProtocolErrors
from pinarray.protocol import PinCalibration, Protocol
from pinarray.protocol.device import STEPS, WIDTH_US, read_width_ns
from pinarray.protocol.load import parse_protocol
from pinarray.protocol.yaml_nodes import Invalid, Reader
from pinarray.protocol.yaml_tree import compose_tree
from pinarray.text_files import decode_text
from pinarray.units import NS_PER_MS

# Each family's positions and their range: STS encoder steps, PWM pulse widths in us.
_UNITS = {unit.suffix: unit for unit in (STEPS, WIDTH_US)}
# Longest first: a UTF-32 LE mark begins with the UTF-16 LE one.
_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32-le"), (codecs.BOM_UTF32_BE, "utf-32-be"),
    (codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be"),
)


@dataclass(frozen=True)
class NewCalibration:
    """What calibrating one pin decided, in its family's unit (steps, or us of pulse width).

    Attributes
    ----------
    pin : int
        The pin, 1-based.
    rest_steps : int
        Where the pin waits.
    positions : tuple of (width_ns, steps)
        The pin's pulse-width map: the narrowest width at rest, the widest "up", the ones in
        between where they were relative to those two.
    limits_steps : (int, int)
        The pin's stroke limits: as before, or widened just enough to hold the new positions.
    limits_widened : bool
        Whether the limits had to change (then they are written to the pin's own entry).
    unit : str
        ``steps`` or ``us``: the keys' suffix (``rest_steps``, ``limits_us``).
    """

    pin: int
    rest_steps: int
    positions: tuple[tuple[int, int], ...]
    limits_steps: tuple[int, int]
    limits_widened: bool
    unit: str

    @property
    def up_steps(self) -> int:
        return self.positions[-1][1]

    def calibration(self, old: PinCalibration) -> PinCalibration:
        """``old`` with these values: what the protocol must read back."""
        low, high = self.limits_steps
        return PinCalibration(old.pin, old.servo_id, self.rest_steps, low, high,
                              self.positions, old.lever_mm)


def new_calibration(old: PinCalibration, rest_steps: int, up_steps: int,
                    limits_given: bool = True, unit: str = STEPS.suffix) -> NewCalibration:
    """The pin's calibration with rest and "up" where they were found.

    The narrowest pulse width maps to ``rest_steps`` and the widest to ``up_steps``; widths in
    between keep their place between the two (linearly, rounded to a step). Limits the file
    gives (``limits_given``) are kept, or widened just enough to hold the new positions;
    without them a pin's limits are its positions' span, so they follow the new positions.
    ``unit``: ``steps`` (STS servos) or ``us`` (pulse widths on a PWM board).
    """
    bounds = _UNITS[unit]
    for name, value in (("rest", rest_steps), ("up", up_steps)):
        if not bounds.low <= value <= bounds.high:
            raise PinArrayError(f"pin {old.pin}: {name} position {value} {unit} is outside "
                                f"{bounds.low}..{bounds.high}")
    if rest_steps == up_steps:
        raise PinArrayError(f"pin {old.pin}: rest and up are both {rest_steps} {unit}; the pin "
                            "would not move")
    by_width = sorted(old.positions_by_width_ns)
    if len(by_width) < 2:
        raise PinArrayError(f"pin {old.pin}: its calibration has one pulse width; calibrating "
                            "needs a rest (narrowest) and an up (widest) width")
    (first_width, first), (last_width, last) = by_width[0], by_width[-1]
    positions = []
    for width, steps in by_width:
        if last != first:
            share = (steps - first) / (last - first)
        else:
            share = (width - first_width) / (last_width - first_width)
        positions.append((width, round(rest_steps + share * (up_steps - rest_steps))))
    positions[0], positions[-1] = (first_width, rest_steps), (last_width, up_steps)
    span = [rest_steps, *(p for _, p in positions)]
    if not limits_given:
        return NewCalibration(old.pin, rest_steps, tuple(positions), (min(span), max(span)),
                              False, unit)
    low, high = min(old.min_steps, *span), max(old.max_steps, *span)
    widened = (low, high) != (old.min_steps, old.max_steps)
    return NewCalibration(old.pin, rest_steps, tuple(positions), (low, high), widened, unit)


def plan_calibration(data: bytes, protocol: Protocol, pin: int, rest_steps: int,
                     up_steps: int) -> NewCalibration:
    """`new_calibration` of ``pin`` in the protocol file ``data`` (which says if it gives limits)."""
    root = compose_tree(decode_text(data))
    reader = Reader(protocol.source)
    device = _value(reader, root, "device") if isinstance(root, MappingNode) else None
    shared = None if device is None else _value(reader, device, "calibration")
    pins = None if device is None else _value(reader, device, "pins")
    own = None if pins is None else _pin_value(reader, pins, pin)
    unit = protocol.device.servo.position_unit
    given = any(node is not None and _value(reader, node, f"limits_{unit}") is not None
                for node in (shared, own))
    return new_calibration(protocol.device.calibration(pin), rest_steps, up_steps, given, unit)


class Edit(NamedTuple):
    """Replace the characters ``start:end`` of the (``\\n``-ended) text with ``text``."""

    start: int
    end: int
    text: str


def rewrite_calibration(data: bytes, protocol: Protocol, new: NewCalibration) -> bytes:
    """The protocol file's bytes with ``new`` written in, checked by reading them back.

    Parameters
    ----------
    data : bytes
        The file as read (it must be the text ``protocol`` was loaded from).
    protocol : Protocol
        The file as loaded: the calibration the other pins must keep.
    new : NewCalibration
        The pin's new values.

    Raises
    ------
    ProtocolError
        The pin's calibration cannot be edited in place (written through a YAML alias).
    PinArrayError
        The edited protocol would not be valid (e.g. a stimulus the new stroke cannot
        follow); nothing is to be written then.
    """
    bom, encoding = _encoding(data)
    raw = data[len(bom):].decode(encoding)
    text = decode_text(data)
    edits = plan_edits(text, protocol, new)
    edited = bom + _apply(raw, edits).encode(encoding)
    _check(edited, protocol, new)
    return edited


def _encoding(data: bytes) -> tuple[bytes, str]:
    for bom, name in _BOMS:
        if data.startswith(bom):
            return bom, name
    return b"", "utf-8"


def _newline(raw: str) -> str:
    for index, char in enumerate(raw):
        if char == "\r":
            return "\r\n" if raw[index + 1:index + 2] == "\n" else "\r"
        if char == "\n":
            return "\n"
    return "\n"


def _apply(raw: str, edits: list[Edit]) -> str:
    """``edits`` (positions in the ``\\n``-ended text) made on ``raw``, whose line ends may be
    CRLF or CR; new lines get the file's first kind of line end."""
    newline = _newline(raw)
    # Where each CRLF of `raw` sits in the text with `\n` line ends: every later position
    # is one character further along in `raw`.
    crlf_at, removed, index = [], 0, raw.find("\r\n")
    while index >= 0:
        crlf_at.append(index - removed)
        removed += 1
        index = raw.find("\r\n", index + 2)

    def at(position: int) -> int:
        return position + bisect.bisect_left(crlf_at, position)

    out, done = [], 0
    for edit in sorted(edits):
        start, end = at(edit.start), at(edit.end)
        out += [raw[done:start], edit.text.replace("\n", newline)]
        done = end
    out.append(raw[done:])
    return "".join(out)


# -- where to edit -----------------------------------------------------------------------------


def plan_edits(text: str, protocol: Protocol, new: NewCalibration) -> list[Edit]:
    """The edits that write ``new`` into ``text`` (``\\n`` line ends), leaving the rest."""
    root = compose_tree(text)
    reader = Reader(protocol.source)
    if not isinstance(root, MappingNode):
        raise PinArrayError(f"{protocol.source}: expected a protocol mapping")
    shared = _shared_nodes(root)
    pin = new.pin
    widths = _width_texts(reader, root)
    device = _value(reader, root, "device")
    if device is None:
        entry = _pin_entry(new, widths)
        return [_insert(text, root, "device", f"{{pins: {{{pin}: {entry}}}}}",
                        block=f"\n  pins:\n    {pin}: {entry}")]
    _refuse_shared(reader, device, shared, "the device section")
    pins = _value(reader, device, "pins")
    if pins is None:
        step = max(2, device.value[0][0].start_mark.column - root.value[0][0].start_mark.column)
        entry = _pin_entry(new, widths)
        indent = " " * (device.value[0][0].start_mark.column + step)
        return [_insert(text, device, "pins", f"{{{pin}: {entry}}}",
                        block=f"\n{indent}{pin}: {entry}")]
    _refuse_shared(reader, pins, shared, "device: pins")
    own = _pin_value(reader, pins, pin)
    if own is None:
        return [_insert(text, pins, str(pin), _pin_entry(new, widths))]
    _refuse_shared(reader, own, shared, f"pin {pin}'s calibration")
    if not isinstance(own, MappingNode):
        raise PinArrayError(f"{protocol.source}: expected a mapping for pin {pin}")
    edits = []
    missing: list[tuple[str, str]] = []
    rest_key, limits_key = f"rest_{new.unit}", f"limits_{new.unit}"
    rest = _value(reader, own, rest_key)
    if rest is None:
        missing.append((rest_key, str(new.rest_steps)))
    else:
        edits.append(_replace(rest, str(new.rest_steps)))
    positions = _value(reader, own, "positions")
    if positions is None:
        missing.append(("positions", _positions_flow(new, widths)))
    else:
        _refuse_shared(reader, positions, shared, f"pin {pin}'s positions")
        steps_by_width = dict(new.positions)
        for width_node, steps_node in _items(positions):
            width_ns = read_width_ns(reader, width_node)
            edits.append(_replace(steps_node, str(steps_by_width[width_ns])))
    if new.limits_widened:
        low, high = new.limits_steps
        limits = _value(reader, own, limits_key)
        if limits is None:
            missing.append((limits_key, f"[{low}, {high}]"))
        else:
            edits.append(_replace(limits, f"[{low}, {high}]"))
    if missing:
        edits.append(_insert_all(text, own, missing))
    return edits


def _items(node: Node) -> list[tuple[Node, Node]]:
    return list(node.value) if isinstance(node, MappingNode) else []


def _key_text(reader: Reader, node: Node) -> object:
    try:
        return reader.scalar_value(node)
    except Invalid:
        return None


def _value(reader: Reader, mapping: Node, key: str) -> Node | None:
    for key_node, value_node in _items(mapping):
        if _key_text(reader, key_node) == key:
            return value_node
    return None


def _pin_value(reader: Reader, pins: Node, pin: int) -> Node | None:
    for key_node, value_node in _items(pins):
        if _key_text(reader, key_node) == pin:
            return value_node
    return None


def _walk(node: Node) -> Iterator[Node]:
    """Every node under ``node`` as often as the tree reaches it (aliases more than once)."""
    stack = [node]
    while stack:
        current = stack.pop()
        yield current
        if isinstance(current, MappingNode):
            for key, value in current.value:
                stack += [key, value]
        elif isinstance(current, SequenceNode):
            stack += current.value


def _shared_nodes(root: Node) -> set[int]:
    """Ids of nodes an alias reaches: editing them would change every place that uses them.

    The tree is at most `MAX_DEPTH` deep with `MAX_ALIASES` aliases (`yaml_tree`), but an
    alias of an alias repeats subtrees; a node seen twice is not walked again.
    """
    seen: set[int] = set()
    shared: set[int] = set()
    stack = [root]
    while stack:
        current = stack.pop()
        if id(current) in seen:
            shared.add(id(current))
            shared.update(id(n) for n in _walk(current))
            continue
        seen.add(id(current))
        if isinstance(current, MappingNode):
            for key, value in current.value:
                stack += [key, value]
        elif isinstance(current, SequenceNode):
            stack += current.value
    return shared


def _refuse_shared(reader: Reader, node: Node, shared: set[int], what: str) -> None:
    if id(node) in shared:
        raise ProtocolError(
            f"{what} is written once and used again through a YAML alias (&name / *name); "
            "calibrating would change every place that uses it. Write it out in full first",
            reader.source, node.start_mark.line + 1, node.start_mark.column + 1)


def _replace(node: Node, text: str) -> Edit:
    return Edit(node.start_mark.index, node.end_mark.index, text)


def _last_index(node: Node) -> int:
    """Where the last character written for ``node`` ends (a block collection's end mark lies
    at the next token, which may be lines further on)."""
    while isinstance(node, MappingNode | SequenceNode) and not node.flow_style and node.value:
        last = node.value[-1]
        node = last[1] if isinstance(node, MappingNode) else last
    return node.end_mark.index


def _insert(text: str, mapping: Node, key: str, value: str, block: str | None = None) -> Edit:
    """Add ``key: value`` to ``mapping`` (see `_insert_all`); ``block``, if given, is written
    after the colon instead of `` value`` when the mapping is in block style."""
    return _insert_all(text, mapping, [(key, value)], block)


def _insert_all(text: str, mapping: Node, pairs: list[tuple[str, str]],
                block: str | None = None) -> Edit:
    """Add ``key: value`` pairs to ``mapping``: inside its braces, or on lines after its last
    entry at its keys' indentation."""
    assert isinstance(mapping, MappingNode)
    if mapping.flow_style or not mapping.value:
        added = ", ".join(f"{key}: {value}" for key, value in pairs)
        if not mapping.value:
            close = mapping.end_mark.index - 1
            assert text[close] == "}", "an empty block mapping is no valid protocol section"
            return Edit(close, close, added)
        end = _last_index(mapping.value[-1][1])
        return Edit(end, end, f", {added}")
    end = _last_index(mapping)
    line_end = text.find("\n", end)
    position = len(text) if line_end < 0 else line_end
    indent = " " * mapping.value[0][0].start_mark.column
    if block is not None:
        (key, _), = pairs
        return Edit(position, position, f"\n{indent}{key}:{block}")
    return Edit(position, position, "".join(f"\n{indent}{key}: {value}" for key, value in pairs))


# -- what to write ---------------------------------------------------------------------------


def _width_texts(reader: Reader, root: Node) -> dict[int, str]:
    """Pulse widths as the file's shared calibration spells them (``1.5``, ``2.0``)."""
    texts: dict[int, str] = {}
    device = _value(reader, root, "device")
    calibration = None if device is None else _value(reader, device, "calibration")
    positions = None if calibration is None else _value(reader, calibration, "positions")
    for width_node, _ in _items(positions) if positions is not None else []:
        if isinstance(width_node, ScalarNode):
            try:
                texts[read_width_ns(reader, width_node)] = width_node.value
            except Invalid:
                continue
    return texts


def _width_text(width_ns: int, texts: dict[int, str]) -> str:
    if width_ns in texts:
        return texts[width_ns]
    ms = Decimal(width_ns) / Decimal(NS_PER_MS)
    return f"{ms}.0" if ms == ms.to_integral_value() else str(ms.normalize())


def _positions_flow(new: NewCalibration, widths: dict[int, str]) -> str:
    pairs = ", ".join(f"{_width_text(w, widths)}: {p}" for w, p in new.positions)
    return f"{{{pairs}}}"


def _pin_entry(new: NewCalibration, widths: dict[int, str]) -> str:
    entry = f"rest_{new.unit}: {new.rest_steps}, positions: {_positions_flow(new, widths)}"
    if new.limits_widened:
        entry += f", limits_{new.unit}: [{new.limits_steps[0]}, {new.limits_steps[1]}]"
    return f"{{{entry}}}"


# -- checking the result ---------------------------------------------------------------------


def _check(edited: bytes, protocol: Protocol, new: NewCalibration) -> None:
    """``edited`` must read as ``protocol`` with the pin's calibration replaced by ``new``."""
    source = protocol.source
    try:
        reread = parse_protocol(decode_text(edited), source)
    except ProtocolErrors as problems:
        first = problems.errors[0].message
        more = f" (and {len(problems.errors) - 1} more problem(s))" if len(problems.errors) > 1 else ""
        raise PinArrayError(
            f"{source}: not written: with pin {new.pin} at rest {new.rest_steps} and up "
            f"{new.up_steps} {new.unit} the protocol would be invalid: {first}{more}") from None
    old = protocol.device
    expected = tuple(new.calibration(c) if c.pin == new.pin else c for c in old.pins)
    same = (reread.device.pins == expected and reread.name == protocol.name
            and reread.description == protocol.description
            and reread.stimuli == protocol.stimuli and reread.design == protocol.design
            and (reread.device.grid, reread.device.servo, reread.device.port,
                 reread.device.scale_infeasible, reread.device.delivery_tolerance_ns)
            == (old.grid, old.servo, old.port, old.scale_infeasible, old.delivery_tolerance_ns))
    if not same:
        raise PinArrayError(
            f"{source}: not written: editing the text did not give the calibration intended "
            f"for pin {new.pin} alone (a bug in pinarray; please report it with the file)")
