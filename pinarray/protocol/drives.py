"""Which pins a trial drives, and whether any pin is driven twice at once. Pure Python.

Kept apart from `pinarray.schedule` (numpy) so that `pinarray validate`, which needs only
these checks, starts without loading numpy.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

from pinarray.errors import PinArrayError
from pinarray.protocol.model import Condition, PinDrive, Protocol, Train


def check_no_overlap(drives: Sequence[PinDrive]) -> None:
    """Refuse drives that play two trains on one pin at the same time.

    A train may start at the very nanosecond the previous one on its pin ends.
    """
    by_pin: dict[int, list[PinDrive]] = {}
    for drive in drives:
        by_pin.setdefault(drive.pin, []).append(drive)
    for pin, pin_drives in by_pin.items():
        pin_drives.sort(key=lambda d: d.delay_ns)
        for before, after in itertools.pairwise(pin_drives):
            if before.delay_ns + before.train.duration_ns > after.delay_ns:
                raise PinArrayError(
                    f"expected one train at a time on each pin, found pin {pin} driven twice at "
                    f"once: a train from {before.delay_ns / 1e6:g} ms lasting "
                    f"{before.train.duration_ns / 1e6:g} ms overlaps one starting at "
                    f"{after.delay_ns / 1e6:g} ms; lengthen the SOA or shorten the train"
                )


def trial_drives(protocol: Protocol, condition: Condition) -> tuple[PinDrive, ...]:
    """The pin drives a design condition asks for (its paradigm says how its stimulus plays it)."""
    try:
        return protocol.design.paradigm.drives(protocol.stimulus(condition.stimulus), condition)
    except PinArrayError as problem:
        raise PinArrayError(f"{protocol.source}: {problem}") from None


def pulse_slots(train: Train) -> int:
    """How many pulse slots start within the train's signal: what compiling it allocates.

    Counted as `pinarray.schedule` counts them (phase included); the pulses that also end
    within the signal may be one or two fewer.
    """
    offset_slots = train.phase * train.pulses_per_cycle
    first = -int(offset_slots)
    last = int(train.duration_ns / train.slot_ns - offset_slots)
    return max(0, last + 1 - first)
