"""Reading YAML with positions: every value comes with the file:line:col it was written at.

`yaml.safe_load` forgets where things were; we keep the node tree (`yaml_tree`) and convert
scalars ourselves, so each problem is reported at the key or value that caused it, and all
problems of a file are collected in one pass.

Every cost is bounded by the size of the text, whatever it holds: the tree is bounded in
depth and aliases (`yaml_tree`), numbers are at most `MAX_NUMBER_CHARS` characters with a
decimal exponent within `MAX_EXPONENT` (``1e999999999`` would otherwise build a
billion-digit integer before any range check), and at most `MAX_PROBLEMS` problems are listed.

Past 400 lines: one job, the `Reader` and the scalar conversions it bounds; every section of a
protocol reads through it.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from fractions import Fraction
from typing import Any, NoReturn, TypeVar

import yaml
from yaml import MappingNode, Node, ScalarNode, SequenceNode

from pinarray.errors import ProtocolError, ProtocolErrors
from pinarray.protocol.yaml_tree import compose_tree

MAX_NUMBER_CHARS = 40
MAX_EXPONENT = 100
MAX_PROBLEMS = 100

T = TypeVar("T")

_YAML = "tag:yaml.org,2002:"
_PLAIN_TAGS = {f"{_YAML}{name}" for name in ("str", "int", "float", "bool", "null", "timestamp")}
_NUMBER_TAGS = {f"{_YAML}int", f"{_YAML}float"}
# The text each plain type accepts, as YAML 1.1 resolves it: an explicit ``!!bool maybe``
# must match it too, or PyYAML's constructors fail with a KeyError or an AttributeError.
_IMPLICIT: dict[str, list[re.Pattern]] = {}
for _resolvers in yaml.resolver.Resolver.yaml_implicit_resolvers.values():
    for _tag, _pattern in _resolvers:
        _IMPLICIT.setdefault(_tag, []).append(_pattern)
# Characters YAML allows in a stream (YAML 1.1, 5.1): anything else is refused where it is.
_NOT_PRINTABLE = re.compile("[^\t\n\r\x20-\x7e\x85\xa0-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")
# ASCII digits only: Python's \d and int() also read full-width and other scripts' digits.
_DECIMAL = re.compile(r"([+-]?)(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?", re.ASCII)
# YAML 1.1 also reads 0x10 as 16, 017 as 15 (octal), 0b101, 1_000 and 1:00 as 60; a protocol
# writes its numbers in decimal, as the lab (and a YAML 1.2 reader) reads them.
_NOT_DECIMAL = re.compile(r"[_:xb]|^[+-]?0[0-9]+$")
_WHOLE = re.compile(r"[+-]?\d+", re.ASCII)  # a whole number written in quotes
_RATIO = re.compile(r"([+-]?)(\d+)\s*/\s*(\d+)", re.ASCII)


# PyYAML's scanner and parser name tokens in angle brackets; a lab reads them as places.
_TOKENS = {
    "<stream end>": "the end of the file",
    "<block end>": "the end of the indented block",
    "<block mapping start>": "a new indented mapping",
    "<block sequence start>": "a new indented list",
    "<scalar>": "a value",
    "'?'": "a new key at a different indent",
    "key": "a key",
    "'-' indicator": "'-' (the next item of the list)",
}


def _found_at(text: str, index: int) -> str:
    """What a reader sees at ``index`` of ``text``, in words."""
    if index >= len(text):
        return "the end of the file"
    char = text[index]
    if char in "\r\n":
        return "the end of the line"
    if char == "\t":
        return "a tab (YAML indents with spaces)"
    return repr(char)


def _expected_found(problem: str, found: str) -> str:
    """PyYAML's description of a syntax error, said as what was expected and what was found."""
    for pattern in (r"expected (.+?), but (?:found|got) (.+)", r"(?:did|could) not find expected (.+)"):
        match = re.fullmatch(pattern, problem)
        if match:
            token = match.group(2) if match.lastindex == 2 else None
            seen = _TOKENS.get(token, token) if token else found
            return f"expected {_TOKENS.get(match.group(1), match.group(1))}, found {seen}"
    if problem.startswith("found character") or problem == "found unexpected end of stream":
        return f"expected a YAML value or the end of one, found {found}"
    if problem.startswith("mapping values are not allowed"):
        return ("expected one 'key: value' per line, found a second ':' "
                "(quote a value that holds ': ')")
    if "tab character" in problem:
        return "expected spaces to indent, found a tab (YAML indents with spaces)"
    if problem == "expected the closing quote":
        return f"{problem}, found {found}"
    if problem.startswith(("expected", "more than", "alias")):
        return problem  # already ours or already in that shape
    return f"expected well-formed YAML, found {problem}"


