"""Finding the servos on a bus: a broadcast ping, else a sweep of ids, then a look again at ids
that were silent.

What the first command of a bring-up (`pinarray servos scan`) and `pinarray.find_servo_ports`
do: nothing but PINGs and register reads; torque and goals stay as they were. The scan takes
a `FeetechBus` opened without the playback handshake and returns values; the commands print
them.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum

from pinarray.errors import BusError
from pinarray.hardware.driver import PortLost, Telemetry
from pinarray.hardware.feetech.bringup import (
    RETURN_DELAY_UNIT_US,
    SWEEP_TIMEOUT_NS,
    ServoFailure,
)
from pinarray.hardware.feetech.feetech import PATIENCE_GROWTH, FeetechBus
from pinarray.hardware.feetech.registers import MAX_SERVO_ID, Register

# A sweep of at most this many given ids looks again at the silent ones (a whole 4x4 array).
LOOK_AGAIN_IDS = 16
# A full sweep looks a third time at this many silent ids beside those that answered, or
# fewer: an array's two ends, and one or two a busy host lost.
LOOK_TWICE_IDS = 4
# ... and again, each time four times longer, while looking again finds someone (a busy host),
# up to 4**LONGEST_LOOK times a first PING's wait.
LONGEST_LOOK = 3
# Looking again waits in all at most this many times as long as the sweep did, a round at
# most once as long (or, where that is more, as long as `LOOK_AGAIN_IDS` ids each looked at
# four times longer): a full scan then waits at most three sweeps' time, however many answers
# the bus loses. A round that would overrun its share waits less per id, down to the sweep's
# own wait, and then looks at as many ids as fit, those the broadcast ping heard and those
# nearest the servos found first (docs/rig/bring-up.md says why).
LOOK_AGAIN_SWEEPS = 2

Progress = Callable[[int, int, tuple[int, ...]], object]


@dataclass(frozen=True)
class LookingAgain:
    """How far looking again has got: ``servo_id`` is about to be pinged, the ``done + 1``-th
    of the ``count`` ids of this round, each waited for at most ``wait_ns``; ``found_ids``
    answered so far."""

    servo_id: int
    done: int
    count: int
    wait_ns: int
    found_ids: tuple[int, ...]


class ScanMethod(StrEnum):
    """How a scan found its servos."""

    BROADCAST = "broadcast ping"
    SWEEP = "sweep"


class SweepReason(StrEnum):
    """Why a scan pinged every id: what its broadcast ping heard (and the sweep then found)."""

    NONE = ""  # the broadcast ping sufficed, or the ids were given
    SILENCE = "nothing answered a broadcast ping"
    # Garbled bytes, and the sweep found several servos: their answers overlapped.
    COLLIDED = "answers to a broadcast ping collided: several servos answer"
    # Garbled bytes, and the sweep found one servo or none: they cannot say which.
    GARBLED = ("answers to a broadcast ping came garbled: one servo's answers damaged, or "
               "several servos' colliding")
    # Clean answers, but asked again it heard others (or late bytes between): some are lost.
    CHANGED = "a broadcast ping asked again heard other answers: some come late or are lost"


@dataclass(frozen=True)
class ServoFound:
    """A servo that answered a scan, with what bring-up wants to know about it."""

    servo_id: int
    model_number: int
    firmware: tuple[int, int]  # major, minor
    return_delay_us: int
    telemetry: Telemetry


@dataclass(frozen=True)
class ScanResult:
    """Who answered, and how they were found.

    Attributes
    ----------
    method : ScanMethod
        A clean broadcast ping, or a sweep of ids.
    found : tuple of ServoFound
        The servos that answered, in id order.
    unreadable : tuple of ServoFailure
        Servos that answered (a PING, or the broadcast ping) but could not be read, each
        with what went wrong.
    swept_ids : tuple of int
        The ids a sweep pinged (empty for a broadcast ping).
    sweep_reason : SweepReason
        Why a sweep of every id was needed.
    """

    method: ScanMethod
    found: tuple[ServoFound, ...]
    unreadable: tuple[ServoFailure, ...]
    swept_ids: tuple[int, ...] = ()
    sweep_reason: SweepReason = SweepReason.NONE

    @property
    def servo_ids(self) -> tuple[int, ...]:
        return tuple(sorted([s.servo_id for s in self.found]
                            + [u.servo_id for u in self.unreadable]))


def scan(bus: FeetechBus, ids: Sequence[int] | None = None,
         timeout_ns: int = SWEEP_TIMEOUT_NS, progress: Progress | None = None,
         still_wanted: Callable[[], object] | None = None,
         looking_again: Callable[[LookingAgain], object] | None = None) -> ScanResult:
    """Find the servos on the bus: a broadcast ping, else a sweep of ids.

    Parameters
    ----------
    bus : FeetechBus
        Opened without the handshake.
    ids : sequence of int, optional
        Sweep exactly these ids; when they are an array's worth or fewer (`LOOK_AGAIN_IDS`),
        look again, four times longer, at those that did not answer (a busy host can hold an
        answer past a quiet host's wait); a sweep of more looks again only at silent ids in
        the gaps of those that answered and just beside them, once more, four times longer
        again, when those are few (`LOOK_TWICE_IDS`) or the last look found someone (up to
        `LONGEST_LOOK`), each round waiting at most as long as the sweep, in all at most
        `LOOK_AGAIN_SWEEPS` times as long. Progress is said once more when looking again
        found someone.

        Default: a broadcast ping, which finds a lone servo (a new one) at once, asked again
        listening longer when nothing answers it, and asked again listening longer to be
        believed when it answers cleanly (a late answer would hide a servo behind the others'
        clean ones). When nothing answers, several answers collide or asked again they
        differ, every id 0-252 is swept; the ids the broadcast ping heard are looked at
        again first, and when nobody answers the sweep though the broadcast ping heard
        someone (garbled bytes will do), every id is looked at again.
    timeout_ns : int
        How long to wait for each id's PING answer in a sweep, in nanoseconds.
    progress : callable, optional
        ``progress(servo_id, last_id, found_ids)`` after each id of a sweep; it may raise to
        stop the sweep (e.g. `pinarray.stop.Stopped`).
    still_wanted : callable, optional
        Called before each ping that is not a sweep's first of its id (the broadcast asked
        again, every look again); it may raise to stop the scan as ``progress`` may.
    looking_again : callable, optional
        ``looking_again(LookingAgain(...))`` before each ping of a look again (after
        ``still_wanted``): a round may last seconds, and says no ``progress`` until it ends.
    """
    def check() -> None:
        if still_wanted is not None:
            still_wanted()

    reason = SweepReason.NONE
    look_again = ids is not None and len(ids) <= LOOK_AGAIN_IDS
    heard = _Heard(frozenset(), 0, 0, settled=False)
    if ids is None:
        heard = _broadcast(bus, check)
        if heard.settled:
            models = {i: bus.ping(i) for i in sorted(heard.servo_ids)}
            found, unreadable = _details(bus, models, heard.servo_ids)
            return ScanResult(ScanMethod.BROADCAST, found, unreadable)
        reason = (SweepReason.GARBLED if heard.garbled_bytes else
                  SweepReason.CHANGED if heard.servo_ids or heard.late_bytes else
                  SweepReason.SILENCE)
        ids = range(MAX_SERVO_ID + 1)
    ids = tuple(ids)
    models = {}
    for servo_id in ids:
        models[servo_id] = bus.ping_within(servo_id, timeout_ns)
        if progress is not None:
            progress(servo_id, ids[-1], tuple(i for i, m in models.items() if m is not None))
    if _look_again(bus, ids, models, timeout_ns, look_again, heard, check, looking_again) \
            and progress is not None:  # the sweep's last word: who answered in the end
        progress(ids[-1], ids[-1], _answered(models))
    found, unreadable = _details(bus, models, heard.servo_ids)
    if reason is SweepReason.GARBLED and len(found) + len(unreadable) > 1:
        reason = SweepReason.COLLIDED
    return ScanResult(ScanMethod.SWEEP, found, unreadable, ids, reason)


@dataclass(frozen=True)
class _Heard:
    """What a scan's broadcast pings heard, all together."""

    servo_ids: frozenset[int]  # in well-formed status packets
    garbled_bytes: int  # that were no status packet
    late_bytes: int  # that came after a ping had stopped listening, before the next
    settled: bool  # the last two heard the same ids, cleanly: who answers

    @property
    def someone(self) -> bool:
        """Something answered, were it only garbled bytes: a servo is there."""
        return bool(self.servo_ids or self.garbled_bytes or self.late_bytes)


