"""What one presentation delivered, and how it ended: played to its end, cut short, or never
started. A stimulus is delivered as scheduled or reported as not delivered, with the reason:
never silently different; and the notices each tells the logger ``"pinarray"``."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from pinarray.errors import PinArrayError
from pinarray.hardware.delivery import DeliveryRecord
from pinarray.hardware.motion import PinStroke
from pinarray.player.playback import PlaybackReport

__all__ = ["Cut", "Delivery", "Ending", "NotStarted", "Played"]


@dataclass(frozen=True)
class Played:
    """Played to its scheduled end (whether every goal change arrived in time is the
    `DeliveryRecord`'s to say)."""


@dataclass(frozen=True)
class Cut:
    """Cut short while it played: by `PinArray.stop`, `Armed.cancel`, `PinArray.close` or an
    error leaving the ``with`` block; the pins went to rest and torque off.

    Attributes
    ----------
    at_ns : int
        When the cut was asked for, on the array's clock, in ns.
    by : str
        What cut it, in words (``"stop()"``, ``"leaving the with block on KeyboardInterrupt"``).
    """

    at_ns: int
    by: str


@dataclass(frozen=True)
class NotStarted:
    """Never started: nothing moved.

    Attributes
    ----------
    reason : str
        Why, in words: its onset had passed before playback could begin (the host stalled),
        or it was cancelled before it started.
    """

    reason: str


Ending = Played | Cut | NotStarted
"""How a presentation ended: `Played`, `Cut` or `NotStarted`."""

PLAYED = Played()

log = logging.getLogger("pinarray")
log.addHandler(logging.NullHandler())  # a library's notices: shown where the script says


@dataclass(frozen=True)
class Delivery:
    """What one presentation delivered.

    Attributes
    ----------
    onset_ns : int
        The stimulus's time zero on the array's clock (`PinArray.now_ns`), in ns: the time
        it was armed for; for one presented at once, the lead after the call; for one armed
        to start on `Armed.start`, when the player took the start. Every goal change of the
        schedule is due at this plus its own time. (For one that never started, the time it
        was armed for, or when it was given up.)
    duration_ns : int
        The stimulus's length as scheduled, in ns.
    onset_write_late_ns : int
        How late the write of the stimulus's first frame (at or after time zero) returned
        after its deadline, in ns: the host's side of the onset (0 for a stimulus without
        frames, or one that never started).
    record : DeliveryRecord
        What reached the servos: goal changes scheduled, confirmed as sent, healed (written
        again, then confirmed), missing; the latest any arrived; the protocol's tolerance; and
        the moving pins' measured strokes where the servos report their positions. For one
        cut short or never started, no goal change counts as confirmed and its problem says why.
    ending : Ending
        How it ended: `Played` to its end, `Cut` short (when, by what) or `NotStarted`.
    stimulus : str
        What was presented, in full: a protocol's condition as its paradigm names it
        (``seed_train on pin 6 at 10 Hz``); a stimulus built in code as the code that builds
        it, every value given (``Pattern(pins=[6, 7], train=Train(frequency_hz=5, ...))``).
    """

    onset_ns: int
    duration_ns: int
    onset_write_late_ns: int
    record: DeliveryRecord
    ending: Ending = PLAYED
    stimulus: str = ""

    @property
    def delivered(self) -> bool:
        """Delivered as scheduled and specified: played to its end, every goal change reached
        its servo within the protocol's tolerance, and, where the servos report their
        positions, every moving pin was measured in every cycle and made its stroke."""
        return isinstance(self.ending, Played) and self.record.delivered

    @property
    def problem(self) -> str:
        """Empty when delivered; otherwise the first thing that went wrong, in plain words."""
        return self.record.problem

    @property
    def strokes(self) -> tuple[PinStroke, ...]:
        """Each moving pin's measured stroke (empty where the servos report no position:
        hobby PWM servos; and for a stimulus cut short or never started)."""
        return () if self.record.strokes is None else self.record.strokes.pins

    def stroke(self, pin: int) -> PinStroke:
        """The measured stroke of ``pin``.

        Raises
        ------
        PinArrayError
            When the pin did not move in this stimulus or its motion was not measured; a pin
            that is not a number from 1 to 16.
        """
        from pinarray.api import arguments

        pin = arguments.pin("Delivery.stroke", pin)
        for stroke in self.strokes:
            if stroke.pin == pin:
                return stroke
        moved = ", ".join(str(s.pin) for s in self.strokes) or "none"
        raise PinArrayError(f"pin {pin}: no stroke measured in this stimulus (pins measured: "
                            f"{moved})")


def unplayed(onset_ns: int, duration_ns: int, changes: int, tolerance_ns: int,
             ending: Cut | NotStarted, problem: str, stimulus: str) -> Delivery:
    """The delivery of a stimulus cut short or never started: not delivered, saying why."""
    record = DeliveryRecord(scheduled=changes, confirmed=0, healed=0, missing=changes,
                            worst_lateness_ns=0, tolerance_ns=tolerance_ns, problem=problem)
    return Delivery(onset_ns, duration_ns, 0, record, ending, stimulus)


def onset_write_late_ns(report: PlaybackReport) -> int:
    """How late the write of the first frame at or after time zero returned, in ns."""
    at_or_after = np.flatnonzero(report.scheduled_ns >= 0)
    if not len(at_or_after):
        return 0
    first = int(at_or_after[0])
    return int(report.sent_ns[first] - report.scheduled_ns[first])


def tell(url: str, stimulus: str, delivery: Delivery, report: PlaybackReport) -> None:
    """The notices of one stimulus played: its verdict, writes healed, retries."""
    record = delivery.record
    if record.healed:
        log.info("%s: %s: %d goal write(s) lost on the wire were written again and confirmed",
                 url, stimulus, record.healed)
    if report.retries:
        log.info("%s: %s: %d transient bus failure(s) retried", url, stimulus, report.retries)
    if delivery.delivered:
        log.info("%s: %s: %s", url, stimulus, record.summary())
    else:
        log.warning("%s: %s: %s", url, stimulus, record.summary())
