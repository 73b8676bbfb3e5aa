"""The screens' footer: Textual's, its keys kept and changed in place as the bindings change.

Textual's `Footer` recomposes on every change of the bindings (an action becoming possible or
not, a focus moving): it removes every key, builds them again, mounts and styles each (twice
more, for its compact state) and lays the screen out again. The run screen changes which keys
act at nearly every phase, so that was the costliest thing it did (a seventh of the UI tests'
processor time, measured). This footer builds the keys as a recompose would, unmounted, and
gives each key shown the state of the new one in its place (what it says, its action, its
tooltip, whether it is dimmed), then removes the keys left over or mounts the new ones beyond
them: the keys a recompose would have shown. A footer of any other kind (a group of keys) is
recomposed as before.
"""

from __future__ import annotations

from textual.widgets import Footer

# What a freshly built key carries, compared and then copied onto the key shown in its place
# (FooterKey's own attributes: `_disabled` is what a click on it consults).
_STATE = ("key", "key_display", "description", "action", "_disabled")
DISABLED = "-disabled"


class KeyFooter(Footer):
    """`Footer`, with keys updated in place (see the module's docstring)."""

    async def recompose(self) -> None:
        if not self.is_attached:
            return
        try:
            fresh = list(self.compose())  # unmounted; a key group needs compose's machinery
        except Exception:  # noqa: BLE001 - whatever stops it, the recompose does it properly
            fresh = None
        shown = list(self.children)
        if fresh is None or not all(_same_kind(new, old)
                                    for new, old in zip(fresh, shown, strict=False)):
            await super().recompose()
            return
        async with self.batch():
            for new, old in zip(fresh, shown, strict=False):
                # What a key draws is its key_display and description (its dimming is a class,
                # which restyles and redraws it when it changes): a key that says the same is
                # not drawn again.
                wider = any(getattr(new, name) != getattr(old, name)
                            for name in ("key_display", "description"))
                for name in _STATE:
                    setattr(old, name, getattr(new, name))
                if old.tooltip != new.tooltip:
                    old.tooltip = new.tooltip
                old.set_class(new.has_class(DISABLED), DISABLED)
                if wider:
                    old.refresh(layout=True)
            for old in shown[len(fresh):]:  # keys no longer shown
                await old.remove()
            if len(fresh) > len(shown):  # keys shown now, after the others as compose has them
                await self.mount_all(fresh[len(shown):])


def _same_kind(new: object, old: object) -> bool:
    """A freshly built key and the one shown in its place, of one type, both with every
    attribute copied, and classes alike but for being dimmed."""
    if type(new) is not type(old) or not all(hasattr(new, name) and hasattr(old, name)
                                             for name in _STATE):
        return False
    classes: frozenset[str] = getattr(new, "classes", frozenset()) - {DISABLED}
    return classes <= getattr(old, "classes", frozenset())
