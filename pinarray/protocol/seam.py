"""The paradigm seam, as a protocol sees it: reading a design, its conditions as stimuli, its answers.

A paradigm is one room (`pinarray.paradigms`): its conditions, how its ``design`` section is
read, what its trials play and ask, its rows, its simulated subject and its estimates. The
protocol, the plan, the procedures and the commands' validation know a paradigm only through
`ParadigmDesign`, found by name (`paradigm_named`: the registry, `pinarray.registry`); the
results know it through `pinarray.journal.seam` and the analysis through
`pinarray.analysis.seam`. A room implements all three (`pinarray.paradigms.base.Paradigm`).

What every paradigm promises is kept here and in the design's reader, once for all: every
condition a design holds is checked as it would play (its trains on its pins, no pin driven
twice at once, every frame of goal changes on the servo bus: `check_conditions`); every
value an adaptive design may present likewise (`pinarray.protocol.adaptive_design`). A
paradigm's own reader says which conditions its design holds, and where each is written.
Pure Python, like the rest of the protocol's reading: `pinarray validate` loads no numpy.
It passes 400 lines because `ParadigmDesign` documents every member a room states, and
`DesignDefaults` gives what most rooms need not: one place a room's author reads.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from functools import cache, partial
from typing import TYPE_CHECKING, NamedTuple, Protocol, runtime_checkable

from pinarray import registry
from pinarray.errors import PinArrayError
from pinarray.protocol.drives import pulse_slots
from pinarray.protocol.model import Condition, Design, Device, PinDrive, Stimulus
from pinarray.protocol.procedures import Parameter, Task
from pinarray.protocol.stimuli import check_drives
from pinarray.protocol.yaml_nodes import Node, Reader

if TYPE_CHECKING:
    from pinarray.grid import Grid
    from pinarray.protocol.model import Protocol as PinProtocol


class Adapting(NamedTuple):
    """An adaptive design's parameter and values, where the values are written."""

    parameter: Parameter
    values: tuple[Fraction, ...]
    node: Node


@dataclass(frozen=True)
class DesignSection:
    """What a paradigm's reader is given: the ``design`` mapping (``node``, its ``keys``), the
    device, the stimuli by name (``declared`` names every stimulus written, broken ones too,
    whose problems are already reported), and an adaptive design's parameter and values."""

    reader: Reader
    node: Node
    keys: Mapping[str, Node]
    device: Device
    stimuli: Mapping[str, Stimulus]
    declared: Mapping[str, Node]
    adapting: Adapting | None = None

    def needs(self, *names: str, paradigm: str) -> None:
        """A `ProtocolError` at the design for the first of ``names`` it lacks."""
        for key in names:
            if key not in self.keys:
                raise self.reader.error(self.node, f"expected a {key!r} key in a {paradigm} "
                                                   "design, found none")


class Written(NamedTuple):
    """One condition a design holds, and the node it is written at (its errors point there);
    ``what`` begins a message about it (``at frequency_hz 12: ``), or is empty."""

    condition: Condition
    node: Node
    what: str = ""


@dataclass(frozen=True)
class ReadDesign:
    """What a paradigm's reader found: its conditions (one block's worth, each where it is
    written; a condition whose problem is already reported is left out), and what the
    subject judges in its terms (`Design.judgement`; None where the conditions say it all)."""

    written: tuple[Written, ...]
    judgement: object = None


class Choice(NamedTuple):
    """One answer an answer pad offers as a button or a card: what the row records, the keys
    that give it, its label, and a small drawing (a pattern's) or nothing."""

    answer: str
    keys: tuple[str, ...]
    label: str
    drawing: str = ""


class AnswerPad(NamedTuple):
    """How the experimenter gives a trial's answer: typed digits then Enter (``typed``; the
    entry says ``entry_hint``) or one of ``choices``; ``hint`` is the run screen's prompt.
    ``pins``: the digits name a pin, which a click on the grid puts in the entry, and 0 or n
    answers ``nothing`` (what nothing felt is written as)."""

    typed: bool
    choices: tuple[Choice, ...]
    entry_hint: str
    hint: str
    pins: bool = False
    nothing: str = ""


