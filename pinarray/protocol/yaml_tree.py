"""YAML text -> one document's node tree, bounded in depth and aliases, without recursion.

libyaml's own composer recurses in C and crashes the interpreter on a few thousand nested
``[``; PyYAML's recurses in Python and raises `RecursionError`; both follow an alias bomb's
aliases as often as they are written and let an anchor be used inside itself. This composer
builds the same nodes (with their marks) from the parser's events in a loop, at most
`MAX_DEPTH` levels deep, following at most `MAX_ALIASES` aliases, each to a finished node.
Limits are reported as `yaml.MarkedYAMLError` at the event that passed them.
"""

from __future__ import annotations

from collections.abc import Iterator

import yaml
from yaml import MappingNode, Node, ScalarNode, SequenceNode

MAX_DEPTH = 32
MAX_ALIASES = 100
_Parser = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml's parser when installed


def compose_tree(text: str) -> Node | None:
    """The tree of the one document in ``text``; None for a file with no document."""
    try:
        return _compose(yaml.parse(text, Loader=_Parser))
    except yaml.MarkedYAMLError as problem:
        # libyaml from PyYAML 6.0.4 stops at 1000 levels of flow nesting while it looks ahead
        # for a key, before this composer has seen the 33rd: the Python parser (lazy,
        # iterative) reaches the limit here, where it is, as on every PyYAML.
        if _Parser is yaml.SafeLoader or "nesting depth" not in str(problem.problem):
            raise
        return _compose(yaml.parse(text, Loader=yaml.SafeLoader))


def _compose(events: Iterator[yaml.Event]) -> Node | None:
    """The tree of one YAML document, built without recursion (depth-checked as it goes)."""
    resolver = yaml.resolver.Resolver()
    anchors: dict[str, Node] = {}
    aliases = 0
    root: Node | None = None
    stack: list[tuple[Node, str | None, list]] = []  # (collection, its anchor, its pending key)

    def place(node: Node) -> None:
        nonlocal root
        if not stack:
            root = node
            return
        collection, _, pending = stack[-1]
        if isinstance(collection, SequenceNode):
            collection.value.append(node)
        elif pending:
            collection.value.append((pending.pop(), node))
        else:
            pending.append(node)

    for event in events:
        if isinstance(event, yaml.DocumentStartEvent) and root is not None:
            raise yaml.composer.ComposerError(
                None, None, "expected a single document, found a second one", event.start_mark)
        if isinstance(event, yaml.AliasEvent):
            aliases += 1
            if aliases > MAX_ALIASES:
                raise yaml.composer.ComposerError(
                    None, None, f"more than {MAX_ALIASES} aliases", event.start_mark)
            if event.anchor not in anchors:
                raise yaml.composer.ComposerError(
                    None, None, f"alias *{event.anchor} names no finished anchor",
                    event.start_mark)
            place(anchors[event.anchor])
        elif isinstance(event, yaml.ScalarEvent):
            tag = event.tag
            if tag is None or tag == "!":
                tag = resolver.resolve(ScalarNode, event.value, event.implicit)
            node = ScalarNode(tag, event.value, event.start_mark, event.end_mark, event.style)
            if event.anchor is not None:
                anchors[event.anchor] = node
            place(node)
        elif isinstance(event, yaml.SequenceStartEvent | yaml.MappingStartEvent):
            if len(stack) >= MAX_DEPTH:
                raise yaml.composer.ComposerError(
                    None, None, f"more than {MAX_DEPTH} levels of nesting", event.start_mark)
            kind = SequenceNode if isinstance(event, yaml.SequenceStartEvent) else MappingNode
            tag = event.tag
            if tag is None or tag == "!":
                tag = resolver.resolve(kind, None, event.implicit)
            stack.append((kind(tag, [], event.start_mark, None, event.flow_style),
                          event.anchor, []))
        elif isinstance(event, yaml.SequenceEndEvent | yaml.MappingEndEvent):
            collection, anchor, _ = stack.pop()
            collection.end_mark = event.end_mark
            # Registered once finished: an anchor used inside itself is an undefined alias.
            if anchor is not None:
                anchors[anchor] = collection
            place(collection)
    return root


