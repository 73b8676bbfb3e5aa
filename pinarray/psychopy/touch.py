"""One stimulus on the pin array as a PsychoPy trial sees it: the flip it started on, what was
delivered, and the columns that go into the experiment's data and log.

A touch armed on a flip is checked against that flip: PsychoPy's stamp of the flip that
actually happened beside the pins' measured onset. One whose onset lay further from its flip
than the protocol's delivery tolerance was not delivered as scheduled, in the data and the
log, with the reason; as is one whose flip was never made (it was cancelled, nothing moved).
One the array failed (the bus failing mid-stimulus, the port lost) goes into the data as not
delivered, with the error, before `Touch.addData` raises it: the row is never left without
its touch.
"""

from __future__ import annotations

import math
import numbers
import threading
import weakref
from collections.abc import Collection
from typing import Any, Protocol

from psychopy import logging

import pinarray
from pinarray.psychopy.timeline import NS_PER_S, Timeline

__all__ = ["Touch"]

NS_PER_MS = 1_000_000

COLUMN_GROUPS = ("delivered", "onset", "strokes")
"""The groups of a touch's data columns, beside its stimulus (always written): ``delivered``
(the verdict, its reason, how it ended, the delivery record), ``onset`` (the flip and the
onset on PsychoPy's clock, the onset from the flip, the first write's lateness), ``strokes``
(each moving pin's commanded and achieved stroke and its lag)."""


class DataSink(Protocol):
    """What a touch's data goes into: PsychoPy's `ExperimentHandler` (or a `TrialHandler`)."""

    def addData(self, name: str, value: object) -> None: ...


