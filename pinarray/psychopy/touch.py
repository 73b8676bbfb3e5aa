"""One stimulus on the pin array as a PsychoPy trial sees it: the flip it was armed on, what
was delivered, and the columns that go into the experiment's data and log."""

from __future__ import annotations

from typing import Protocol

from psychopy import logging

import pinarray
from pinarray.psychopy.timeline import NS_PER_S, Timeline

__all__ = ["Touch"]

NS_PER_MS = 1_000_000


class DataSink(Protocol):
    """What a touch's data goes into: PsychoPy's `ExperimentHandler` (or a `TrialHandler`)."""

    def addData(self, name: str, value: object) -> None: ...


class Touch:
    """A stimulus presented on the array, now or on a screen flip (`PinArrayDevice.present`,
    `PinArrayDevice.armOnFlip`).

    Times are on PsychoPy's clock (`psychopy.logging.defaultClock`, the clock its flips and
    log are stamped on), in seconds; the array's own are kept in ns.
    """

    def __init__(self, stimulus: pinarray.Presentable, onset_ns: int, timeline: Timeline,
                 result: pinarray.Armed | pinarray.Delivery, clock_zero_s: float) -> None:
        self._stimulus = stimulus
        self._onset_ns = onset_ns
        self._timeline = timeline
        self._result = result
        self._clock_zero_s = clock_zero_s  # defaultClock's time base at its last reset
        self._flip_ns: int | None = None
        self._flip_stamp: dict[str, float] = {}

    @property
    def stimulus(self) -> str:
        """The stimulus's name in the protocol."""
        stimulus = self._stimulus
        condition = stimulus.condition if isinstance(stimulus, pinarray.PlannedTrial) else stimulus
        return condition.stimulus

    @property
    def onsetTime(self) -> float:
        """The stimulus's time zero on PsychoPy's clock, in s: the flip it was armed on, as
        predicted when it was armed."""
        return self._timeline.to_psychopy_s(self._onset_ns) - self._clock_zero_s

    @property
    def flipTime(self) -> float | None:
        """When the flip it was armed on happened, on PsychoPy's clock, in s (PsychoPy's own
        stamp of that flip); None before that flip, or for a stimulus presented at once."""
        if self._flip_ns is None:
            return None
        return self._timeline.to_psychopy_s(self._flip_ns) - self._clock_zero_s

    @property
    def onsetFromFlip(self) -> float | None:
        """The tactile onset relative to the flip it was armed on, in s (positive: the pins
        started after the screen changed); None until that flip."""
        if self._flip_ns is None:
            return None
        return (self._onset_ns - self._flip_ns) / NS_PER_S

    @property
    def done(self) -> bool:
        """Whether the stimulus has played (or failed: `wait` then raises)."""
        return not isinstance(self._result, pinarray.Armed) or self._result.done

    def wait(self, timeout: float | None = None) -> pinarray.Delivery:
        """Wait until the stimulus has played; what it delivered.

        Parameters
        ----------
        timeout : float or None
            Wait at most this long, in s (None: until it has played).

        Raises
        ------
        pinarray.PinArrayError
            What stopped it (the bus failed, the device closed first), or a wait that timed out.
        """
        result = self._result
        return result.result(timeout) if isinstance(result, pinarray.Armed) else result

    def columns(self, name: str = "touch") -> dict[str, object]:
        """The touch as data columns, ``name.`` before each: the stimulus, the flip and the
        onset on PsychoPy's clock (s), the onset from the flip (ms), the delivery record, and
        each moving pin's measured stroke (``name.pin6.achieved_steps``, ...). Waits until
        the stimulus has played."""
        delivery = self.wait()
        record = delivery.record
        from_flip = self.onsetFromFlip
        values: dict[str, object] = {
            "stimulus": self.stimulus,
            "flip_t": self.flipTime,
            "onset_t": self.onsetTime,
            "onset_from_flip_ms": None if from_flip is None else from_flip * 1e3,
            "onset_write_late_ms": delivery.onset_write_late_ns / NS_PER_MS,
            "delivered": delivery.delivered,
            "problem": delivery.problem,
            "goal_changes": record.scheduled,
            "confirmed": record.confirmed,
            "healed": record.healed,
            "missing": record.missing,
            "latest_ms": record.worst_lateness_ns / NS_PER_MS,
            "tolerance_ms": record.tolerance_ns / NS_PER_MS,
        }
        for stroke in delivery.strokes:
            values |= {
                f"pin{stroke.pin}.commanded_steps": stroke.commanded_steps,
                f"pin{stroke.pin}.achieved_steps": stroke.achieved_steps,
                f"pin{stroke.pin}.lag_ms": None if stroke.lag_ns is None
                else stroke.lag_ns / NS_PER_MS,
            }
        return {f"{name}.{key}": value for key, value in values.items()}

    def addData(self, experiment: DataSink, name: str = "touch") -> pinarray.Delivery:
        """Wait until the stimulus has played, then add its `columns` to ``experiment`` (an
        `ExperimentHandler`: the current trial's row) and a line to PsychoPy's log.

        Returns
        -------
        pinarray.Delivery
            What it delivered.
        """
        delivery = self.wait()
        for column, value in self.columns(name).items():
            experiment.addData(column, value)
        logging.data(self.describe(name))
        if not delivery.delivered:
            logging.warning(f"{name}: {self.stimulus} not delivered as scheduled: "
                            f"{delivery.problem}")
        return delivery

    def describe(self, name: str = "touch") -> str:
        """One line for the log: the stimulus, its onset from the flip, what was delivered."""
        delivery = self.wait()
        from_flip = self.onsetFromFlip
        when = ("presented at once" if from_flip is None
                else f"onset {from_flip * 1e3:+.2f} ms from its flip")
        return f"{name}: {self.stimulus}, {when}; {delivery.record.summary()}"

    def _flipped(self) -> None:
        """Called by the window right after the flip it was armed on (`win.callOnFlip`),
        after PsychoPy stamped that flip into ``_flip_stamp`` (`win.timeOnFlip`)."""
        self._flip_ns = self._timeline.to_array_ns(self._flip_stamp["flip"] + self._clock_zero_s)