# PyYAML reads a key only within this many characters of its start (YAML 1.1's limit for a
# "simple key"); past it, its messages name a ':' it cannot place ("expected ':', found ':'").
MAX_KEY_CHARS = 1024


def _check_key_length(reader: Reader, text: str, line_index: int) -> None:
    """Refuse, where it starts, a key on line ``line_index`` (from 0) longer than YAML reads."""
    line = text.split("\n", line_index + 1)[line_index] if line_index < text.count("\n") + 1 else ""
    start = len(line) - len(line.lstrip(" -"))
    key = re.match(r"[^\n]*?(?=:(?: |$))", line[start:])
    if key is not None and len(key[0]) > MAX_KEY_CHARS:
        reader._fail(f"expected a key of at most {MAX_KEY_CHARS} characters (the longest YAML "
                     f"reads), found one of {len(key[0])}", line_index + 1, start + 1)


class Invalid(Exception):
    """Raised inside a reader after an error was recorded, to skip the rest of a section."""


class _TooLarge(Exception):
    """A number written beyond `MAX_NUMBER_CHARS` or `MAX_EXPONENT`."""


class Reader:
    """Collects located errors while turning YAML nodes into checked Python values."""

    def __init__(self, source: str):
        self.source = source
        self.errors: list[ProtocolError] = []
        self.unlisted = 0  # problems past MAX_PROBLEMS: counted, not listed
        # Problems that leave the values read valid (an unknown key: its value is not used),
        # so that a typo does not stop what depends on its section from being checked.
        self.harmless = 0
        # A section read with a misspelt key stands on defaults where the author meant a value:
        # checks that rest on it (a servo's speed, a pin's calibration) are left out until the
        # typo is fixed, so that no problem is reported about a value nobody wrote.
        self.guessing = False
        # One constructor per file: PyYAML's caches every object it built, keyed by node.
        self._constructor = yaml.constructor.SafeConstructor()
        self.text = ""  # the file's text, once composed (a block's lines are located in it)

    def error(self, node: Node | None, message: str) -> Invalid:
        if len(self.errors) >= MAX_PROBLEMS:
            self.unlisted += 1
            return Invalid(message)
        line = node.start_mark.line + 1 if node is not None else 0
        col = node.start_mark.column + 1 if node is not None else 0
        self.errors.append(ProtocolError(message, self.source, line, col))
        return Invalid(message)

    def raise_if_errors(self) -> None:
        if self.errors:
            self.errors.sort(key=lambda e: (e.line, e.col))
            if self.unlisted:
                self.errors.append(ProtocolError(
                    f"{self.unlisted} more problem(s) not listed; fix these first", self.source))
            raise ProtocolErrors(self.errors)

    def attempt(self, read: Callable[[], T], default: T) -> T:
        """Run a reader step; on a recorded error return ``default`` and carry on."""
        try:
            return read()
        except Invalid:
            return default

    def optional(
        self, keys: Mapping[str, Node], key: str, read: Callable[[Node], T], default: T
    ) -> T:
        """``read`` the value of ``key``; ``default`` when the key is absent or its value is wrong
        (the problem is recorded, and reading goes on with the rest)."""
        if key not in keys:
            return default
        try:
            return read(keys[key])
        except Invalid:
            return default

    @contextmanager
    def section(self) -> Iterator[None]:
        """Read every field of a section, then fail it as a whole if any field was wrong."""
        before = len(self.errors) + self.unlisted - self.harmless
        yield
        if len(self.errors) + self.unlisted - self.harmless > before:
            raise Invalid("section")

    # -- structure ---------------------------------------------------------------------------

    def compose(self, text: str, what: str = "a protocol") -> Node:
        """The node tree of ``text``: one document, bounded in depth and aliases (``what``
        the file should hold, for an empty one)."""
        bad = _NOT_PRINTABLE.search(text)
        if bad:
            line = text.count("\n", 0, bad.start()) + 1
            col = bad.start() - (text.rfind("\n", 0, bad.start()) + 1) + 1
            self._fail(f"expected text, found the control character U+{ord(bad[0]):04X}",
                       line, col)
        self.text = text
        try:
            root = compose_tree(text)
        except yaml.MarkedYAMLError as problem:
            mark = problem.problem_mark or problem.context_mark
            if mark is not None:
                _check_key_length(self, text, mark.line)
            what = " ".join(str(problem.problem or problem.context or "malformed YAML").split())
            found = _found_at(text, mark.index) if mark else "an unreadable file"
            if "quoted scalar" in str(problem.context):
                what = "expected the closing quote"
            self._fail(f"malformed YAML: {_expected_found(what, found)}",
                       mark.line + 1 if mark else 0, mark.column + 1 if mark else 0)
        except yaml.YAMLError as problem:
            self._fail(f"malformed YAML: {' '.join(str(problem).split())}")
        if root is None:
            found = "an empty file" if not text.strip() else "only comments and blank lines"
            self._fail(f"expected {what}, found {found}", 1, 1)
        return root

    def _fail(self, message: str, line: int = 0, col: int = 0) -> NoReturn:
        raise ProtocolErrors([ProtocolError(message, self.source, line, col)])

    def mapping(
        self,
        node: Node,
        allowed: set[str],
        required: frozenset[str] | set[str] = frozenset(),
        what: str = "section",
        *,
        stop_if_missing: bool = True,
    ) -> dict[str, Node]:
        """Keys of a mapping with their value nodes; unknown keys get a did-you-mean hint.

        A required key missing is reported, then raises `Invalid` unless ``stop_if_missing``
        is False: the caller reads the keys that are there (each problem of the section found
        in one pass) and stops before it needs the missing one.
        """
        if not isinstance(node, MappingNode):
            raise self.error(node, f"expected a mapping for the {what}, found {describe(node)}")
        out: dict[str, Node] = {}
        first: dict[str, Node] = {}  # each key's node, where it is first written
        suggested: set[str] = set()
        for key_node, value_node in node.value:
            key_text = str(self.scalar_value(key_node))
            if key_text in first:
                self._again(key_node, key_text, first[key_text], f"the {what}")
                continue
            first[key_text] = key_node
            if key_text not in allowed:
                hint = close_match(key_text, sorted(allowed))
                suggested.update(hint)
                if hint:
                    said = f"found {shown(key_text)}; did you mean {hint[0]!r}?"
                else:
                    said = f"(one of {', '.join(sorted(allowed))}), found {shown(key_text)}"
                self.error(key_node, f"expected a key of the {what}"
                                     f"{', ' if hint else ' '}{said}")
                self.harmless += 1
                continue
            out[key_text] = value_node
        missing = sorted(required - out.keys())
        for key in missing:
            if key not in suggested:  # a misspelt key was already reported with its hint
                self.error(node, f"expected a {key!r} key in the {what}, found none")
        if missing and stop_if_missing:
            raise Invalid(f"missing {missing}")
        return out

    def items(self, node: Node, what: str) -> list[tuple[Node, Node]]:
        """(key node, value node) pairs of a mapping whose keys are data (names, pins)."""
        if not isinstance(node, MappingNode):
            raise self.error(node, f"expected a mapping for {what}, found {describe(node)}")
        first: dict[str, Node] = {}
        pairs = []
        for key_node, value_node in node.value:
            key_text = str(self.scalar_value(key_node))
            if key_text in first:
                self._again(key_node, key_text, first[key_text], what)
                continue
            first[key_text] = key_node
            pairs.append((key_node, value_node))
        return pairs

    def _again(self, key_node: Node, key_text: str, first: Node, what: str) -> None:
        """A key written a second time in one mapping (``what``), said where it is again."""
        self.error(key_node, f"expected each key once in {what}, found {shown(key_text)} again "
                             f"(first at line {first.start_mark.line + 1})")

    def sequence(self, node: Node, what: str, min_items: int = 1) -> list[Node]:
        if not isinstance(node, SequenceNode):
            raise self.error(node, f"expected a list for {what}, found {describe(node)}")
        if len(node.value) < min_items:
            raise self.error(
                node, f"expected at least {min_items} item(s) in {what}, found {len(node.value)}"
            )
        return list(node.value)

    # -- scalars -----------------------------------------------------------------------------

    def scalar_value(self, node: Node) -> Any:
        if not isinstance(node, ScalarNode):
            raise self.error(node, f"expected a single value, found {describe(node)}")
        tag = node.tag
        if tag not in _PLAIN_TAGS:
            raise self.error(node, f"expected a plain value, found {shown(node.value)} tagged "
                             f"{_short_tag(tag)} (only text, numbers, true/false and null are read)")
        if tag in _NUMBER_TAGS and len(node.value) > MAX_NUMBER_CHARS:
            raise self.error(node, f"expected a number of at most {MAX_NUMBER_CHARS} characters, "
                             f"found {shown(node.value)}")
        if tag != f"{_YAML}str" and not any(p.match(node.value) for p in _IMPLICIT[tag]):
            raise self.error(node, f"expected a plain value, found {shown(node.value)}, which is "
                             f"not a {_short_tag(tag)}")
        try:
            return self._constructor.construct_object(node)
        except (yaml.YAMLError, ValueError, OverflowError) as problem:
            # e.g. a date 2024-13-45, which matches the date pattern but is no date
            what = " ".join(str(getattr(problem, "problem", None) or problem).split())
            raise self.error(node, f"expected a plain value, found {shown(node.value)} ({what})"
                             ) from None

    def decimal_value(self, node: Node) -> Any:
        """`scalar_value`, refused where YAML read a number not written in decimal."""
        value = self.scalar_value(node)
        if node.tag in _NUMBER_TAGS and _NOT_DECIMAL.search(node.value):
            raise self.error(node, f"expected a decimal number, found {shown(node.value)}")
        return value

    def string(self, node: Node, what: str, choices: tuple[str, ...] = ()) -> str:
        value = self.scalar_value(node)
        if not isinstance(value, str) or not value.strip():
            raise self.error(node, f"expected text for {what}, found {describe(node)}")
        if choices and value not in choices:
            hint = close_match(value, choices)
            extra = f"; did you mean {hint[0]!r}?" if hint else ""
            raise self.error(
                node, f"expected {what} to be one of {', '.join(choices)}, found {shown(value)}{extra}"
            )
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
        value = self.decimal_value(node)
        if isinstance(value, float) and not math.isfinite(value):
            raise self.error(
                node, f"expected a finite number of {unit} for {what}, found {node.value}"
            )
        try:
            exact = _exact(node.value, value)
        except _TooLarge:
            raise self.error(
                node,
                f"expected a number of {unit} for {what} in at most {MAX_NUMBER_CHARS} "
                f"characters with an exponent within ±{MAX_EXPONENT}, found {shown(node.value)}",
            ) from None
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
        value = self.decimal_value(node)
        if isinstance(value, str) and _WHOLE.fullmatch(value.strip()):
            # quoted, as a number with a unit may be ("1/3"): read as the number it writes
            if len(value) > MAX_NUMBER_CHARS:
                raise self.error(node, f"expected a number of at most {MAX_NUMBER_CHARS} "
                                 f"characters, found {shown(node.value)}")
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(node, f"expected a whole number for {what}, found {describe(node)}")
        if minimum is not None and value < minimum:
            raise self.error(node, f"expected {what} of at least {minimum}, found {value}")
        if maximum is not None and value > maximum:
            raise self.error(node, f"expected {what} of at most {maximum}, found {value}")
        return value


