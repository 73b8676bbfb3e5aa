"""Reading YAML with positions: every value comes with the file:line:col it was written at.

`yaml.safe_load` forgets where things were; we compose the node tree instead and convert
scalars ourselves, so each problem is reported at the key or value that caused it, and all
problems of a file are collected in one pass.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import yaml

from pinarray.errors import ProtocolError, ProtocolErrors

_constructor = yaml.constructor.SafeConstructor()

Node = yaml.Node


class Invalid(Exception):
    """Raised inside a reader after an error was recorded, to skip the rest of a section."""


class Reader:
    """Collects located errors while turning YAML nodes into checked Python values."""

    def __init__(self, source: str):
        self.source = source
        self.errors: list[ProtocolError] = []

    def error(self, node: Node | None, message: str) -> Invalid:
        line = node.start_mark.line + 1 if node is not None else 0
        col = node.start_mark.column + 1 if node is not None else 0
        self.errors.append(ProtocolError(message, self.source, line, col))
        return Invalid(message)

    def raise_if_errors(self) -> None:
        if self.errors:
            self.errors.sort(key=lambda e: (e.line, e.col))
            raise ProtocolErrors(self.errors)

    def attempt(self, read: Callable[[], Any], default: Any = None) -> Any:
        """Run a reader step; on a recorded error return ``default`` and carry on."""
        try:
            return read()
        except Invalid:
            return default

    # -- structure ---------------------------------------------------------------------------

    def compose(self, text: str) -> Node:
        try:
            root = yaml.compose(text, Loader=yaml.SafeLoader)
        except yaml.MarkedYAMLError as problem:
            mark = problem.problem_mark or problem.context_mark
            what = problem.problem or problem.context or "malformed YAML"
            error = ProtocolError(
                f"malformed YAML: {what}",
                self.source,
                mark.line + 1 if mark else 0,
                mark.column + 1 if mark else 0,
            )
            raise ProtocolErrors([error]) from None
        except yaml.YAMLError as problem:
            raise ProtocolErrors(
                [ProtocolError(f"malformed YAML: {problem}", self.source)]
            ) from None
        if root is None:
            raise ProtocolErrors(
                [ProtocolError("expected a protocol, found an empty file", self.source)]
            )
        return root

    def mapping(
        self, node: Node, allowed: set[str], required: set[str] = frozenset(), what: str = "section"
    ) -> dict[str, Node]:
        """Keys of a mapping with their value nodes; unknown keys get a did-you-mean hint."""
        if not isinstance(node, yaml.MappingNode):
            raise self.error(node, f"expected a mapping for the {what}, found {describe(node)}")
        out: dict[str, Node] = {}
        suggested: set[str] = set()
        for key_node, value_node in node.value:
            key = self.scalar_value(key_node)
            key_text = str(key)
            if key_text in out:
                self.error(key_node, f"duplicate key {key_text!r} in the {what}")
                continue
            if key_text not in allowed:
                hint = difflib.get_close_matches(key_text, sorted(allowed), n=1)
                suggested.update(hint)
                suggestion = (
                    f"; did you mean {hint[0]!r}?"
                    if hint
                    else f"; expected one of {', '.join(sorted(allowed))}"
                )
                self.error(key_node, f"unknown key {key_text!r} in the {what}{suggestion}")
                continue
            out[key_text] = value_node
        missing = sorted(required - out.keys())
        for key in missing:
            if key not in suggested:  # a misspelt key was already reported with its hint
                self.error(node, f"the {what} needs a {key!r} key, found none")
        if missing:
            raise Invalid(f"missing {missing}")
        return out

    def items(self, node: Node, what: str) -> list[tuple[Node, Node]]:
        """(key node, value node) pairs of a mapping whose keys are data (names, pins)."""
        if not isinstance(node, yaml.MappingNode):
            raise self.error(node, f"expected a mapping for {what}, found {describe(node)}")
        seen: set[str] = set()
        pairs = []
        for key_node, value_node in node.value:
            key_text = str(self.scalar_value(key_node))
            if key_text in seen:
                self.error(key_node, f"duplicate key {key_text!r} in {what}")
                continue
            seen.add(key_text)
            pairs.append((key_node, value_node))
        return pairs

    def sequence(self, node: Node, what: str, min_items: int = 1) -> list[Node]:
        if not isinstance(node, yaml.SequenceNode):
            raise self.error(node, f"expected a list for {what}, found {describe(node)}")
        if len(node.value) < min_items:
            raise self.error(
                node, f"expected at least {min_items} item(s) in {what}, found {len(node.value)}"
            )
        return list(node.value)

    # -- scalars -----------------------------------------------------------------------------

    def scalar_value(self, node: Node) -> Any:
        if not isinstance(node, yaml.ScalarNode):
            raise self.error(node, f"expected a single value, found {describe(node)}")
        try:
            return _constructor.construct_object(node)
        except (yaml.YAMLError, ValueError, TypeError, OverflowError) as problem:
            # e.g. "!!python/name:os.system" (refused by the safe loader) or a date 2024-13-45
            what = getattr(problem, "problem", None) or str(problem)
            raise self.error(node, f"expected a plain value, found {node.value!r} ({what})") from None

    def string(self, node: Node, what: str, choices: tuple[str, ...] = ()) -> str:
        value = self.scalar_value(node)
        if not isinstance(value, str) or not value.strip():
            raise self.error(node, f"expected text for {what}, found {describe(node)}")
        if choices and value not in choices:
            hint = difflib.get_close_matches(value, choices, n=1)
            extra = f"; did you mean {hint[0]!r}?" if hint else ""
            raise self.error(
                node, f"expected {what} to be one of {', '.join(choices)}, found {value!r}{extra}"
            )
        return value

    def boolean(self, node: Node, what: str) -> bool:
        value = self.scalar_value(node)
        if not isinstance(value, bool):
            raise self.error(node, f"expected true or false for {what}, found {describe(node)}")
        return value

    def number(
        self,
        node: Node,
        what: str,
        unit: str,
        *,
        minimum: Fraction | int | None = 0,
        maximum: Fraction | int | None = None,
        allow_zero: bool = False,
    ) -> Fraction:
        """An exact number: 0.1 means 1/10; "1/3" is accepted; NaN and infinities are not."""
        value = self.scalar_value(node)
        exact: Fraction | None = None
        if isinstance(value, bool):
            exact = None
        elif isinstance(value, int):
            exact = Fraction(value)
        elif isinstance(value, float):
            if math.isfinite(value):
                exact = Fraction(repr(value))  # the shortest decimal that reads back: "0.1" -> 1/10
            else:
                raise self.error(
                    node, f"expected a finite number of {unit} for {what}, found {node.value}"
                )
        elif isinstance(value, str):
            try:
                exact = Fraction(value.strip())
            except (ValueError, ZeroDivisionError):
                exact = None
        if exact is None:
            raise self.error(
                node, f"expected a number of {unit} for {what}, found {describe(node)}"
            )
        if minimum is not None and (exact < minimum or (exact == minimum and not allow_zero)):
            relation = "at least" if allow_zero else "more than"
            raise self.error(
                node,
                f"expected {what} {relation} {float(minimum):g} {unit}, found {float(exact):g}",
            )
        if maximum is not None and exact > maximum:
            raise self.error(
                node,
                f"expected {what} of at most {float(maximum):g} {unit}, found {float(exact):g}",
            )
        return exact

    def integer(
        self, node: Node, what: str, minimum: int | None = None, maximum: int | None = None
    ) -> int:
        value = self.scalar_value(node)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(node, f"expected a whole number for {what}, found {describe(node)}")
        if minimum is not None and value < minimum:
            raise self.error(node, f"expected {what} of at least {minimum}, found {value}")
        if maximum is not None and value > maximum:
            raise self.error(node, f"expected {what} of at most {maximum}, found {value}")
        return value


def describe(node: Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    if node.tag.endswith(":null"):
        return "nothing"
    return repr(node.value)
