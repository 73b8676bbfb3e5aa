"""What every simulated subject shares: its model read from ``--observer``, and how subjects of a
population differ.

A paradigm's room models its own subject (`pinarray.analysis.seam.ParadigmAnalysis.observer`);
the model's numbers are set on the command line as ``default`` or ``name=value`` overrides
(`parse_overrides`: each name once, written as a protocol writes its numbers). Subjects of a
population differ by normal offsets on a logit (or log) scale, drawn from the subject's seed
first (`draw_offsets`), so the same seed is the same subject.

A population is calibrated so that its *average subject's* rates are the model's: a rate's
logit centre is solved so that the mean over subjects (Gauss-Hermite quadrature) is the target
(`centre`), and each subject's rate is that centre shifted by its offset (`shifted`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import fields, replace
from functools import cache
from typing import Any, TypeVar

import numpy as np

from pinarray.errors import PinArrayError
from pinarray.protocol.yaml_nodes import exact_number

QUADRATURE_NODES = 40  # Gauss-Hermite nodes for averages over subjects
LOGIT_LIMIT = 30.0  # expit(30) = 1 - 1e-13: keeps a subject's rates strictly inside (0, 1)

Model = TypeVar("Model")


def observer_number(item: str, text: str) -> float:
    """The number of an ``--observer`` item ``name=text``, written as a protocol writes its
    numbers (ASCII decimal, ``1/3``; not ``1_000``, ``inf`` or ``1e400``)."""
    try:
        return float(exact_number(text))
    except ValueError as problem:
        raise PinArrayError(f"observer: {quoted(item)}: {problem}") from None


def quoted(item: str, limit: int = 60) -> str:
    """An item as a message quotes it, cut to ``limit`` characters ("..." marking the cut)."""
    shown = repr(item.strip())
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."


def observer_items(spec: str) -> list[tuple[str, str, str]]:
    """``name=value,...`` as (item, name, value text), each name once."""
    found: list[tuple[str, str, str]] = []
    for item in spec.split(","):
        name, equals, text = (part.strip() for part in item.partition("="))
        if not equals:
            raise PinArrayError(f"observer: {quoted(item)}: expected name=number, or 'default'")
        if any(name == seen for _, seen, _ in found):
            raise PinArrayError(f"observer: {quoted(name)} is given twice; give each parameter "
                                "once")
        found.append((item, name, text))
    return found


def parse_overrides(spec: str, model: Model, what: str,
                    names: Iterable[str] | None = None) -> Model:
    """``model`` (a frozen dataclass of numbers) with the ``name=value`` overrides of
    ``spec`` (``default``: as it is); a name it does not have is refused, naming ``what``."""
    if spec.strip() in ("", "default"):
        return model
    known = sorted(names if names is not None
                   else (f.name for f in fields(model)))  # type: ignore[arg-type]
    changes: dict[str, Any] = {}
    for item, name, text in observer_items(spec):
        if name not in known:
            raise PinArrayError(f"observer: unknown parameter {quoted(name)} for {what}; expected "
                                f"one of {', '.join(known)}")
        changes[name] = observer_number(item, text)
    return replace(model, **changes)  # type: ignore[type-var]


def draw_offsets(rng: np.random.Generator, sd: float, count: int) -> tuple[float, ...]:
    """One subject's ``count`` offsets (normal, SD ``sd``); nothing is drawn when ``sd`` is 0."""
    if sd == 0:
        return (0.0,) * count
    return tuple(float(u) for u in rng.normal(0.0, sd, count))


def expit(x: float) -> float:
    x = min(max(x, -LOGIT_LIMIT), LOGIT_LIMIT)
    return 1 / (1 + math.exp(-x))


def shifted(mean: float, top: float, centre_: float, offset: float) -> float:
    """A subject's rate on (0, top) whose population mean is ``mean``; ends stay put."""
    if mean <= 0 or mean >= top:
        return mean
    return top * expit(centre_ + offset)


@cache
def hermite(nodes: int = QUADRATURE_NODES) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights for the mean of f(Z), Z standard normal: sum(w * f(z))."""
    x, w = np.polynomial.hermite.hermgauss(nodes)
    return math.sqrt(2) * x, w / math.sqrt(math.pi)


def centre(share: float, sd: float) -> float:
    """The logit centre m with E[expit(m + sd * Z)] = share, Z standard normal."""
    if share <= 0 or share >= 1:
        return 0.0  # unused: `shifted` keeps a rate at 0 or at its top where it is
    if sd == 0:
        return math.log(share / (1 - share))
    z, w = hermite(QUADRATURE_NODES)
    low, high = -2 * LOGIT_LIMIT, 2 * LOGIT_LIMIT
    for _ in range(100):  # the mean rises with m, so bisection finds it
        middle = (low + high) / 2
        mean = float(w @ (1 / (1 + np.exp(-np.clip(middle + sd * z, -700, 700)))))
        low, high = (middle, high) if mean < share else (low, middle)
    return (low + high) / 2


def check_fraction(name: str, value: float) -> None:
    """A model's probability: a fraction from 0 to 1."""
    if not 0 <= value <= 1:
        raise PinArrayError(f"observer: {name} must be a fraction from 0 to 1, found {value}")