@runtime_checkable
class ParadigmDesign(Protocol):
    """What a paradigm is to a protocol: the design it reads, what its trials play and ask.

    Attributes
    ----------
    name : str
        What a design's ``paradigm:`` says (lowercase letters, digits and _).
    keys : frozenset of str
        The design keys it reads beside every design's (`pinarray.protocol.design.COMMON_KEYS`).
    attributes : tuple of str
        Its conditions' attributes an order constraint may name (``no_repeat: [pin]``).
    parameters, tasks : tuple
        What an adaptive design of it may adapt, and the tasks it may set (empty: it has no
        adaptive designs).
    balanced_draws : bool
        An adaptive design draws its conditions as often each as the trials allow (which
        interval holds the comparison...), not independently at random.
    warns_of_cut_lifts : bool
        Validation warns of a train whose signal ends inside a lift (its trials judge every
        pin's stroke, the last lift's included).
    plan_columns : tuple of str
        The columns ``pinarray plan`` gives its conditions (`plan_cells`).
    """

    name: str
    keys: frozenset[str]
    attributes: tuple[str, ...]
    parameters: tuple[Parameter, ...]
    tasks: tuple[Task, ...]
    balanced_draws: bool
    warns_of_cut_lifts: bool
    plan_columns: tuple[str, ...]

    def read(self, section: DesignSection) -> ReadDesign:
        """The design's conditions and judgement; problems go to ``section.reader`` (an
        error at the design's node or the key's, a `ProtocolError` raised or recorded)."""
        ...

    def completes(self, section: DesignSection) -> str | None:
        """The stimulus whose train leaves its frequency to this design, if any (a train
        without ``frequency_hz`` is an error unless a design completes it)."""
        ...

    def warnings(self, protocol: PinProtocol) -> list[str]:
        """What a valid design of it may still get wrong, one line each (validate prints them
        beside every paradigm's: a duration cue, a lift cut short)."""
        ...

    def drives(self, stimulus: Stimulus, condition: Condition) -> tuple[PinDrive, ...]:
        """What ``stimulus`` plays for ``condition``: each pin's train and when it starts."""
        ...

    # -- adaptive designs ------------------------------------------------------------------

    def adapt(self, condition: Condition, parameter: Parameter, value: Fraction) -> Condition:
        """``condition`` as its row tells it when ``parameter`` is at ``value`` (a frequency
        adapted is the one played; most conditions stay as they are)."""
        ...

    def adapts_condition(self, condition: Condition) -> bool:
        """Whether a value changes the condition alone (a comparison, an SOA between two pins),
        not the stimulus the protocol states."""
        ...

    def default_guess(self, task: Task, conditions: Sequence[Condition]) -> Fraction:
        """The chance of a correct answer without feeling the stimulus, for ``task``."""
        ...

    def catch_condition(self, stimulus: Stimulus) -> Condition:
        """What a catch trial presenting ``stimulus`` is; a `PinArrayError` saying why it
        cannot be one."""
        ...

    def counts_as_correct(self, task: Task, condition: Condition, catch: bool,
                          response: str) -> bool:
        """Whether ``response`` counts as correct for an adaptive design's ``task``."""
        ...

    def felt_answer(self, condition: Condition, design: Design, trial: int) -> str:
        """What a simulated subject who felt the stimulus answers (the answer that names it;
        for a control with none, one of the design's, chosen by ``trial``)."""
        ...

    def wrong_answer(self, task: Task, condition: Condition, design: Design, pin_count: int,
                     trial: int) -> str:
        """What a simulated subject answers wrongly for ``task`` (another of the design's
        answers, chosen by ``trial``; nothing felt for detection)."""
        ...

    # -- answers ---------------------------------------------------------------------------

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        """Every answer a trial of ``design`` takes, as the results write it."""
        ...

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        """Each answer with what it means, as the run's manifest keeps it (what a row's
        answer is checked against when read back; empty: the paradigm's rows say what a run
        offered from its plan, as the first two paradigms' files have always done)."""
        ...

    def instructions(self, design: Design) -> str:
        """What the subject is told, for the results' sidecars."""
        ...

    def take_answer(self, response: object, design: Design, grid: Grid) -> str:
        """``response`` as the results write it; a `PinArrayError` saying what is expected."""
        ...

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        """An answer sheet's cell (lowercase, stripped) as the results write it, or None."""
        ...

    def sheet_expected(self, design: Design, grid: Grid) -> str:
        """What an answer sheet's cell may hold, in words (``a pin number from 1 to 16...``)."""
        ...

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        """How the experimenter gives an answer on the run screen."""
        ...

    def cue(self, condition: Condition, design: Design) -> tuple[object, str] | None:
        """(the answer that names ``condition``, its label): conditions with different answers
        must last alike, or the duration gives the answer away; None where it cannot (every
        trial plays both intervals, or both pins)."""
        ...

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        """The answer that names what ``condition`` presented (None: no answer is right)."""
        ...

    # -- words -----------------------------------------------------------------------------

    def describe(self, condition: Condition) -> str:
        """The condition in one line of the lab's words (``pin 6 at 10 Hz``)."""
        ...

    def title(self, condition: Condition) -> str:
        """The condition with its stimulus, for a script (``seed_train on pin 6 at 10 Hz``)."""
        ...

    def marker_fields(self, condition: Condition, stimulus: Stimulus) -> dict[str, object]:
        """What a trial's LSL markers say of its condition (plain JSON values)."""
        ...

    def grouped(self, condition: Condition) -> tuple[str, int | None]:
        """How a list of conditions names this one: its group in the lab's words (``seed_train
        at 5 Hz``) and its pin within the group (None: the group is the condition)."""
        ...

    def screen_line(self, condition: Condition, pins: tuple[int, ...]) -> str:
        """The stimulus as the run screen shows it (``pins``: those it moves)."""
        ...

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        """Its cells under `plan_columns`."""
        ...

    def plan_fields(self, condition: Condition) -> dict[str, object]:
        """What a plan entry of the run's manifest (and ``pinarray compile``) says of it,
        beside the trial, block, practice and stimulus: plain JSON values."""
        ...


