"""Where the experimenter enters the subject's answer, with keys or the mouse."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

from textual import events, on
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.message import Message
from textual.reactive import reactive
from textual.widget import Widget
from textual.widgets import Button, Static

# The usual motion answers: their keys (arrows too, since the subject says "left" or "up")
# and buttons. u is unsure and d the run screen's redo, so up and down have their arrows only.
USUAL_ANSWERS = {"left": (("l", "left"), "← left (l)"), "right": (("r", "right"), "right (r) →"),
                 "up": (("up",), "↑ up"), "down": (("down",), "↓ down"),
                 "none": (("n",), "no motion (n)"), "unsure": (("u",), "unsure (u)")}
SEQUENCE_KEYS = "123456789"  # the directions sequence waves name, in the order first listed
# Keys that answer on one paradigm or the other: typed while no answer is expected they are
# refused with a notice by the run screen, not taken for something else.
ANSWER_KEYS = frozenset({*(k for keys, _ in USUAL_ANSWERS.values() for k in keys),
                         *"0123456789", "backspace"})


class Choice(NamedTuple):
    """One answer the pad offers as a button (or a card): what it records, its keys, its
    label, and for a pattern a small drawing of it (`pinarray.tui.answers`)."""

    answer: str
    keys: tuple[str, ...]
    label: str
    drawing: str = ""


# What the entry (digits, then Enter) says it takes: a pin, or a count of pins.
PIN_ENTRY = "type the pin number, Enter to confirm · 0 or n: nothing felt · or click a pin"
COUNT_ENTRY = "type how many pins were raised, Enter to confirm"


def motion_answer_keys(answers: Sequence[str]) -> tuple[tuple[str, tuple[str, ...], str], ...]:
    """(answer, its keys, its button label) for each motion answer the protocol offers."""
    named = iter(SEQUENCE_KEYS)
    out = []
    for answer in answers:
        if answer in USUAL_ANSWERS:
            keys, label = USUAL_ANSWERS[answer]
        else:
            key = next(named, None)  # a design names at most 9 of its own (ten would be keyless)
            keys, label = ((key,), f"{answer} ({key})") if key else ((), answer)
        out.append((answer, keys, label))
    return tuple(out)


def motion_hint(answers: Sequence[str]) -> str:
    """The keys that answer, as the run screen's prompt says them: ``l / r / n (no motion)...``."""
    names = {"left": "l", "right": "r", "up": "↑", "down": "↓"}
    return " / ".join(
        "n (no motion)" if answer == "none" else "u (unsure)" if answer == "unsure"
        else names.get(answer, f"{keys[0] if keys else '?'} ({answer})")
        for answer, keys, _ in motion_answer_keys(answers))


class ChoiceCard(Static):
    """A pattern offered as an answer: its small drawing, its key and its name; a click
    answers it."""

    DEFAULT_CSS = """
    ChoiceCard { width: auto; height: auto; padding: 0 1 0 0; }
    ChoiceCard.-off { color: $text-disabled; }
    """

    def __init__(self, choice: Choice, **kwargs):
        super().__init__(choice.drawing, **kwargs)
        self.choice = choice

    def on_click(self) -> None:
        pad = self.parent.parent if self.parent is not None else None
        if isinstance(pad, ResponsePad) and pad.accepting:
            pad._answer(self.choice.answer)


