"""Where the experimenter enters the subject's answer, with keys or the mouse."""

from __future__ import annotations

from textual import events, on
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.message import Message
from textual.reactive import reactive
from textual.widget import Widget
from textual.widgets import Button, Static

from pinarray.protocol.seam import AnswerPad, Choice


def answer_keys(pad: AnswerPad) -> frozenset[str]:
    """The keys that answer on ``pad``: typed while no answer is expected, they are refused
    with a notice by the run screen, not taken for something else."""
    typed = {*"0123456789", "backspace", *("n" if pad.nothing else "")} if pad.typed else set()
    return frozenset({*typed, *(key for choice in pad.choices for key in choice.keys)})


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

    Entry (a pin, a count): digits then Enter; for a pin ``0`` or ``n`` means nothing felt,
    and a pin clicked on the grid is put in the entry (`choose`) and Enter confirms it.
    Choices (directions, patterns, intervals, the pin first...): one key answers, or a click.
    The pad only collects answers; the run screen decides whether they are accepted.

    Parameters
    ----------
    pad : AnswerPad
        What the run's paradigm takes, and how (`pinarray.protocol.seam.ParadigmDesign.pad`):
        typed digits (a pin or a count) or choices, and what the entry says it takes.
    pin_count : int
        Most digits a pin number (or count) can have follow from it.
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

    def __init__(self, pad: AnswerPad, pin_count: int = 16, **kwargs):
        super().__init__(**kwargs)
        self.localisation = pad.typed
        self.entry_hint = pad.entry_hint
        self.nothing = pad.nothing  # what 0 or n types (nothing felt), if anything
        self.digits = len(str(pin_count))
        self.answers: tuple[Choice, ...] = pad.choices
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
        shown = "nothing felt" if self.nothing and self.entry == self.nothing else self.entry
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
        nothing = self.nothing
        if key == "backspace":
            event.stop()
            self.entry = "" if nothing and self.entry == nothing else self.entry[:-1]
        elif nothing and (key == "n" or (key == "0" and self.entry in ("", nothing))):
            event.stop()
            self.entry = nothing
        elif key.isascii() and key.isdigit():
            event.stop()
            base = "" if nothing and self.entry == nothing else self.entry
            self.entry = key if len(base) >= self.digits else base + key

    @on(Button.Pressed)
    def _button(self, event: Button.Pressed) -> None:
        event.stop()
        self._answer(str(event.button.id).removeprefix("answer-"))
        self.focus()