@cache  # a protocol's check is slow (typing's), and a results file asks once per row
def paradigm_named(name: str) -> ParadigmDesign:
    """The paradigm called ``name`` (the registry's), checked to implement `ParadigmDesign`."""
    room = registry.room(name)
    if not isinstance(room, ParadigmDesign):
        missing = [m for m in DESIGN_MEMBERS if not hasattr(room, m)]
        raise PinArrayError(f"paradigm {name!r} does not implement the paradigm seam: "
                            f"{type(room).__name__} lacks {', '.join(missing)}")
    return room


# What a paradigm's design must have, by name (the protocol's attributes and methods; Python
# 3.11 keeps no list of them on the class).
DESIGN_MEMBERS = tuple(sorted({*ParadigmDesign.__annotations__,
                               *(m for m in vars(ParadigmDesign) if not m.startswith("_"))}))


# Plays a trial's drives on a model of the device (the simulated array: `pinarray.player.
# rehearsal`) and says why they are not delivered there, or None: what `check_conditions`
# asks last, of conditions that pass every other check, when it is given one.
Rehearse = Callable[[Sequence[PinDrive], Device], "str | None"]


def check_conditions(reader: Reader, read: ReadDesign, device: Device,
                     stimuli: Mapping[str, Stimulus], paradigm: ParadigmDesign,
                     check_pulses: Callable[[Node, int], None],
                     rehearse: Rehearse | None = None,
                     ) -> tuple[tuple[Condition, ...], tuple[int, ...]]:
    """Every condition a paradigm read, checked as it would play: its pulses within a trial's
    limit (``check_pulses``), its trains followed by its pins, no pin driven twice at once,
    and on bus servos every frame of goal changes written and read back in time. The
    conditions that pass, with the pulse slots each plays. A problem is reported where its
    condition is written, once for the place (the first condition written there that fails)
    and once for the words (the same problem at each of a design's frequencies is said once).
    With ``rehearse``, the conditions that pass are then played on the model it stands for,
    when nothing else in the file is wrong, and those it does not deliver are refused in the
    same way.
    """
    passed: list[tuple[Condition, Node, str, int]] = []
    failed: set[int] = set()
    said: set[str] = set()

    def refused(before: int, node: Node) -> None:
        failed.add(id(node))
        new = reader.errors[before:]
        if new and all(e.message in said for e in new):
            # The same problem at another place (a stroke too large at each of a design's
            # frequencies): said once, where it is first written.
            del reader.errors[before:]
        said.update(e.message for e in new)

    with reader.section():
        for condition, node, what in read.written:
            if id(node) in failed:
                continue
            before = len(reader.errors)
            count = reader.attempt(partial(_checked, reader, node, condition, stimuli, device,
                                           paradigm, what, check_pulses), None)
            if count is None:
                refused(before, node)
            else:
                passed.append((condition, node, what, count))
        if rehearse is not None and not reader.errors and not reader.guessing:
            for condition, node, what, _ in passed:
                if id(node) in failed:
                    continue
                before = len(reader.errors)
                problem = rehearse(paradigm.drives(stimuli[condition.stimulus], condition),
                                   device)
                if problem is not None:
                    reader.error(node, what + problem)
                    refused(before, node)
    kept = [(condition, count) for condition, node, _, count in passed
            if id(node) not in failed]
    return tuple(c for c, _ in kept), tuple(n for _, n in kept)


