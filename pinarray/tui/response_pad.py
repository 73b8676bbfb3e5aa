"""Where the experimenter enters the subject's answer, with keys or the mouse."""

from __future__ import annotations

from collections.abc import Sequence

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


class ResponsePad(Widget, can_focus=True):
    """The answer entry: a pin number for localisation, a direction for apparent motion.

    Localisation: digits then Enter; ``0`` or ``n`` means nothing felt; a pin clicked on the
    grid is put in the entry (`choose`) and Enter confirms it. Motion: one key answers.
    The pad only collects answers; the run screen decides whether they are accepted.

    Parameters
    ----------
    localisation : bool
        Which paradigm's answers to take.
    pin_count : int
        Most digits a pin number can have follow from it.
    answers : sequence of str
        Apparent motion: the answers offered (the directions the waves go, none, unsure).
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
                 answers: Sequence[str] = ("left", "right", "none", "unsure"), **kwargs):
        super().__init__(**kwargs)
        self.localisation = localisation
        self.digits = len(str(pin_count))
        self.answers = motion_answer_keys(answers)
        self.motion_keys = {key: answer for answer, keys, _ in self.answers for key in keys}

    def compose(self) -> ComposeResult:
        if self.localisation:
            yield Static(id="entry")
            yield Static("type the pin number, Enter to confirm · 0 or n: nothing felt · "
                         "or click a pin", classes="hint")
        else:
            with Horizontal(id="motion-buttons"):
                for answer, _, label in self.answers:
                    yield Button(label, id=f"answer-{answer}", disabled=True)

    def on_mount(self) -> None:
        self._draw()

    def watch_entry(self) -> None:
        self._draw()
        self.post_message(self.Typed(self, self.entry))

    def watch_accepting(self) -> None:
        self.set_class(self.accepting, "-accepting")
        for button in self.query(Button):
            button.disabled = not self.accepting
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
        elif key == "n" or (key == "0" and self.entry in ("", "none")):
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
