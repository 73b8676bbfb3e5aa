"""What a forked copy of a process that drives servos lets go of at once.

A lab's script may fork after opening an array (``multiprocessing`` workers, a recorder
process, ``os.fork``). The copy inherits every descriptor: the player process's channel, the
port and its lock. Were it to keep them, the player would not hear of its parent's end until
the last copy ended (the stimulus played on, torque held), and the port would stay held. So
each owner of such descriptors registers here (`let_go_in_forks`) and, in the copy, right
after the fork, its ``_forked`` method blanks them (`blank_descriptors`) and makes it inert:
only the process that opened the array drives it. (The port's lock lets go of itself:
`pinarray.hardware.port_lock`.)
"""

from __future__ import annotations

import os
import weakref
from typing import Protocol

from pinarray.hardware.port_lock import blank_descriptors

__all__ = ["FORKED_COPY", "blank_descriptors", "let_go_in_forks"]

# Why a forked copy is refused what only the original may do.
FORKED_COPY = ("this process is a forked copy of the one that opened the array: only that one "
               "plays on it")


class LetsGoInForks(Protocol):
    def _forked(self) -> None:
        """Called in a forked copy, right after the fork: let go of what the original owns."""


_owners: weakref.WeakSet[LetsGoInForks] = weakref.WeakSet()


def let_go_in_forks(owner: LetsGoInForks) -> None:
    """Call ``owner._forked()`` in every forked copy of this process (for as long as the
    owner lives here)."""
    _owners.add(owner)


def _in_forked_child() -> None:
    for owner in list(_owners):
        owner._forked()
    _owners.clear()


os.register_at_fork(after_in_child=_in_forked_child)