def _checked(reader: Reader, node: Node, condition: Condition, stimuli: Mapping[str, Stimulus],
             device: Device, paradigm: ParadigmDesign, what: str,
             check_pulses: Callable[[Node, int], None]) -> int:
    try:
        drives = paradigm.drives(stimuli[condition.stimulus], condition)
    except PinArrayError as problem:
        raise reader.error(node, what + str(problem)) from None
    count = sum(pulse_slots(d.train) for d in drives)
    check_pulses(node, count)
    check_drives(reader, node, drives, device, what)
    return count


class DesignDefaults:
    """What a paradigm need not say of itself: no adaptive designs, no catch trials, answers
    taken as written (an answer sheet's in any case), one key each on the pad (1 to 9), no
    design that completes a train, a duration cue wherever conditions have different answers.

    A room subclasses it and states the rest (`ParadigmDesign`); `pinarray.paradigms.base`
    adds the rows and the analysis.
    """

    name: str
    attributes: tuple[str, ...] = ()
    parameters: tuple[Parameter, ...] = ()
    tasks: tuple[Task, ...] = ()
    balanced_draws = False
    warns_of_cut_lifts = True

    def completes(self, section: DesignSection) -> str | None:
        return None

    def warnings(self, protocol: PinProtocol) -> list[str]:
        return []

    def adapt(self, condition: Condition, parameter: Parameter, value: Fraction) -> Condition:
        return condition

    def adapts_condition(self, condition: Condition) -> bool:
        return False

    def default_guess(self, task: Task, conditions: Sequence[Condition]) -> Fraction:
        return Fraction(0)

    def catch_condition(self, stimulus: Stimulus) -> Condition:
        raise PinArrayError(f"expected no catch stimulus in a {self.name} design (its trials "
                            f"have none), found {stimulus.name!r}")

    def counts_as_correct(self, task: Task, condition: Condition, catch: bool,
                          response: str) -> bool:
        raise PinArrayError(f"a {self.name} design has no adaptive task {task!r}")

    def felt_answer(self, condition: Condition, design: Design, trial: int) -> str:
        right = self.correct_answer(condition, design)
        return right if right is not None else design.answers(0)[0]

    def wrong_answer(self, task: Task, condition: Condition, design: Design, pin_count: int,
                     trial: int) -> str:
        right = self.correct_answer(condition, design)
        answers = [a for a in design.answers(pin_count) if a != right]
        return answers[trial % len(answers)]

    def answers(self, design: Design, pin_count: int) -> tuple[str, ...]:
        raise NotImplementedError

    def answer_meanings(self, design: Design, pin_count: int) -> tuple[tuple[str, str], ...]:
        return tuple((a, f"answered {a}") for a in self.answers(design, pin_count))

    def take_answer(self, response: object, design: Design, grid: Grid) -> str:
        answers = design.answers(grid.pin_count)
        text = str(response).strip()
        if text not in answers:
            raise PinArrayError(f"expected one of {', '.join(answers)}, found {response!r}")
        return text

    def sheet_answer(self, text: str, design: Design, grid: Grid) -> str | None:
        return {a.lower(): a for a in design.answers(grid.pin_count)}.get(text)

    def sheet_expected(self, design: Design, grid: Grid) -> str:
        return f"one of {', '.join(design.answers(grid.pin_count))}"

    def pad(self, design: Design, grid: Grid) -> AnswerPad:
        """One key each: an answer that is one digit its own (a subject who says "3" is
        given 3), the others the digits 1 to 9 no answer is, in the order `answers` gives them."""
        answers = design.answers(grid.pin_count)
        own = {a for a in answers if len(a) == 1 and a in DIGITS}
        free = iter([d for d in DIGITS[1:] if d not in own])
        choices = []
        for answer in answers:
            key = answer if answer in own else next(free, None)
            choices.append(Choice(answer, (key,) if key else (),
                                  answer if key in (None, answer) else f"{answer} ({key})"))
        return AnswerPad(False, tuple(choices), "", choices_hint(choices))

    def cue(self, condition: Condition, design: Design) -> tuple[object, str] | None:
        return (self.correct_answer(condition, design), condition.stimulus)

    def correct_answer(self, condition: Condition, design: Design) -> str | None:
        """The answer that names what ``condition`` presented (None: no answer is right)."""
        raise NotImplementedError

    def describe(self, condition: Condition) -> str:
        raise NotImplementedError

    def plan_cells(self, condition: Condition) -> tuple[str, ...]:
        raise NotImplementedError

    def title(self, condition: Condition) -> str:
        return f"{condition.stimulus}: {self.describe(condition)}"

    def grouped(self, condition: Condition) -> tuple[str, int | None]:
        return self.title(condition), None

    def screen_line(self, condition: Condition, pins: tuple[int, ...]) -> str:
        return f"stimulus: {self.describe(condition)}"

    def marker_fields(self, condition: Condition, stimulus: Stimulus) -> dict[str, object]:
        plan_columns: tuple[str, ...] = getattr(self, "plan_columns", ())
        return {"stimulus": condition.stimulus,
                "condition": dict(zip(plan_columns, self.plan_cells(condition), strict=True))}


