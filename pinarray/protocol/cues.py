"""Cues a stimulus should not give away: how long it lasts, when that differs between answers.

If the conditions a subject must tell apart last different times, duration alone can give
the answer (the seed's no-wave motion stimulus lasts 0.90 s, its waves 0.75 s). Validation
warns about it without refusing the protocol: the lab may have reasons. Pure; no numpy.
"""

from __future__ import annotations

from fractions import Fraction

from pinarray.protocol.drives import trial_drives
from pinarray.protocol.model import Condition, Protocol
from pinarray.units import NS_PER_S


def stimulus_duration_ns(protocol: Protocol, condition: Condition) -> int:
    """How long a condition's stimulus lasts: from onset until its last train ends, in ns."""
    return max((d.delay_ns + d.train.duration_ns for d in trial_drives(protocol, condition)),
               default=0)


def duration_cues(protocol: Protocol) -> list[str]:
    """Warnings (one line each, without the file name) when durations differ between answers.

    Conditions with the same correct answer may differ (a pin at several frequencies); those
    with different answers must not, or the duration tells them apart.
    """
    design = protocol.design
    durations: dict[object, set[int]] = {}
    names: dict[int, list[str]] = {}
    for condition in design.conditions:
        cue = design.paradigm.cue(condition, design)
        if cue is None:
            continue  # its paradigm plays every answer's stimulus in every trial
        answer, label = cue
        duration_ns = stimulus_duration_ns(protocol, condition)
        durations.setdefault(answer, set()).add(duration_ns)
        if label not in names.setdefault(duration_ns, []):
            names[duration_ns].append(label)
    if len({frozenset(d) for d in durations.values()}) <= 1:
        return []
    listing = "; ".join(f"{', '.join(labels)} {duration_ns / NS_PER_S:.3f} s"
                        for duration_ns, labels in sorted(names.items(), reverse=True))
    return [f"the stimuli a subject must tell apart last different times ({listing}): duration "
            "alone could give the answer away; make them last equally long"]


def cut_lifts(protocol: Protocol) -> list[str]:
    """Warnings (one line each) for trains whose signal ends inside a lift: the pin is lowered
    before the lift's time is up, so it may not finish its stroke, and a trial whose pin falls
    short is judged not delivered. A paradigm whose trials play one train a pin, whose last
    lift no later change measures, is not warned of (`ParadigmDesign.warns_of_cut_lifts`)."""
    if not protocol.design.paradigm.warns_of_cut_lifts:
        return []
    found: dict[tuple, str] = {}
    for condition in protocol.design.conditions:
        for drive in trial_drives(protocol, condition):
            train = drive.train
            period_ns = NS_PER_S / train.frequency_hz
            into = (train.duration_ns / period_ns - train.phase) % 1  # of a cycle, at the end
            lift = Fraction(train.up_pulses, train.pulses_per_cycle)
            if 0 < into < lift:
                key = (train.frequency_hz, train.duration_ns)
                found.setdefault(key, (
                    f"{condition.stimulus} at {float(train.frequency_hz):g} Hz ends "
                    f"{float(into * period_ns) / 1e6:.1f} ms into a lift of "
                    f"{float(lift * period_ns) / 1e6:.1f} ms: the pin is lowered before it may "
                    "finish its stroke; give the signal a whole number of half cycles"))
    return list(found.values())