class Touch:
    """A stimulus presented on the array, now or on a screen flip (`PinArrayDevice.present`,
    `PinArrayDevice.armOnFlip`).

    Times are on PsychoPy's clock (`psychopy.logging.defaultClock`, the clock its flips and
    log are stamped on), in seconds; the array's own are kept in ns.
    """

    def __init__(self, stimulus: pinarray.Presentable, timeline: Timeline,
                 result: pinarray.Armed | pinarray.Delivery, clock_zero_s: float,
                 on_flip: bool) -> None:
        self._stimulus = stimulus
        self._on_flip = on_flip
        self._timeline = timeline
        self._result = result
        self._clock_zero_s = clock_zero_s  # defaultClock's time base at its last reset
        self._flip_ns: int | None = None
        self._flip_stamp: dict[str, float] = {}
        self._window: weakref.ref[Any] | None = None  # the window armed on
        self._never_flipped = False
        self._cut_by = ""  # what the device cut it for (PsychoPy quitting, its window closing)
        self._failure: pinarray.PinArrayError | None = None  # what the array raised, if it did

    @property
    def stimulus(self) -> str:
        """The stimulus's name in the protocol; a stimulus built in code, as the code that
        builds it (``Pattern(pins=[6, 7], train=Train(...))``)."""
        stimulus = self._stimulus
        condition = stimulus.condition if isinstance(stimulus, pinarray.PlannedTrial) else stimulus
        return condition.stimulus if isinstance(condition, pinarray.Condition) else repr(condition)

    @property
    def armed_on_flip(self) -> bool:
        """Whether it was armed on a flip (`PinArrayDevice.armOnFlip`), not presented at once."""
        return self._on_flip

    @property
    def onsetTime(self) -> float | None:
        """The stimulus's time zero on PsychoPy's clock, in s, as the pins played it; None
        until it has started (or for one that never did)."""
        delivery = self._delivery_if_ended()
        if delivery is None or isinstance(delivery.ending, pinarray.NotStarted):
            return None
        return self._timeline.to_psychopy_s(delivery.onset_ns) - self._clock_zero_s

    @property
    def flipTime(self) -> float | None:
        """When the flip it was armed on happened, on PsychoPy's clock, in s (PsychoPy's own
        stamp of that flip); None before that flip, or for a stimulus presented at once."""
        if self._flip_ns is None:
            return None
        return self._timeline.to_psychopy_s(self._flip_ns) - self._clock_zero_s

    @property
    def onsetFromFlip(self) -> float | None:
        """The pins' measured onset (their time zero as played) relative to PsychoPy's stamp
        of the flip it was armed on, in s (positive: the pins started after the screen
        changed); None until both are known."""
        delivery = self._delivery_if_ended()
        if (self._flip_ns is None or delivery is None
                or isinstance(delivery.ending, pinarray.NotStarted)):
            return None
        return (delivery.onset_ns - self._flip_ns) / NS_PER_S

    @property
    def done(self) -> bool:
        """Whether the stimulus has ended (played, cut, never started, or failed: `wait`
        then raises)."""
        return not isinstance(self._result, pinarray.Armed) or self._result.done

    def wait(self, timeout: float | None = None) -> pinarray.Delivery:
        """Wait until the stimulus has ended; what the array delivered (`delivered` and
        `problem` add the check against the flip).

        A touch armed on a flip that was not made before this call is cancelled (the flip can
        no longer come while the script waits here): not delivered, nothing moved.

        Parameters
        ----------
        timeout : float or None
            Wait at most this long, in s (None: until it has ended).

        Raises
        ------
        pinarray.PinArrayError
            What stopped it (the bus failed mid-stimulus: `pinarray.PlaybackAborted`), a wait
            that timed out, a timeout that is not a number of seconds from 0.
        """
        if timeout is not None and (
                isinstance(timeout, bool) or not isinstance(timeout, numbers.Real)
                or not math.isfinite(timeout) or not 0 <= timeout <= threading.TIMEOUT_MAX):
            raise pinarray.PinArrayError(
                f"Touch.wait: timeout: expected a number of seconds from 0, or None, found "
                f"{_shown(timeout)} ({type(timeout).__name__})")
        result = self._result
        if not isinstance(result, pinarray.Armed):
            return result
        if self._on_flip and self._flip_ns is None and not result.done:
            self._never_flipped = True
            result.cancel()
        return result.result(timeout)

    @property
    def failure(self) -> pinarray.PinArrayError | None:
        """What the array raised for this stimulus (the bus failing mid-stimulus, the port
        lost), once it has ended; None when it raised nothing. Waits until it has ended."""
        self._ended()
        return self._failure

    def _ended(self) -> pinarray.Delivery | None:
        """`wait`, the array's error kept (`failure`) rather than raised: None then."""
        if self._failure is not None:
            return None
        try:
            return self.wait()
        except pinarray.PinArrayError as error:
            if not self.done:
                raise  # not an outcome of the stimulus (a wait refused): the caller's
            self._failure = error
            return None

    @property
    def delivered(self) -> bool:
        """Delivered as scheduled: the array delivered it (`pinarray.Delivery.delivered`) and,
        armed on a flip, its onset lay within the protocol's delivery tolerance of that flip.
        Waits until the stimulus has ended."""
        return not self.problem

    @property
    def problem(self) -> str:
        """Empty when delivered; otherwise what went wrong first, in words. Waits until the
        stimulus has ended."""
        delivery = self._ended()
        if delivery is None:
            return f"the array failed: {self._failure}"
        if not self.armed_on_flip:
            return delivery.problem
        if self._never_flipped:
            return ("its flip was never made (call win.flip() after armOnFlip): cancelled, "
                    "nothing moved")
        if self._cut_by and isinstance(delivery.ending, pinarray.Cut):
            return f"cut short by {self._cut_by}"
        from_flip = self.onsetFromFlip
        tolerance_ns = delivery.record.tolerance_ns
        if from_flip is not None and abs(from_flip) * NS_PER_S > tolerance_ns:
            return (f"missed its flip: the pins started {abs(from_flip) * 1e3:.1f} ms "
                    f"{'after' if from_flip > 0 else 'before'} the screen changed, beyond the "
                    f"delivery tolerance of {tolerance_ns / NS_PER_MS:g} ms")
        return delivery.problem

    def columns(self, name: str = "touch",
                groups: Collection[str] = COLUMN_GROUPS) -> dict[str, object]:
        """The touch as data columns, ``name.`` before each: the stimulus, and the ``groups``
        asked for (`COLUMN_GROUPS`, all by default): ``onset``, the flip and the onset on
        PsychoPy's clock (s), the onset from the flip (ms); ``delivered``, the verdict and its
        reason, how it ended, the delivery record; ``strokes``, each moving pin's measured
        stroke (``name.pin6.achieved_steps``, ...). Waits until the stimulus has ended.

        Raises
        ------
        pinarray.PinArrayError
            A group that is not one of `COLUMN_GROUPS`.
        """
        unknown = sorted(set(groups) - set(COLUMN_GROUPS))
        if unknown:
            raise pinarray.PinArrayError(
                f"Touch.columns: expected groups among {', '.join(COLUMN_GROUPS)}, found "
                f"{', '.join(map(repr, unknown))}")
        delivery = self._ended()
        if delivery is None:
            return {f"{name}.{key}": value for key, value in self._failed_columns(groups).items()}
        record = delivery.record
        from_flip = self.onsetFromFlip
        values: dict[str, object] = {"stimulus": self.stimulus}
        if "onset" in groups:
            values |= {
                "flip_t": self.flipTime,
                "onset_t": self.onsetTime,
                "onset_from_flip_ms": None if from_flip is None else from_flip * 1e3,
                "onset_write_late_ms": delivery.onset_write_late_ns / NS_PER_MS,
            }
        if "delivered" in groups:
            values |= {
                "delivered": self.delivered,
                "problem": self.problem,
                "ending": _ending(delivery.ending, self._cut_by),
                "goal_changes": record.scheduled,
                "confirmed": record.confirmed,
                "healed": record.healed,
                "missing": record.missing,
                "latest_ms": record.worst_lateness_ns / NS_PER_MS,
                "tolerance_ms": record.tolerance_ns / NS_PER_MS,
            }
        for stroke in delivery.strokes if "strokes" in groups else ():
            values |= {
                f"pin{stroke.pin}.commanded_steps": stroke.commanded_steps,
                f"pin{stroke.pin}.achieved_steps": stroke.achieved_steps,
                f"pin{stroke.pin}.lag_ms": None if stroke.lag_ns is None
                else stroke.lag_ns / NS_PER_MS,
            }
        return {f"{name}.{key}": value for key, value in values.items()}

    def addData(self, experiment: DataSink, name: str = "touch",
                columns: Collection[str] = COLUMN_GROUPS) -> pinarray.Delivery:
        """Wait until the stimulus has ended, then add its `columns` (the ``columns`` groups:
        all by default) to ``experiment`` (an `ExperimentHandler`: the current trial's row)
        and a line to PsychoPy's log (a warning too when it was not delivered as scheduled).

        Returns
        -------
        pinarray.Delivery
            What the array delivered.

        Raises
        ------
        pinarray.PinArrayError
            What the array raised for it (`failure`: the bus failed mid-stimulus, the port was
            lost), once its columns are in the row, saying it was not delivered and why.
        """
        delivery = self._ended()
        for column, value in self.columns(name, columns).items():
            experiment.addData(column, value)
        logging.data(self.describe(name))
        if not self.delivered:
            logging.warning(f"{name}: {self.stimulus} not delivered as scheduled: "
                            f"{self.problem}")
        if delivery is None:
            assert self._failure is not None
            raise self._failure
        return delivery

    def describe(self, name: str = "touch") -> str:
        """One line for the log: the stimulus, its onset from the flip, what was delivered."""
        delivery = self._ended()
        if delivery is None:
            return f"{name}: {self.stimulus}: NOT DELIVERED: {self.problem}"
        from_flip = self.onsetFromFlip
        when = ("presented at once" if not self.armed_on_flip
                else "never started" if from_flip is None
                else f"onset {from_flip * 1e3:+.2f} ms from its flip")
        problem = self.problem  # the record's summary says its own
        verdict = (f": NOT DELIVERED AS SCHEDULED: {problem}"
                   if problem and problem != delivery.problem else "")
        return f"{name}: {self.stimulus}, {when}; {delivery.record.summary()}{verdict}"

    def _failed_columns(self, groups: Collection[str]) -> dict[str, object]:
        """The columns of a stimulus the array failed: not delivered, the error, nothing
        measured."""
        values: dict[str, object] = {"stimulus": self.stimulus}
        if "onset" in groups:
            values |= {"flip_t": self.flipTime, "onset_t": None, "onset_from_flip_ms": None,
                       "onset_write_late_ms": None}
        if "delivered" in groups:
            values |= {"delivered": False, "problem": self.problem, "ending": "failed",
                       "goal_changes": None, "confirmed": None, "healed": None,
                       "missing": None, "latest_ms": None, "tolerance_ms": None}
        return values

    def _delivery_if_ended(self) -> pinarray.Delivery | None:
        result = self._result
        if not isinstance(result, pinarray.Armed):
            return result
        if not result.done or self._failure is not None:
            return None
        try:
            return result.result()
        except pinarray.PinArrayError as error:
            self._failure = error
            return None

    def _flipped(self) -> None:
        """Called by the window right after the flip it was armed on (`win.callOnFlip`),
        after PsychoPy stamped that flip into ``_flip_stamp`` (`win.timeOnFlip`): the pins
        start now."""
        result = self._result
        if isinstance(result, pinarray.Armed) and not result.done:
            try:
                result.start()
            except pinarray.PinArrayError:
                pass  # cancelled or stopped meanwhile (a quit): its result says so
        self._flip_ns = self._timeline.to_array_ns(self._flip_stamp["flip"] + self._clock_zero_s)


def _ending(ending: pinarray.Ending, cut_by: str) -> str:
    match ending:
        case pinarray.Cut(at_ns=_, by=by):
            return f"cut by {cut_by or by}"
        case pinarray.NotStarted():
            return "not started"
    return "played"


def _shown(value: object) -> str:
    """A value as a message shows it: its repr, shortened (one that fails, named)."""
    try:
        text = repr(value)
    except Exception:  # the value's own repr failed: the message must not
        return f"<a {type(value).__name__} whose repr fails>"
    return text if len(text) <= 60 else text[:57] + "..."