def exact_number(text: str) -> Fraction:
    """The exact number ``text`` writes by a protocol's rules (``0.1``, ``1e-3``, ``1/3``: ASCII
    decimal, at most `MAX_NUMBER_CHARS` characters, an exponent within ±`MAX_EXPONENT`), for
    numbers typed on a command line; `ValueError` saying what was expected otherwise."""
    try:
        exact = _exact(text, text)
    except _TooLarge:
        raise ValueError(f"expected a number of at most {MAX_NUMBER_CHARS} characters with an "
                         f"exponent within ±{MAX_EXPONENT}, found {shown(text)}") from None
    if exact is None:
        raise ValueError(f"expected a decimal number, found {shown(text)}")
    return exact


def _exact(text: str, value: Any) -> Fraction | None:
    """The exact number ``text`` writes (``value`` is what YAML made of it), or None.

    Decimals are read from their text, so ``0.1`` is 1/10 and ``1e-400`` is refused rather
    than rounded to 0.0 (numbers YAML read are written in decimal: `Reader.decimal_value`).
    """
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return None
    plain = text.strip() if isinstance(value, int | float) else value.strip()
    decimal = _DECIMAL.fullmatch(plain)
    ratio = None if decimal else _RATIO.fullmatch(plain)
    if (decimal and (decimal[2] or decimal[3])) or ratio:
        if len(plain) > MAX_NUMBER_CHARS:
            raise _TooLarge
        if ratio:
            sign, numerator, denominator = ratio[1], int(ratio[2]), int(ratio[3])
            if not denominator:
                return None
            return Fraction(-numerator if sign == "-" else numerator, denominator)
        assert decimal is not None
        written = int(decimal[4] or 0)
        if abs(written) > MAX_EXPONENT:
            raise _TooLarge
        fraction_digits = decimal[3] or ""
        digits = int((decimal[2] or "") + fraction_digits or "0")
        exact = Fraction(digits) * Fraction(10) ** (written - len(fraction_digits))
        return -exact if decimal[1] == "-" else exact
    return None


def _short_tag(tag: str) -> str:
    return "!!" + tag.removeprefix(_YAML) if tag.startswith(_YAML) else tag


def close_match(text: str, choices) -> list[str]:
    import difflib  # here: only a misspelt key needs it

    # difflib's cost grows with the text's length; a long unknown word is no misspelling.
    return difflib.get_close_matches(text, choices, n=1) if len(text) <= 64 else []


def shown(value: object, limit: int = 48) -> str:
    """``repr(value)``, cut short for a message line."""
    text = repr(value)
    if len(text) <= limit:
        return text
    size = f" ({len(value)} characters)" if isinstance(value, str) else ""
    return f"{text[:limit]}...{size}"


def describe(node: Node) -> str:
    if isinstance(node, MappingNode):
        return "a mapping"
    if isinstance(node, SequenceNode):
        return "a list"
    if node.tag.endswith(":null"):
        return "nothing"
    return shown(node.value)