def _broadcast(bus: FeetechBus, check: Callable[[], None]) -> _Heard:
    """Broadcast PINGs: asked again, listening longer, when nothing answers, and asked again
    to be believed when answers come back clean."""
    answers = [bus.broadcast_ping()]
    if not answers[-1].servo_ids and not answers[-1].garbled_bytes:
        # Silence: asked once more, listening longer, as `FeetechBus.ping` retries one (a
        # busy host can hold a lone servo's answer past a quiet host's wait). Far cheaper
        # than the sweep of every id that silence would otherwise cost.
        check()
        answers.append(bus.broadcast_ping(patience=PATIENCE_GROWTH))
    first = answers[-1]
    settled, late_bytes = False, 0
    if first.clean and first.servo_ids:
        # Believed only when asked again, listening longer, it comes back the same: the
        # answer of a servo that came late (held past the wait, or lost) would else leave the
        # others' answers clean, and that servo unfound. Its late bytes, drained before the
        # next ping, tell as much as its answer would.
        check()
        stale_bytes = bus.link.counters.stale_bytes
        again = bus.broadcast_ping(patience=PATIENCE_GROWTH)
        answers.append(again)
        late_bytes = bus.link.counters.stale_bytes - stale_bytes
        settled = (again.clean and not late_bytes
                   and set(again.servo_ids) == set(first.servo_ids))
    # (A status packet from an id no servo can have, 253 up, is no servo's.)
    servo_ids = frozenset(i for a in answers for i in a.servo_ids if i <= MAX_SERVO_ID)
    return _Heard(servo_ids, sum(a.garbled_bytes for a in answers), late_bytes,
                  settled and bool(servo_ids))


