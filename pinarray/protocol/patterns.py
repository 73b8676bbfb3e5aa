"""Pattern stimuli: pins raised together, by number or drawn, and patterns in time (frames).

    stimuli:
      tap: {frequency_hz: 5, duration_s: 1}
      bottom_row:
        pattern: [1, 2, 3, 4]         # the pins raised, by number
        train: tap                    # every raised pin moves with it
      letter_L:
        pattern: |                    # drawn as the subject feels the array: the top row
          # . . .                     # first (13 14 15 16), the bottom row last (1 2 3 4);
          # . . .                     # '#', 'x', 'o' or '1' a raised pin, '.', '-' or '0'
          # . . .                     # one at rest, spaces between cells optional
          # # # #
        train: tap
        phase_deg: 90                 # optional: every raised pin at this phase of the train
      sweep:
        frames: [bottom_row, letter_L]  # patterns in time: frame i starts at i x soa_ms
        soa_ms: 500

Each pattern is checked as it would play: every raised pin can follow the train, no pin is
driven twice at once (frames), and the servo bus carries the frames of goal changes of all
its pins together (`pinarray.protocol.bus`). Pure Python, like the rest of the protocol.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from functools import partial

from yaml import Mark, ScalarNode

from pinarray.grid import Grid
from pinarray.protocol.device import MS, read_pin, whole_ns
from pinarray.protocol.model import (
    Device,
    Frames,
    Pattern,
    PatternStimulus,
    Stimulus,
    Train,
    TrainStimulus,
)
from pinarray.protocol.stimuli import check_drives, stimulus_kind, stimulus_named
from pinarray.protocol.yaml_nodes import Invalid, Node, Reader, shown

PATTERN_KEYS = {"pattern", "train", "phase_deg"}
FRAMES_KEYS = {"frames", "soa_ms"}
RAISED = frozenset("#Xx*oO1●■")
AT_REST = frozenset(".-_0○□")
MAX_FRAMES = 64


def read_patterns(reader: Reader, nodes: Mapping[str, Node], device: Device | None,
                  trains: Mapping[str, Stimulus],
                  declared_trains: Mapping[str, Node]) -> list[PatternStimulus]:
    """Every pattern and frames stimulus of ``nodes`` (the stimuli section's, by name)."""
    patterns: dict[str, Stimulus] = {}
    for name, node in nodes.items():
        if stimulus_kind(node) is PatternStimulus and not _is_frames(node):
            pattern = reader.attempt(
                partial(read_pattern, reader, node, device, trains, declared_trains), None)
            if pattern is not None:
                patterns[name] = PatternStimulus(name, pattern)
    declared = {name: node for name, node in nodes.items()
                if stimulus_kind(node) is PatternStimulus and not _is_frames(node)}
    found = list(patterns.values())
    for name, node in nodes.items():
        if stimulus_kind(node) is PatternStimulus and _is_frames(node):
            frames = reader.attempt(partial(read_frames, reader, node, device, patterns, declared),
                                    None)
            if frames is not None:
                found.append(PatternStimulus(name, frames))
    return [s for s in found if isinstance(s, PatternStimulus)]


def _is_frames(node: Node) -> bool:
    return isinstance(node.value, list) and any(
        getattr(pair[0], "value", None) == "frames" for pair in node.value)


def read_pattern(reader: Reader, node: Node, device: Device | None, trains: Mapping[str, Stimulus],
             declared_trains: Mapping[str, Node]) -> Pattern:
    keys = reader.mapping(node, PATTERN_KEYS, {"pattern", "train"}, "pattern")
    grid = device.grid if device is not None else Grid()
    with reader.section():
        no_pins: tuple[int, ...] = ()
        pins = reader.attempt(partial(pattern_pins, reader, keys["pattern"], grid), no_pins)
        stimulus = reader.attempt(
            partial(stimulus_named, reader, keys["train"], trains, declared_trains, TrainStimulus),
            None)
        phase = reader.optional(
            keys, "phase_deg",
            lambda n: reader.number(n, "the phase", "deg", minimum=0, allow_zero=True,
                                    maximum=36000), None)
    if stimulus is None:  # a train whose own problem is already reported where it is written
        raise Invalid(f"pattern on a broken train {keys['train'].value!r}")
    train = stimulus.train
    if not isinstance(train, Train):
        raise reader.error(keys["train"], f"expected a train with a frequency_hz for a pattern, "
                                          f"found train {stimulus.name!r} without one")
    if phase is not None:
        train = replace(train, phase=(phase / 360) % 1)
    pattern = Pattern(pins, train)
    if device is not None:
        check_drives(reader, keys["pattern"], pattern.drives(), device)
    return pattern


def pattern_pins(reader: Reader, node: Node, grid: Grid) -> tuple[int, ...]:
    """The pins a pattern raises, ascending: listed by number, or drawn (the module's form)."""
    if isinstance(node, ScalarNode) and isinstance(node.value, str) and "\n" in node.value:
        return _drawn(reader, node, grid)
    pins = [read_pin(reader, n, grid) for n in reader.sequence(node, "the pattern's pins")]
    repeated = sorted({p for p in pins if pins.count(p) > 1})
    if repeated:
        raise reader.error(node, f"expected each pin of a pattern once, found "
                                 f"{', '.join(map(str, repeated))} more than once")
    return tuple(sorted(pins))


def _drawn(reader: Reader, node: ScalarNode, grid: Grid) -> tuple[int, ...]:
    """The pins a drawing raises: its first line is the grid's top row, its last the bottom."""
    lines = node.value.split("\n")
    numbered = [(i, line) for i, line in enumerate(lines) if line.strip()]
    if len(numbered) != grid.rows:
        raise reader.error(node, f"expected a drawing of {grid.rows} rows (the top row first), "
                                 f"found {len(numbered)}")
    pins: list[int] = []
    for drawn_row, (index, line) in enumerate(numbered):
        cells = "".join(line.split())
        where = _line_node(reader, node, index, line)
        strangers = sorted(set(cells) - RAISED - AT_REST)
        if strangers:
            raise reader.error(where, f"expected '#' (raised) or '.' (at rest) in each cell of "
                                      f"a drawn pattern, found {shown(strangers[0])}")
        if len(cells) != grid.columns:
            raise reader.error(where, f"expected {grid.columns} cells in each row of a drawn "
                                      f"pattern, found {len(cells)} in {shown(line.strip())}")
        row = grid.rows - 1 - drawn_row
        pins.extend(grid.pin_at(row, column) for column, cell in enumerate(cells)
                    if cell in RAISED)
    if not pins:
        raise reader.error(node, "expected at least one raised pin ('#') in a drawn pattern, "
                                 "found none")
    return tuple(sorted(pins))


def _line_node(reader: Reader, node: ScalarNode, index: int, line: str) -> Node:
    """A stand-in node at line ``index`` of a literal block's text, for the error's place.

    A literal block (``|``) starts on the line after its indicator and keeps its lines as
    written; where its row's first cell is, the file's own text says.
    """
    mark = node.start_mark
    if node.style != "|":
        return node
    line_number = mark.line + 1 + index
    source = reader.text.split("\n")
    if line_number >= len(source) or source[line_number].strip() != line.strip():
        return node
    written = source[line_number]
    at = Mark(mark.name, mark.index, line_number, len(written) - len(written.lstrip()), None,
              None)
    return ScalarNode(node.tag, line, start_mark=at, end_mark=at)


def read_frames(reader: Reader, node: Node, device: Device | None,
            patterns: Mapping[str, Stimulus], declared: Mapping[str, Node]) -> Frames:
    keys = reader.mapping(node, FRAMES_KEYS, {"frames", "soa_ms"}, "frames")
    items = reader.sequence(keys["frames"], "the frames", 2)
    if len(items) > MAX_FRAMES:
        raise reader.error(keys["frames"], f"expected at most {MAX_FRAMES} frames, found "
                                           f"{len(items)}")
    with reader.section():
        named = [reader.attempt(partial(stimulus_named, reader, item, patterns, declared,
                                        PatternStimulus), None) for item in items]
        soa = reader.attempt(lambda: whole_ns(
            reader, keys["soa_ms"], reader.number(keys["soa_ms"], "the frames' SOA", "ms",
                                                  maximum=60_000), MS, "the frames' SOA", "ms"),
            0)
    frames: list[tuple[str, Pattern]] = []
    for stimulus in named:
        if stimulus is None:  # a pattern whose own problem is already reported
            raise Invalid("frames of a broken pattern")
        assert isinstance(stimulus.shape, Pattern)  # a pattern's name: stimulus_named saw it
        frames.append((stimulus.name, stimulus.shape))
    shape = Frames(tuple(frames), soa)
    if device is not None:
        check_drives(reader, keys["soa_ms"], shape.drives(), device)
    return shape
