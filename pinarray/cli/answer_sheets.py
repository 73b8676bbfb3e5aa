"""Answer sheets for ``pinarray batch --responses``: read as labs make them, checked before a run.

A sheet is a table with a header row naming a ``trial`` and a ``response`` column (in any
case, among any others), one row per trial, as a spreadsheet saves it: comma-, semicolon- or
tab-separated (Excel's "Unicode text" is tab-separated UTF-16, its "CSV UTF-8" starts with
a byte-order mark, some locales separate with semicolons), CRLF or LF line ends, blank rows
anywhere. Every answer is checked against the protocol before a run is created, so a typo
on row 40 is found before the first stimulus plays, not when trial 40 comes up. Problems are
reported together, one ``FILE:LINE: message`` each.

Pure but for `load_answers`, which reads the file (with a size cap).
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from pinarray.errors import PinArrayError
from pinarray.protocol.model import Protocol

# 20 000 trials (a protocol's most) of a few bytes each, with room for extra columns.
MAX_ANSWERS_BYTES = 4 << 20
MAX_PROBLEMS = 100
DELIMITERS = (",", "\t", ";")
_WHOLE = re.compile("[0-9]{1,9}")  # trial and pin numbers: ASCII digits, never a huge one


@dataclass(frozen=True)
class Answer:
    """One row of a sheet: the trial it answers, the answer as written, and its line."""

    trial: int
    response: str
    line: int


class AnswersError(PinArrayError):
    """Problems of one answer sheet, each on its own ``FILE:LINE: message`` line."""

    def __init__(self, source: str, problems: Sequence[tuple[int, str]]):
        lines = [f"{source}:{line}: {message}" if line else f"{source}: {message}"
                 for line, message in problems[:MAX_PROBLEMS]]
        if len(problems) > MAX_PROBLEMS:
            lines.append(f"{source}: {len(problems) - MAX_PROBLEMS} more problem(s) not listed")
        super().__init__("\n".join(lines))


def parse_answers(text: str, source: str) -> tuple[Answer, ...]:
    """The rows of a sheet's ``text`` (already decoded); `AnswersError` lists what is wrong."""
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise AnswersError(source, [(0, "expected a header row naming the columns trial and "
                                        "response, found an empty file")])
    header = lines[first]
    for delimiter in DELIMITERS:
        names = [name.strip().lower() for name in _cells(header, delimiter) or []]
        if "trial" in names and "response" in names:
            break
    else:
        raise AnswersError(source, [(first + 1, "expected a header row naming the columns trial "
                                                 "and response (comma-, semicolon- or tab-"
                                                 f"separated), found {_shown(header)}")])
    trial_at, response_at = names.index("trial"), names.index("response")
    answers: list[Answer] = []
    problems: list[tuple[int, str]] = []
    first_line: dict[int, int] = {}
    for index in range(first + 1, len(lines)):
        line = index + 1
        row = _cells(lines[index], delimiter)
        if row is None:
            problems.append((line, f"expected cells separated by {delimiter!r}, found "
                                   f"{_shown(lines[index])}"))
            continue
        cells = [cell.strip() for cell in row]
        if not any(cells):
            continue  # a blank row, as spreadsheets leave them
        written = cells[trial_at] if trial_at < len(cells) else ""
        if not _WHOLE.fullmatch(written):
            problems.append((line, f"expected a trial number, found {_shown(written)}"))
            continue
        trial = int(written)
        if trial in first_line:
            problems.append((line, f"trial {trial} is answered twice (first on line "
                                   f"{first_line[trial]})"))
            continue
        first_line[trial] = line
        answers.append(Answer(trial, cells[response_at] if response_at < len(cells) else "",
                              line))
    if problems:
        raise AnswersError(source, problems)
    return tuple(answers)


def check_answers(
    answers: Iterable[Answer], source: str, protocol: Protocol
) -> dict[int, str]:
    """Answers by trial number, as the session takes them (``"7"``, ``"none"``, ``"left"``,
    a pattern's name, ``"first"``).

    Every trial of the protocol's plan must be answered once, with an answer its paradigm
    accepts as a sheet writes it (`ParadigmDesign.sheet_answer`: in any case; an interval by
    its number too, a pin first by its place...); trials the plan does not have are refused.
    """
    design = protocol.design
    grid = protocol.device.grid
    count = design.trial_count
    expected = design.paradigm.sheet_expected(design, grid)
    problems: list[tuple[int, str]] = []
    by_trial: dict[int, str] = {}
    for answer in answers:
        if not 1 <= answer.trial <= count:
            problems.append((answer.line, f"no trial {answer.trial} in the plan of "
                                          f"{protocol.source}: expected 1 to {count}"))
            continue
        found = design.paradigm.sheet_answer(answer.response.lower(), design, grid)
        if found is not None:
            by_trial[answer.trial] = found
            continue
        problems.append((answer.line, f"trial {answer.trial}: expected {expected}, found "
                                      f"{_shown(answer.response) if answer.response else 'nothing'}"))
    missing = [n for n in range(1, count + 1) if n not in by_trial]
    if missing and not problems:
        problems.append((0, f"no response for trial(s) {', '.join(map(str, missing[:10]))}"
                            + (" ..." if len(missing) > 10 else "")))
    if problems:
        raise AnswersError(source, problems)
    return by_trial


def load_answers(path: str, protocols: Sequence[Protocol]) -> dict[int, str]:
    """Read the sheet at ``path`` and check it against every protocol it will answer."""
    from pinarray.text_files import NotText, decode_text, read_bounded

    try:
        text = decode_text(read_bounded(path, MAX_ANSWERS_BYTES, "responses"))
    except NotText as problem:
        raise AnswersError(path, [(problem.line, problem.message)]) from None
    answers = parse_answers(text, path)
    by_trial: dict[int, str] = {}
    for protocol in protocols:
        by_trial = check_answers(answers, path, protocol)
    return by_trial


def _cells(line: str, delimiter: str) -> list[str] | None:
    """The cells of one line, or None when the csv module cannot read it (a NUL, say)."""
    try:
        return next(csv.reader(io.StringIO(line), delimiter=delimiter), [])
    except csv.Error:
        return None


def _shown(text: str) -> str:
    return repr(text) if len(text) <= 40 else f"{text[:40]!r}..."