def _look_again(bus: FeetechBus, ids: tuple[int, ...], models: dict[int, int | None],
                timeout_ns: int, every_silent_id: bool, heard: _Heard,
                check: Callable[[], None],
                looking_again: Callable[[LookingAgain], object] | None) -> bool:
    """Ping silent ids again, longer, in rounds (see `scan`), filling ``models`` in; whether
    looking again found anyone. Which ids: `_to_look_at_again`."""
    # In first-PING waits: what all the rounds together may wait, and what one round may.
    budget = max(LOOK_AGAIN_SWEEPS * len(ids), LOOK_AGAIN_IDS * PATIENCE_GROWTH)
    round_budget = max(len(ids), LOOK_AGAIN_IDS * PATIENCE_GROWTH)
    patience = PATIENCE_GROWTH
    found_anyone = False
    for look in range(1, LONGEST_LOOK + 1):
        silent = _to_look_at_again(models, every_silent_id, heard)
        most = min(budget, round_budget)
        wait = max(1, min(patience, most // max(1, len(silent))))
        silent = silent[:most // wait]
        if not silent:
            break
        budget -= wait * len(silent)
        for done, servo_id in enumerate(silent):
            check()
            if looking_again is not None:
                looking_again(LookingAgain(servo_id, done, len(silent), wait * timeout_ns,
                                           _answered(models)))
            models[servo_id] = bus.ping_within(servo_id, wait * timeout_ns)
        answered = any(models[i] is not None for i in silent)
        found_anyone = found_anyone or answered
        # Looking again found someone: the host is busy, so the rest may be lost answers too.
        rest = _to_look_at_again(models, every_silent_id, heard)
        few = len(rest) <= LOOK_TWICE_IDS and look == 1
        if every_silent_id or not (answered or few):
            break
        patience *= PATIENCE_GROWTH
    return found_anyone


def _answered(models: dict[int, int | None]) -> tuple[int, ...]:
    return tuple(i for i, model in models.items() if model is not None)


def _to_look_at_again(models: dict[int, int | None], every_silent_id: bool,
                      heard: _Heard) -> list[int]:
    """The ids swept that have not answered; in a full sweep only those in the gaps of the
    ids that answered or just beside them (an array's ids run together, so that is where a
    busy host lost one; as more answer, the ids beside them join), nearest those first, and
    before them any whose answer the broadcast ping heard. When nobody answered the sweep
    but someone answered the broadcast ping (were it only garbled bytes), every id: a servo
    is there, its answer to the sweep lost."""
    silent = [i for i, model in models.items() if model is None]
    if every_silent_id:
        return silent
    answered = sorted(_answered(models))
    if not answered:
        return sorted(silent, key=lambda i: (i not in heard.servo_ids, i)) \
            if heard.someone else []
    near = [i for i in silent
            if i in heard.servo_ids or answered[0] - 1 <= i <= answered[-1] + 1]
    return sorted(near, key=lambda i: (i not in heard.servo_ids, _distance(i, answered), i))


def _distance(servo_id: int, answered: list[int]) -> int:
    """How far ``servo_id`` is from the nearest of ``answered`` (sorted, not empty)."""
    at = bisect_left(answered, servo_id)
    return min(abs(answered[k] - servo_id) for k in (at - 1, at) if 0 <= k < len(answered))


def _details(bus: FeetechBus, models: dict[int, int | None], heard_ids: frozenset[int]
             ) -> tuple[tuple[ServoFound, ...], tuple[ServoFailure, ...]]:
    """What bring-up wants to know of each servo that answered; a servo the broadcast ping
    heard that answered no PING of its id is unreadable, not left out."""
    found, unreadable = [], []
    for servo_id, model in sorted(models.items()):
        if model is None:
            if servo_id in heard_ids:
                unreadable.append(ServoFailure(
                    servo_id, "answered a broadcast ping, but no PING of its id"))
            continue
        try:
            firmware, _ = bus.read(servo_id, Register.FIRMWARE_MAJOR, 2)
            delay, _ = bus.read(servo_id, Register.RETURN_DELAY_TIME)
            delay_us = delay[0] * RETURN_DELAY_UNIT_US
            bus.note_return_delay(servo_id, delay_us)
            (telemetry,) = bus.read_telemetry((servo_id,))
        except PortLost:
            raise
        except BusError as problem:
            unreadable.append(ServoFailure(
                servo_id, f"answers a PING, but reading it failed: {problem}"))
            continue
        found.append(ServoFound(servo_id, model, (firmware[0], firmware[1]), delay_us, telemetry))
    return tuple(found), tuple(unreadable)
