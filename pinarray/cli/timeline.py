"""Pictures of one trial's schedule: a text timeline for the terminal, a PNG with matplotlib."""

from __future__ import annotations

from typing import IO

import numpy as np

from pinarray.plan import PlannedTrial
from pinarray.protocol import Protocol
from pinarray.protocol.seam import paradigm_named
from pinarray.schedule import TrialSchedule


def describe_trial(planned: PlannedTrial) -> str:
    c = planned.condition
    what = paradigm_named(c.paradigm).describe(c)
    kind = "practice" if planned.practice else f"block {planned.block}"
    return f"trial {planned.trial} ({kind}): {c.stimulus}, {what}"


def _lifted_ranges(schedule: TrialSchedule, protocol: Protocol, pin: int) -> list[tuple[int, int]]:
    """[start, stop) spans in ns during which the pin's target is away from rest."""
    targets = schedule.targets
    mask = targets.pin == pin
    times, positions = targets.time_ns[mask], targets.position_steps[mask]
    rest = protocol.device.calibration(pin).rest_steps
    spans = []
    for i, (time_ns, position) in enumerate(zip(times.tolist(), positions.tolist(), strict=True)):
        if position != rest:
            stop = times[i + 1] if i + 1 < len(times) else schedule.end_ns
            spans.append((time_ns, int(stop)))
    return spans


def text_timeline(
    protocol: Protocol, planned: PlannedTrial, schedule: TrialSchedule, width: int
) -> str:
    """One line per active pin; '#' where the pin is lifted during that column's time slice."""
    end_ns = max(schedule.end_ns, 1)
    lines = [
        describe_trial(planned),
        f"{end_ns / 1e9:g} s, one column = {end_ns / width / 1e6:.3g} ms",
    ]
    for pin in schedule.active_pins:
        cells = np.zeros(width, dtype=bool)
        for start, stop in _lifted_ranges(schedule, protocol, pin):
            a = start * width // end_ns
            b = max(a + 1, -(-stop * width // end_ns))
            cells[a:b] = True
        lines.append(f"pin {pin:>2} |" + "".join("#" if c else "." for c in cells) + "|")
    lines.append(f"{len(schedule.pulses)} pulses, {len(schedule.targets)} target changes")
    return "\n".join(lines)


def draw_timeline(
    protocol: Protocol, planned: PlannedTrial, schedule: TrialSchedule, stream: IO[bytes]
) -> None:
    """The commanded position of each active pin over time, as PNG bytes written to ``stream``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pins = schedule.active_pins
    fig, axes = plt.subplots(
        len(pins), 1, sharex=True, figsize=(9, 0.8 + 0.7 * len(pins)), squeeze=False
    )
    for ax, pin in zip(axes[:, 0], pins, strict=True):
        rest = protocol.device.calibration(pin).rest_steps
        mask = schedule.targets.pin == pin
        times = np.concatenate(([0], schedule.targets.time_ns[mask], [schedule.end_ns])) / 1e9
        positions = np.concatenate(([rest], schedule.targets.position_steps[mask], [rest]))
        ax.step(times, positions, where="post", lw=1)
        ax.set_ylabel(f"pin {pin}", rotation=0, ha="right", va="center")
        ax.set_yticks([])
    axes[-1, 0].set_xlabel("time from stimulus onset (s)")
    fig.suptitle(describe_trial(planned))
    fig.tight_layout()
    try:
        fig.savefig(stream, format="png", dpi=110)
    finally:
        plt.close(fig)
