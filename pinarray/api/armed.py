"""A stimulus armed on an open array: to start at a time, or on a cue (`Armed.start`); it plays
in the background while the script goes on, and can be cancelled at any moment."""

from __future__ import annotations

from concurrent import futures
from concurrent.futures import Future
from typing import TYPE_CHECKING

from pinarray.api import arguments
from pinarray.api.delivery import Cut, Delivery
from pinarray.api.stimuli import described
from pinarray.errors import PinArrayError
from pinarray.player.playback import Onset, OnsetAt
from pinarray.player.process import StartCue

if TYPE_CHECKING:
    from pinarray.api.array import PinArray, Stimulus

__all__ = ["Armed"]


class Armed:
    """A stimulus armed to start at a time, or on a cue (`start`): it plays in the background
    while the script goes on (draws a frame, flips a screen); `result` waits for what it
    delivered, `cancel` cuts it short.

    Made by `PinArray.arm`.
    """

    def __init__(self, array: PinArray, stimulus: Stimulus, onset: Onset | StartCue) -> None:
        self._array = array
        self._stimulus = stimulus
        self._onset = onset
        self._future: Future[Delivery] = Future()
        self._cut: Cut | None = None  # what cut it, once something has
        self._runner: int | None = None  # the thread playing it
        self._started_ns: int | None = None  # when `start` was called

    @property
    def onset_ns(self) -> int | None:
        """The time zero it is armed for, on the array's clock, in ns; None for one armed to
        start on `start` (its `Delivery.onset_ns` says when it did)."""
        return self._onset.onset_ns if isinstance(self._onset, OnsetAt) else None

    @property
    def done(self) -> bool:
        """Whether it has ended: played, cut short, never started, or failed (`result` then
        raises)."""
        return self._future.done()

    def result(self, timeout_s: float | None = None) -> Delivery:
        """Wait until it has ended; what it delivered.

        A stimulus that could not start in time, or was cut short, is returned as not
        delivered (its `Delivery.ending` says why), not raised.

        A stimulus armed to start on `start`, not started yet, cannot end while this waits
        without a limit in the thread that would start it: that is refused at once (a thread
        that waits while another starts it gives a ``timeout_s``).

        Parameters
        ----------
        timeout_s : float or None
            Wait at most this long, in seconds of the host's time (None: until it ends).

        Raises
        ------
        PlaybackAborted
            The bus failed while it played (the message says where; the pins were put to
            rest first).
        PinArrayError
            A wait that timed out; a stimulus waiting for its `start` waited for without a
            limit.
        """
        timeout = arguments.timeout_s("Armed.result", timeout_s)
        cue = self._onset
        if (timeout is None and isinstance(cue, StartCue) and not cue.given
                and not cue.withdrawn and not self.done):
            raise PinArrayError(f"Armed.result: the stimulus {self._described()} waits for "
                                "Armed.start(), which has not been called: start it first, or "
                                "cancel() it (or give a timeout_s while another thread starts "
                                "it)")
        # Waited for here, not by `result(timeout)`: its TimeoutError could not be told from
        # one a script's watchdog raises (its signal handler's, meanwhile), which is the script's.
        if not futures.wait([self._future], timeout).done:
            raise PinArrayError(f"the stimulus {self._described()} has not ended after "
                                f"{timeout_s} s")
        return self._future.result()

    def start(self) -> None:
        """Start a stimulus armed without an onset, now: its time zero is the moment the
        player takes the start, a fraction of a millisecond after this call on an idle
        machine (`Delivery.onset_ns` says when). Cheap enough for a screen's flip callback.

        Raises
        ------
        PinArrayError
            One armed for a time (it starts then), or one started, cancelled or ended already.
        """
        cue = self._onset
        if not isinstance(cue, StartCue):
            raise PinArrayError(f"start: the stimulus {self._described()} is armed for a time: "
                                "it starts then")
        started_ns = self._array.now_ns()
        if not cue.give():
            raise PinArrayError(f"start: the stimulus {self._described()} has started, been "
                                "cancelled or ended already")
        self._started_ns = started_ns

    def cancel(self) -> None:
        """Cut it short, or keep it from starting: every pin to rest and torque off, as
        `PinArray.stop` (nothing happens to one that has ended). Its `result` is then a
        delivery whose `Delivery.ending` says it was cut (`Cut`) or never started."""
        self._array._cancel(self)

    def _began(self, at_ns: int, playing_from_ns: int | None) -> bool:
        """Whether it had begun moving pins by ``at_ns`` (the array's clock)."""
        match self._onset:
            case StartCue():
                return self._onset.given
            case OnsetAt(onset_ns=onset_ns):
                return onset_ns <= at_ns
        return playing_from_ns is not None and playing_from_ns <= at_ns

    def _described(self) -> str:
        when = f" armed for {self.onset_ns} ns" if self.onset_ns is not None else ""
        return f"{described(self._stimulus)}{when}"
