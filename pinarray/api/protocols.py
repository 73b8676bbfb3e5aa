"""Protocols for scripts: read and check one, draw its trial plan, find one of its conditions.

A protocol is the one checked description of an experiment (device, stimuli, design): every
condition its design holds was checked when it was read (each pin can follow its train, no pin
is driven twice at once, every goal lies within the pins' limits), so whatever a script
presents from it is safe to play. A stimulus the protocol does not hold is written into it.
"""

from __future__ import annotations

from fractions import Fraction
from os import PathLike, fspath

from pinarray.api import arguments
from pinarray.errors import PinArrayError
from pinarray.plan import PlannedTrial, TrialPlan, make_plan
from pinarray.protocol.model import Condition, Protocol
from pinarray.protocol.seam import paradigm_named

__all__ = ["Condition", "PlannedTrial", "Protocol", "TrialPlan", "find_condition",
           "load_protocol", "plan_trials"]


def load_protocol(path: str | PathLike[str]) -> Protocol:
    """Read a protocol file and check it whole.

    Parameters
    ----------
    path : str or path-like
        A YAML protocol (``protocols/README.md`` describes the format; at most 1 MiB).

    Returns
    -------
    Protocol
        The validated, frozen protocol.

    Raises
    ------
    ProtocolErrors
        Every problem found, each a `ProtocolError` located at ``file:line:col``
        (``str(error)`` lists them one per line, as ``pinarray validate`` prints them).
    """
    from pinarray.protocol.load import load_protocol as load

    return load(fspath(arguments.path("load_protocol", "path", path)))


def plan_trials(protocol: Protocol, seed: int | None = None) -> TrialPlan:
    """The protocol's trial plan: which condition each trial presents, in which order.

    The same protocol and seed always give the same plan, the one ``pinarray plan`` prints and
    a run with that seed presents.

    Parameters
    ----------
    protocol : Protocol
        From `load_protocol`.
    seed : int or None
        0 to 2^63 - 1; None: the protocol's own seed, else a new one (the plan records it).

    Returns
    -------
    TrialPlan
        Its trials numbered 1..N in plan order, practice trials first.
    """
    return make_plan(arguments.protocol("plan_trials", protocol), arguments.seed("plan_trials", seed))


def find_condition(protocol: Protocol, *, pin: int | None = None,
                   frequency_hz: float | Fraction | None = None,
                   stimulus: str | None = None) -> Condition:
    """The one condition of the protocol's design that matches every filter given.

    Parameters
    ----------
    protocol : Protocol
        From `load_protocol`.
    pin : int or None
        A localisation condition's pin, numbered as the subject sees them (1 bottom-left).
    frequency_hz : float, Fraction or None
        A localisation condition's train frequency, in Hz.
    stimulus : str or None
        The stimulus's name in the protocol (a wave's name finds its apparent-motion condition).

    Returns
    -------
    Condition
        Ready to be presented (`PinArray.present`).

    Raises
    ------
    PinArrayError
        When no condition or more than one matches, naming the protocol and what it holds;
        a filter of the wrong kind (a pin outside 1-16, a frequency that is not a finite
        number above 0).
    """
    call = "find_condition"
    protocol = arguments.protocol(call, protocol)
    pin = arguments.optional_pin(call, pin)
    frequency_hz = arguments.frequency_hz(call, frequency_hz)
    stimulus = arguments.optional_text(call, "stimulus", stimulus)
    if isinstance(frequency_hz, float):
        frequency_hz = Fraction(repr(frequency_hz))  # 0.1 Hz is 1/10, as the protocol reads it
    wanted = {"pin": pin, "frequency_hz": frequency_hz, "stimulus": stimulus}
    given = {name: value for name, value in wanted.items() if value is not None}
    found = [c for c in protocol.design.conditions
             if all(getattr(c, name, None) == value for name, value in given.items())]
    if len(found) == 1:
        return found[0]
    asked = ", ".join(f"{name} {arguments.shortened(str(value))}"
                      for name, value in given.items()) or "no filter"
    held = "; ".join(describe_condition(c) for c in (found or protocol.design.conditions)[:8])
    if not found:
        raise PinArrayError(f"{protocol.source}: no condition of the design has {asked} "
                            f"(it holds: {held}{' ...' if len(protocol.design.conditions) > 8 else ''})")
    raise PinArrayError(f"{protocol.source}: {len(found)} conditions have {asked} ({held}"
                        f"{' ...' if len(found) > 8 else ''}): name more of pin, frequency_hz, "
                        "stimulus")


def describe_condition(condition: Condition) -> str:
    """A condition in the lab's words, as its paradigm says it: ``seed_train on pin 6 at 10 Hz``."""
    return paradigm_named(condition.paradigm).title(condition)
