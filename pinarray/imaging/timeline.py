"""Scanner volumes as they arrive: numbered, judged against the TR, gaps filled in. Pure logic.

Triggers arrive at clock times (ns). The first ``dummy_volumes`` triggers are dummies; the next
one is the run's time zero. From then on each arrival is judged against the TR (given, or the
median interval seen so far):

- ``steps = round(interval / TR)`` volumes have passed since the previous one; when that is 2
  or more, the volumes between were *missed* (no trigger came) and are logged as such at the
  times the TR puts them;
- an arrival off the time the TR puts it by more than `tolerance_ns` is *irregular*;
- a trigger less than half a TR after the previous volume's is *extra* (a repeated character),
  not a new volume.

When the triggers stop, volumes keep being expected every TR: each one is logged missed once
half a TR has passed beyond it with no trigger (a later trigger would have been numbered after
it), so a stream that dies mid-run leaves its gap in the log and nothing waits on it.

Rows are final when returned: `VolumeTimeline.rows_until` returns each row once, in volume
order, and a later arrival never changes a row already returned.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field

from pinarray.journal.volumes import VolumeRow, VolumeStatus

# Irregular: off the TR's time by more than this, or by 5 % of a TR shorter than 0.2 s.
MAX_TOLERANCE_NS = 10_000_000


def tolerance_ns(tr_ns: int) -> int:
    """How far off its expected time a trigger may arrive and still be regular (ns)."""
    return min(tr_ns // 20, MAX_TOLERANCE_NS)


@dataclass
class VolumeTimeline:
    """The volumes of one scanner run, from trigger arrival times.

    Parameters
    ----------
    dummy_volumes : int
        Triggers logged but not counted before time zero.
    tr_ns : int or None
        The TR in ns; None: the median interval between the triggers received so far.
    """

    dummy_volumes: int
    tr_ns: int | None = None
    arrivals_ns: list[int] = field(default_factory=list)
    _rows: list[VolumeRow] = field(default_factory=list)
    _judged: int = 0  # arrivals turned into rows so far
    _returned: int = 0  # rows handed out by rows_until
    _highest: int = 0  # the highest volume number logged (received, or missed)
    _last_volume: int = 0  # number of the last volume received
    _last_volume_ns: int | None = None  # and when its trigger came
    _intervals_ns: list[int] = field(default_factory=list)

    # -- what arrived ---------------------------------------------------------------------------

    def arrive(self, at_ns: int) -> None:
        """A trigger came at ``at_ns`` (clock ns, not before the previous one)."""
        if self.arrivals_ns and at_ns < self.arrivals_ns[-1]:
            raise ValueError(f"trigger arrivals go forward: {at_ns} ns after {self.arrivals_ns[-1]}")
        self.arrivals_ns.append(at_ns)

    @property
    def seen(self) -> int:
        """Triggers received."""
        return len(self.arrivals_ns)

    @property
    def zero_ns(self) -> int | None:
        """The arrival of the first counted volume (the run's time zero), once it came."""
        if len(self.arrivals_ns) <= self.dummy_volumes:
            return None
        return self.arrivals_ns[self.dummy_volumes]

    def current_tr_ns(self) -> int | None:
        """The TR volumes are judged by now: the given one, or the median interval seen."""
        if self.tr_ns is not None:
            return self.tr_ns
        return round(statistics.median(self._intervals_ns)) if self._intervals_ns else None

    # -- the log ----------------------------------------------------------------------------------

    @property
    def rows(self) -> list[VolumeRow]:
        """Every row judged so far (returned by `rows_until` or not)."""
        return list(self._rows)

    def rows_until(self, now_ns: int) -> list[VolumeRow]:
        """Rows not yet returned: every arrival so far, and volumes missed by ``now_ns``.

        Nothing is returned before time zero (onsets are counted from it).
        """
        zero = self.zero_ns
        if zero is None:
            return []
        self._judge_arrivals(zero)
        self._trailing_missed(now_ns, zero)
        new = self._rows[self._returned:]
        self._returned = len(self._rows)
        return new

    def _judge_arrivals(self, zero_ns: int) -> None:
        while self._judged < len(self.arrivals_ns):
            self._judge(self.arrivals_ns[self._judged], zero_ns)
            self._judged += 1

    def _judge(self, at_ns: int, zero_ns: int) -> None:
        index = self._judged  # 0-based among triggers received
        dummy = index < self.dummy_volumes
        previous_ns = self._last_volume_ns
        if previous_ns is None:
            self._volume(1, at_ns, zero_ns, dummy, VolumeStatus.RECEIVED, None, None)
            return
        interval_ns = at_ns - previous_ns
        tr_ns = self.current_tr_ns()
        if tr_ns is None:  # the second trigger, and no TR given: nothing to judge it by yet
            self._intervals_ns.append(interval_ns)
            self._volume(self._last_volume + 1, at_ns, zero_ns, dummy, VolumeStatus.RECEIVED,
                         interval_ns, None)
            return
        steps = round(interval_ns / tr_ns)
        if steps == 0 and index > self.dummy_volumes:
            # Within half a TR of the last volume: a second character, not a new volume.
            self._rows.append(VolumeRow(self._last_volume, at_ns - zero_ns, False,
                                        VolumeStatus.EXTRA, interval_ns, interval_ns - tr_ns))
            return
        if index <= self.dummy_volumes:
            steps = 1  # before time zero each trigger is the next volume: nothing is inferred
        # A volume already logged missed keeps its row: a trigger for it that comes after the
        # log said so (only a thread's delay allows it) is the next volume, judged irregular.
        steps = max(steps, self._highest - self._last_volume + 1)
        for missed in range(self._highest - self._last_volume + 1, steps):
            self._missed(self._last_volume + missed, previous_ns + missed * tr_ns - zero_ns)
        deviation_ns = at_ns - (previous_ns + steps * tr_ns)
        status = (VolumeStatus.IRREGULAR if abs(deviation_ns) > tolerance_ns(tr_ns)
                  else VolumeStatus.RECEIVED)
        if steps == 1:
            self._intervals_ns.append(interval_ns)
        self._volume(self._last_volume + steps, at_ns, zero_ns, dummy, status, interval_ns,
                     deviation_ns)

    def _missed(self, number: int, onset_ns: int) -> None:
        self._rows.append(VolumeRow(number, onset_ns, False, VolumeStatus.MISSED))
        self._highest = number

    def _volume(self, number: int, at_ns: int, zero_ns: int, dummy: bool, status: VolumeStatus,
                interval_ns: int | None, deviation_ns: int | None) -> None:
        self._rows.append(VolumeRow(number, at_ns - zero_ns, dummy, status, interval_ns,
                                    deviation_ns))
        self._last_volume, self._last_volume_ns = number, at_ns
        self._highest = number

    def _trailing_missed(self, now_ns: int, zero_ns: int) -> None:
        tr_ns = self.current_tr_ns()
        last_ns = self._last_volume_ns
        if tr_ns is None or last_ns is None:
            return
        while True:
            expected_ns = last_ns + (self._highest + 1 - self._last_volume) * tr_ns
            if now_ns < expected_ns + tr_ns // 2:
                return
            self._missed(self._highest + 1, expected_ns - zero_ns)

    # -- where volumes are (for onsets locked to them) ------------------------------------------

    def counted_volume_ns(self, counted: int) -> int | None:
        """When counted volume ``counted`` (0 = time zero) arrived, if its trigger did (ns)."""
        zero = self.zero_ns
        if zero is None:
            return None
        self._judge_arrivals(zero)
        number = self.dummy_volumes + 1 + counted
        for row in reversed(self._rows):
            if row.volume == number and row.status is not VolumeStatus.MISSED and (
                    row.status is not VolumeStatus.EXTRA):
                return zero + row.onset_ns
            if row.volume < number:
                return None
        return None

    def expected_ns(self, counted: int) -> int | None:
        """When counted volume ``counted`` is due by the TR from the last volume received (ns)."""
        tr_ns, last_ns = self.current_tr_ns(), self._last_volume_ns
        if self.zero_ns is None or tr_ns is None or last_ns is None:
            return None
        return last_ns + (self.dummy_volumes + 1 + counted - self._last_volume) * tr_ns
