"""A screen's notice line, and the rule that no key is dropped in silence.

Every key reaches either a binding that acts, the focused widget (typing), or `KeyNotices`,
which says on the screen's `Notice` why it does nothing now: the binding's action is not
possible at this moment (the screen's `refusal` explains), or the key means nothing here.
"""

from __future__ import annotations

import typing
from typing import ClassVar

from textual import events
from textual.binding import Binding, BindingType
from textual.widgets import Static

if typing.TYPE_CHECKING:
    from textual.screen import Screen


class Notice(Static):
    """One line: why a key did nothing, or what is wrong with an entry.

    A notice stays until the screen clears it (the next action, a change of phase, the
    entry being corrected), so a burst of keys shows the last word, not a pile of toasts.
    """

    DEFAULT_CSS = """
    Notice {
        height: auto;
        color: $warning;
    }
    Notice.-error {
        color: $error;
        text-style: bold;
    }
    """

    _said: tuple[str, bool] = ("", False)  # what it says now: a notice said again is not redrawn

    def say(self, text: str, error: bool = False) -> None:
        if (text, error) == self._said:
            return
        self._said = (text, error)
        self.update(text)
        self.set_class(error, "-error")

    def clear(self) -> None:
        self.say("")

    @property
    def text(self) -> str:
        return str(self.render())


def actions_by_key(bindings: list[BindingType]) -> dict[str, tuple[str, ...]]:
    """Each key of a BINDINGS list and the actions it names (a key may serve two, e.g. p:
    pause and resume, of which `check_action` enables one at a time)."""
    found: dict[str, tuple[str, ...]] = {}
    for binding in bindings:
        if not isinstance(binding, Binding):
            binding = Binding(*binding)
        for key in binding.key.split(","):
            key = key.strip()
            found[key] = (*found.get(key, ()), binding.action)
    return found


class KeyNotices:
    """Mixed into a `Screen`: a key no binding takes now gets a notice, never silence.

    The screen provides ``notice`` (its `Notice`), and may override `refusal` (why a bound
    action is not possible now) and `unbound` (what a key this screen has no binding for
    means here, e.g. an answer typed while no answer is expected).
    """

    BINDINGS: ClassVar[list[BindingType]]

    def on_key(self, event: events.Key) -> None:
        # Keys arrive here after the focused widget let them through and before Textual
        # looks for a binding: one that a binding takes now goes on to it.
        if event.key in self.active_bindings:  # type: ignore[attr-defined]
            return
        event.stop()
        actions = actions_by_key(self.BINDINGS).get(event.key, ())
        name = event.character if event.is_printable and event.character != " " else event.key
        text = self.refusal(actions) if actions else self.unbound(event.key)
        self.notice.say(text or f"{name} does nothing here (the keys are in the footer)")

    @property
    def notice(self) -> Notice:
        return self.query_one(Notice)  # type: ignore[attr-defined]

    def refresh_keys(self) -> None:
        """Have the footer show which keys act now, if that changed.

        The footer redraws every key it shows when told the bindings changed (the costliest
        update a screen makes), so it is told only when one of the actions it shows became
        possible or impossible.
        """
        screen = typing.cast("Screen[object]", self)
        shown = [b if isinstance(b, Binding) else Binding(*b) for b in self.BINDINGS]
        now = tuple(screen.check_action(b.action, ()) for b in shown if b.show)
        if now != getattr(self, "_keys_shown", None):
            self._keys_shown = now
            screen.refresh_bindings()

    def refusal(self, actions: tuple[str, ...]) -> str:
        """Why none of ``actions`` is possible now ('' for the generic notice)."""
        return "not possible now"

    def unbound(self, key: str) -> str:
        """What ``key``, bound to nothing on this screen, means here ('' for the generic notice)."""
        return ""
