"""Protocols for scripts: read and check one, draw its trial plan, find one of its conditions.

A protocol is the one checked description of an experiment (device, stimuli, design): every
condition its design holds was checked when it was read (each pin can follow its train, no pin
is driven twice at once, every goal lies within the pins' limits), so whatever a script
presents from it is safe to play. A stimulus the protocol does not hold is written into it.
"""

from __future__ import annotations

import functools
from fractions import Fraction
from os import PathLike, fspath

from pinarray.api import arguments
from pinarray.errors import PinArrayError
from pinarray.plan import PlannedTrial, TrialPlan, make_plan
from pinarray.protocol.model import Condition, Protocol
from pinarray.protocol.seam import paradigm_named

__all__ = ["Condition", "PlannedTrial", "Protocol", "TrialPlan", "find_condition",
           "load_protocol", "plan_trials", "protocol_from_text"]


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


def protocol_from_text(text: str, *, name: str = "<text>") -> Protocol:
    """Read a protocol written in a script (YAML text) and check it whole, as a file is.

    A separate call from `load_protocol`, so that a path is never read as YAML nor YAML as a
    path.

    Parameters
    ----------
    text : str
        The protocol, as a file would hold it (at most 1 MiB).
    name : str
        What its problems are located in (``<text>:LINE:COL: ...``) and what the protocol's
        `Protocol.source` says; lines count from the text's first. A ``response:`` file the
        device names is found from the current directory.

    Returns
    -------
    Protocol
        As `load_protocol` gives it for a file holding ``text`` (its ``sha256`` the text's,
        in UTF-8, line ends as ``\n``).

    Raises
    ------
    ProtocolErrors
        Every problem found, each a `ProtocolError` at ``name:line:col``, as a file's are.
    PinArrayError
        A text that is not a str, or larger than 1 MiB; a name that is empty or not a str.
    """
    from pinarray.protocol.load import MAX_PROTOCOL_BYTES, parse_protocol

    call = "protocol_from_text"
    text = arguments.text(call, "text", text)
    name = arguments.text(call, "name", name)
    if not name.strip() or "\n" in name:
        arguments.refuse(call, "name", "a name for the text on one line, not empty", name)
    if len(text.encode("utf-8", "surrogatepass")) > MAX_PROTOCOL_BYTES:
        raise PinArrayError(f"{call}: text: expected a protocol of at most "
                            f"{MAX_PROTOCOL_BYTES:,} bytes, found {len(text):,} characters")
    return parse_protocol(text.replace("\r\n", "\n").replace("\r", "\n"), name)


# The protocol of an array opened without one (`open_array()`, simulated servos only): the
# device every protocol without a device section has (the 4x4 grid, STS3215 servos at their
# datasheet speed, the seed's calibration: rest at 2048 steps, a 2 ms pulse lifting the pin
# 114 steps), for stimuli built in code. Its one condition is there because a protocol has a
# design; a script presents its own stimuli.
DEFAULTS = """\
protocol: defaults
description: pinarray's default device, for stimuli built in code (no protocol given)
stimuli:
  tap: {frequency_hz: 5, duration_s: 1}
design: {paradigm: localisation, stimulus: tap, pins: [1], frequencies_hz: [5]}
"""


@functools.cache
def default_protocol() -> Protocol:
    """The protocol an array opened without one plays its stimuli on (`DEFAULTS`)."""
    from pinarray.protocol.load import parse_protocol

    return parse_protocol(DEFAULTS, "<pinarray's defaults>")


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