KEY_NAMES = {"left": "←", "right": "→", "up": "↑", "down": "↓"}


DIGITS = "0123456789"


def choices_hint(choices: Sequence[Choice]) -> str:
    """``1 (across) / 2 (upright) ...``: each choice's first key and its answer."""
    return " / ".join(f"{KEY_NAMES.get(c.keys[0], c.keys[0]) if c.keys else '?'} ({c.answer})"
                      for c in choices)


MAX_LEVELS = 200  # the values a fixed design lists of one parameter (comparisons, SOAs...)


def read_levels(reader: Reader, node: Node, what: str, unit: str,
                signed: bool) -> list[tuple[Node, Fraction]]:
    """A design's list of distinct values (``what``, in ``unit``; negative ones too where
    ``signed``), each with its node: at most `MAX_LEVELS`, within ±60 000."""
    items = reader.sequence(node, what)
    if len(items) > MAX_LEVELS:
        raise reader.error(node, f"expected at most {MAX_LEVELS} of {what}, found {len(items)}")
    read = [(item, reader.number(item, f"each of {what}", unit,
                                 minimum=-60_000 if signed else 0, maximum=60_000))
            for item in items]
    values = [value for _, value in read]
    for item, value in read:
        if values.count(value) > 1:
            raise reader.error(item, f"expected each of {what} once, found {float(value):g} "
                                     "more than once")
    return read