class ResponsePad(Widget, can_focus=True):
    """The answer entry: typed digits (a pin, or a count of pins), or one key per answer.

    Entry (localisation, counts): digits then Enter; for a pin ``0`` or ``n`` means nothing
    felt, and a pin clicked on the grid is put in the entry (`choose`) and Enter confirms it.
    Choices (motion, patterns, intervals, pins first): one key answers, or a click.
    The pad only collects answers; the run screen decides whether they are accepted.

    Parameters
    ----------
    localisation : bool
        Whether answers are typed (a pin or a count) rather than chosen.
    pin_count : int
        Most digits a pin number (or count) can have follow from it.
    answers : sequence of str or of Choice
        The answers chosen between: motion answers by name (the directions the waves go,
        none, unsure), or `Choice` values.
    entry_hint : str
        What the entry takes, said under it (`PIN_ENTRY` or `COUNT_ENTRY`).
    """

    DEFAULT_CSS = """
    ResponsePad {
        height: auto;
        border: round $panel;
        padding: 0 1;
        &.-accepting { border: round $accent; }
        &:focus.-accepting { border: heavy $accent; }
        #entry { text-style: bold; }
        /* rows of four: a protocol's waves may go more ways than one row holds */
        #motion-buttons { height: auto; layout: grid; grid-size: 4; grid-rows: 3;
                          grid-gutter: 0 1; }
        #motion-buttons Button { width: 100%; }
        #pattern-cards { height: auto; layout: grid; grid-size: 4; grid-gutter: 0 1; }
    }
    """

    class PadMessage(Message):
        """Something from the pad; ``pad`` sent it (``@on(..., "#id")`` matches on it)."""

        def __init__(self, pad: ResponsePad):
            super().__init__()
            self.pad = pad

        @property
        def control(self) -> ResponsePad:
            return self.pad

    class Answered(PadMessage):
        """An answer was entered: a pin number as text, ``none``, or a motion answer."""

        def __init__(self, pad: ResponsePad, answer: str):
            super().__init__(pad)
            self.answer = answer

    class Proceed(PadMessage):
        """Enter with no answer to confirm: the experimenter wants the next step."""

    class Typed(PadMessage):
        """The entry changed (so the grid can show the pin being typed)."""

        def __init__(self, pad: ResponsePad, entry: str):
            super().__init__(pad)
            self.entry = entry

    entry: reactive[str] = reactive("")
    accepting: reactive[bool] = reactive(False)

    def __init__(self, localisation: bool, pin_count: int = 16,
                 answers: Sequence[str | Choice] = ("left", "right", "none", "unsure"),
                 entry_hint: str = PIN_ENTRY, **kwargs):
        super().__init__(**kwargs)
        self.localisation = localisation
        self.entry_hint = entry_hint
        self.nothing_felt = entry_hint == PIN_ENTRY  # 0 or n: a pin's entry only
        self.digits = len(str(pin_count))
        named = [a for a in answers if not isinstance(a, Choice)]
        self.answers: tuple[Choice, ...] = (
            *(Choice(*keyed) for keyed in motion_answer_keys(named)),
            *(a for a in answers if isinstance(a, Choice)))
        self.motion_keys = {key: choice.answer for choice in self.answers for key in choice.keys}

    def compose(self) -> ComposeResult:
        if self.localisation:
            yield Static(id="entry")
            yield Static(self.entry_hint, classes="hint")
        elif any(choice.drawing for choice in self.answers):
            with Horizontal(id="pattern-cards"):
                for choice in self.answers:
                    yield ChoiceCard(choice, id=f"answer-{choice.answer}",
                                     classes="answer -off")
        else:
            with Horizontal(id="motion-buttons"):
                for choice in self.answers:
                    yield Button(choice.label, id=f"answer-{choice.answer}", classes="answer",
                                 disabled=True)

    def on_mount(self) -> None:
        self._draw()

    def watch_entry(self) -> None:
        self._draw()
        self.post_message(self.Typed(self, self.entry))

    def watch_accepting(self) -> None:
        self.set_class(self.accepting, "-accepting")
        for button in self.query(Button):
            button.disabled = not self.accepting
        for card in self.query(ChoiceCard):
            card.set_class(not self.accepting, "-off")
        self._draw()

    def _draw(self) -> None:
        if not self.localisation or not self.is_mounted:
            return
        shown = "nothing felt" if self.entry == "none" else self.entry
        cursor = "▏" if self.accepting else ""
        self.query_one("#entry", Static).update(f"answer: {shown}{cursor}")

    def choose(self, pin: int) -> None:
        """Put a clicked pin in the entry; a second click on the same pin confirms it."""
        if not self.accepting:
            return
        if self.entry == str(pin):
            self._answer(self.entry)
        else:
            self.entry = str(pin)

    def clear(self) -> None:
        self.entry = ""

    def _answer(self, answer: str) -> None:
        self.post_message(self.Answered(self, answer))

    def on_key(self, event: events.Key) -> None:
        key = event.key
        if key == "enter":
            event.stop()
            if not self.accepting or not self.entry:
                self.post_message(self.Proceed(self))
            else:
                self._answer(self.entry)
            return
        if not self.accepting:
            return
        if not self.localisation:
            if key in self.motion_keys:
                event.stop()
                self._answer(self.motion_keys[key])
            return
        if key == "backspace":
            event.stop()
            self.entry = "" if self.entry == "none" else self.entry[:-1]
        elif self.nothing_felt and (key == "n" or (key == "0" and self.entry in ("", "none"))):
            event.stop()
            self.entry = "none"
        elif key.isdigit():
            event.stop()
            base = "" if self.entry == "none" else self.entry
            self.entry = key if len(base) >= self.digits else base + key

    @on(Button.Pressed)
    def _button(self, event: Button.Pressed) -> None:
        event.stop()
        self._answer(str(event.button.id).removeprefix("answer-"))
        self.focus()
