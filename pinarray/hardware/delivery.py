"""Was a stimulus delivered as scheduled? One verdict per trial, from every goal change's fate.

A sync write gets no reply, so a goal lost on the wire would go unnoticed. The player reads
each changed goal back from its servo in the slack after the frame: a change is *confirmed*
when the servo holds it, *healed* when it had to be written again (acknowledged) and then
held, and *missing* when neither happened before the servo's next change or the trial's end.
A trial is delivered when nothing is missing and every change reached its servo within the
protocol's tolerance; otherwise it is reported as not delivered, with the reason in words.
Where the servos report their positions, the pins' measured motion joins the verdict: a trial
whose pin moved less than the protocol's share of its commanded stroke
(`pinarray.hardware.motion`) was not delivered as specified either.
A `PreparedTrial` is what is to be delivered: every frame encoded for the wire before onset,
and the goal changes in it. Pure values and bookkeeping: no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING

from pinarray.units import NS_PER_MS

if TYPE_CHECKING:
    from pinarray.hardware.motion import PinTrace, TrialStrokes

# A goal change must reach its servo within this of its scheduled time unless the protocol
# says otherwise (device: delivery: tolerance_ms).
DEFAULT_TOLERANCE_NS = 10 * NS_PER_MS


class Fate(StrEnum):
    PENDING = "pending"
    CONFIRMED = "confirmed"
    HEALED = "healed"
    MISSING = "missing"


@dataclass(frozen=True)
class Change:
    """One scheduled goal change: which servo (and pin), to what, when (ns from onset)."""

    servo_id: int
    pin: int
    goal_steps: int
    time_ns: int


@dataclass(frozen=True)
class PreparedFrame:
    """One frame ready to send: its time from onset, its packet and the goals in it."""

    time_ns: int
    packet: bytes
    goals: tuple[tuple[int, int], ...]  # (servo id, goal in steps)
    first_change: int  # index of its first goal in `PreparedTrial.changes`


@dataclass(frozen=True)
class PreparedTrial:
    """A trial encoded for the wire before onset: frames, their goal changes and the end."""

    frames: tuple[PreparedFrame, ...]
    changes: tuple[Change, ...]
    end_ns: int
    pin_of_servo: dict[int, int]

    def write_window_ns(self) -> int | None:
        """How late a frame may be written and still take effect as scheduled, when the
        hardware sets such a limit (a PWM board's period); None: the protocol's tolerance
        alone decides."""
        return None


@dataclass(frozen=True)
class DeliveryRecord:
    """What reached the servos in one trial.

    Attributes
    ----------
    scheduled, confirmed, healed, missing : int
        Goal changes the schedule holds, and how many of them were confirmed on their servo
        as first sent, confirmed after being written again, or never confirmed.
    worst_lateness_ns : int
        The latest any delivered change reached its servo after its scheduled time, in ns
        (host write time plus wire time; healed changes count from their re-write).
    tolerance_ns : int
        How late a change may reach its servo and still count as delivered as scheduled.
    problem : str
        Empty when delivered; otherwise the first thing that went wrong, in plain words.
    strokes : TrialStrokes or None
        The moving pins' measured strokes; None where the servos report no position (PWM).
    """

    scheduled: int
    confirmed: int
    healed: int
    missing: int
    worst_lateness_ns: int
    tolerance_ns: int
    problem: str = ""
    strokes: TrialStrokes | None = None

    @property
    def delivered(self) -> bool:
        """Delivered as scheduled (and, where measured, as specified): no problem found."""
        return not self.problem

    def summary(self) -> str:
        """One clause for a report line."""
        text = (f"{self.confirmed + self.healed}/{self.scheduled} goal changes confirmed "
                f"({self.healed} healed, {self.missing} missing), "
                f"latest {self.worst_lateness_ns / NS_PER_MS:.1f} ms")
        worst = self.strokes.worst if self.strokes is not None else None
        if worst is not None:
            text += f", stroke {worst.achieved_steps}/{worst.commanded_steps} steps"
        return text if self.delivered else f"{text}: NOT DELIVERED AS SCHEDULED: {self.problem}"


class DeliveryLedger:
    """The fate of every goal change of one trial, filled in by the player as it learns them.

    Parameters
    ----------
    changes : sequence of Change
        Every goal change of the trial, in the order the frames send them.
    tolerance_ns : int
        See `DeliveryRecord.tolerance_ns`.
    """

    def __init__(self, changes: tuple[Change, ...], tolerance_ns: int):
        self.changes = changes
        self.tolerance_ns = tolerance_ns
        self.fates = [Fate.PENDING] * len(changes)
        self.lateness_ns = [0] * len(changes)
        self._first_missing: tuple[int, str] | None = None

    def confirm(self, index: int, lateness_ns: int, healed: bool) -> None:
        self.fates[index] = Fate.HEALED if healed else Fate.CONFIRMED
        self.lateness_ns[index] = lateness_ns

    def lose(self, index: int, why: str) -> None:
        self.fates[index] = Fate.MISSING
        if self._first_missing is None:
            self._first_missing = (index, why)

    def record(self, strokes: TrialStrokes | None = None) -> DeliveryRecord:
        """The trial's verdict; changes still pending count as missing (never confirmed).

        ``strokes``: the pins' measured motion, when the servos report it; a pin that fell
        short of the tolerance makes the trial not delivered as specified.
        """
        for index, fate in enumerate(self.fates):
            if fate is Fate.PENDING:
                self.lose(index, "no read-back confirmed it before the trial ended")
        counts = {fate: self.fates.count(fate) for fate in Fate}
        delivered = [i for i, f in enumerate(self.fates) if f in (Fate.CONFIRMED, Fate.HEALED)]
        worst = max((self.lateness_ns[i] for i in delivered), default=0)
        return DeliveryRecord(
            scheduled=len(self.changes),
            confirmed=counts[Fate.CONFIRMED],
            healed=counts[Fate.HEALED],
            missing=counts[Fate.MISSING],
            worst_lateness_ns=worst,
            tolerance_ns=self.tolerance_ns,
            problem=(self._problem(delivered, worst)
                     or (strokes.problem() if strokes is not None else "")),
            strokes=strokes,
        )

    def _problem(self, delivered: list[int], worst_ns: int) -> str:
        if self._first_missing is not None:
            index, why = self._first_missing
            missing = self.fates.count(Fate.MISSING)
            return (f"{missing} of {len(self.changes)} goal changes not confirmed on their servo; "
                    f"first: {self._describe(index)}: {why}")
        if worst_ns > self.tolerance_ns:
            late = [i for i in delivered if self.lateness_ns[i] > self.tolerance_ns]
            first = late[0]
            return (f"{len(late)} goal change(s) reached their servo later than the tolerance of "
                    f"{self.tolerance_ns / NS_PER_MS:g} ms; first: {self._describe(first)}, "
                    f"{self.lateness_ns[first] / NS_PER_MS:.1f} ms late")
        return ""

    def _describe(self, index: int) -> str:
        change = self.changes[index]
        return (f"pin {change.pin} (servo {change.servo_id}) to {change.goal_steps} steps at "
                f"{change.time_ns / 1e9:.3f} s")


@dataclass(frozen=True)
class Presentation:
    """A trial's stimulus as it was played: when its time zero was (clock ns), and delivered?"""

    onset_ns: int
    delivery: DeliveryRecord
    trace: tuple[PinTrace, ...] = ()  # the moving pins' sampled positions (none: not sampled)
