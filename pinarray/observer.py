"""A simulated subject, for piloting a protocol and testing the runner without people.

Localisation: a subject who feels the stimulus reports pin ``r`` for stimulated pin ``s``
with probability proportional to ``exp(-d(s, r) / sigma)``, where ``d`` is the distance
between the pins in grid pitches and ``sigma`` (the spatial spread) shrinks as frequency
rises. ``sigma`` is not given directly: it is solved, per anchor frequency, so that the mean
correct rate over the calibration pins equals the anchor's target, and interpolated in
log-log between anchors (held constant beyond them). Corner pins have fewer near neighbours
than edge pins, and edge pins fewer than centre pins, so the model localises corners best
and the centre worst without being told to; a per-pin acuity factor scales ``sigma`` for
single pins (the seed found pin 4 best localised).

Motion: on a wave trial the subject feels motion with probability ``motion_felt``; having
felt it, names the right direction with ``direction_given_felt``, says "unsure" with
``unsure_given_felt``, and otherwise names the wrong one. On a no-wave trial motion is felt
with ``no_wave_felt`` and the named direction is left or right with equal odds.

The defaults reproduce the seed's reported figures in expectation (section 9.7.1): 62.5 %
correct at 10 Hz, rising with frequency (the 3 and 5 Hz targets, 40 % and 50 %, are this
model's assumptions: the seed shows them only in a figure), error A the most frequent error
at every frequency, 77 % motion felt and 65 % of those naming the direction right.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from functools import cache

import numpy as np

from pinarray.errors import PinArrayError
from pinarray.grid import DEFAULT_GRID, Grid

MOTION_ANSWERS = ("none", "left", "right", "unsure")
_OPPOSITE = {"left": "right", "right": "left"}


@dataclass(frozen=True)
class ObserverModel:
    """Parameters of a simulated subject; probabilities are fractions in [0, 1].

    Parameters
    ----------
    correct_by_frequency : tuple of (frequency_hz, fraction)
        Anchors: expected fraction of localisation trials answered with the stimulated pin,
        averaged over ``calibration_pins``. Must rise with frequency.
    miss_rate : float
        Fraction of localisation trials on which nothing is felt (answer ``None``).
    pin_acuity : tuple of (pin, factor)
        Multiplies ``sigma`` for single pins; below 1 localises that pin better.
    calibration_pins : tuple of int, optional
        Pins the anchors average over; all pins of ``grid`` when empty.
    motion_felt, direction_given_felt, unsure_given_felt, no_wave_felt : float
        Motion-task probabilities, described in the module docstring.
    """

    correct_by_frequency: tuple[tuple[float, float], ...] = ((3.0, 0.40), (5.0, 0.50),
                                                             (10.0, 0.625))
    miss_rate: float = 0.0
    pin_acuity: tuple[tuple[int, float], ...] = ((4, 0.8),)
    calibration_pins: tuple[int, ...] = ()
    grid: Grid = DEFAULT_GRID
    motion_felt: float = 0.77
    direction_given_felt: float = 0.65
    unsure_given_felt: float = 0.10
    no_wave_felt: float = 0.30

    def __post_init__(self) -> None:
        # Tuples all the way down keep the model hashable, so its calibration is cached.
        object.__setattr__(self, "correct_by_frequency",
                           tuple((float(f), float(c)) for f, c in self.correct_by_frequency))
        object.__setattr__(self, "pin_acuity",
                           tuple((int(p), float(a)) for p, a in self.pin_acuity))
        object.__setattr__(self, "calibration_pins", tuple(self.calibration_pins))
        for name in ("miss_rate", "motion_felt", "direction_given_felt", "unsure_given_felt",
                     "no_wave_felt"):
            _check_fraction(name, getattr(self, name))
        if self.direction_given_felt + self.unsure_given_felt > 1:
            raise PinArrayError(
                "observer: direction_given_felt + unsure_given_felt must be at most 1, found "
                f"{self.direction_given_felt} + {self.unsure_given_felt}"
            )
        anchors = sorted(self.correct_by_frequency)
        if not anchors:
            raise PinArrayError("observer: correct_by_frequency needs at least one anchor")
        for frequency_hz, fraction in anchors:
            if not frequency_hz > 0:
                raise PinArrayError(
                    f"observer: anchor frequency must be > 0 Hz, found {frequency_hz}"
                )
            chance = (1 - self.miss_rate) / self.grid.pin_count
            if not chance < fraction < 1 - self.miss_rate:
                raise PinArrayError(
                    f"observer: correct fraction at {frequency_hz:g} Hz must lie between "
                    f"chance ({chance:.3f}) and 1 - miss_rate ({1 - self.miss_rate:.3f}), "
                    f"found {fraction}"
                )
        targets = [fraction for _, fraction in anchors]
        if any(b <= a for a, b in zip(targets, targets[1:], strict=False)):
            raise PinArrayError(
                f"observer: correct fractions must rise with frequency, found {anchors}"
            )
        for pin, factor in self.pin_acuity:
            self.grid.check_pin(pin)
            if not factor > 0:
                raise PinArrayError(
                    f"observer: acuity factor of pin {pin} must be > 0, found {factor}"
                )
        for pin in self.calibration_pins:
            self.grid.check_pin(pin)

    @property
    def pins(self) -> tuple[int, ...]:
        """The pins the anchors average over."""
        return self.calibration_pins or tuple(self.grid.pins)

    def _acuity(self) -> np.ndarray:
        factors = np.ones(self.grid.pin_count)
        for pin, factor in self.pin_acuity:
            factors[pin - 1] = factor
        return factors

    def _felt_matrix(self, sigma: float) -> np.ndarray:
        """P(report column pin | stimulated row pin, felt) for a spread of ``sigma`` pitches."""
        weights = np.exp(-_distances(self.grid) / (sigma * self._acuity()[:, None]))
        return weights / weights.sum(axis=1, keepdims=True)

    def _mean_correct(self, sigma: float) -> float:
        rows = np.array(self.pins) - 1
        return (1 - self.miss_rate) * float(np.diag(self._felt_matrix(sigma))[rows].mean())

    def _solve_sigma(self, fraction: float) -> float:
        # The correct rate falls strictly as sigma grows, so bisection in log(sigma) finds it.
        low, high = math.log(1e-3), math.log(1e3)
        for _ in range(80):
            middle = (low + high) / 2
            if self._mean_correct(math.exp(middle)) > fraction:
                low = middle
            else:
                high = middle
        return math.exp((low + high) / 2)

    def sigma(self, frequency_hz: float) -> float:
        """Spatial spread at ``frequency_hz``, in grid pitches (before per-pin acuity)."""
        log_f, log_sigma = _log_anchor_sigmas(self)
        return math.exp(float(np.interp(math.log(frequency_hz), log_f, log_sigma)))

    def report_probabilities(self, frequency_hz: float) -> np.ndarray:
        """Exact answer probabilities: row ``s - 1`` for stimulated pin ``s``.

        Column 0 is "nothing felt"; column ``r`` is pin ``r``. Each row sums to 1.
        """
        felt = (1 - self.miss_rate) * self._felt_matrix(self.sigma(frequency_hz))
        missed = np.full((self.grid.pin_count, 1), self.miss_rate)
        return np.hstack([missed, felt])

    def expected_localisation(
        self, frequency_hz: float, pins: Sequence[int] | None = None
    ) -> dict[str, float]:
        """Expected fraction of each answer class ("correct", "A".."D", "none").

        Averaged over ``pins`` stimulated equally often (the calibration pins by default).
        """
        probabilities = self.report_probabilities(frequency_hz).tolist()
        chosen = tuple(pins) if pins is not None else self.pins
        rates = dict.fromkeys(("correct", "A", "B", "C", "D"), 0.0)
        for s in chosen:
            for r in self.grid.pins:
                rates[self.grid.classify(s, r).value] += probabilities[s - 1][r] / len(chosen)
        rates["none"] = self.miss_rate
        return rates

    def expected_pin_accuracy(self, frequency_hz: float) -> np.ndarray:
        """Expected correct fraction per pin, laid out rows x columns with row 0 at the bottom."""
        correct = np.diag(self.report_probabilities(frequency_hz)[:, 1:])
        return correct.reshape(self.grid.rows, self.grid.columns)

    def motion_probabilities(self, direction: str) -> dict[str, float]:
        """Exact answer probabilities for a wave going ``direction`` ("left", "right", "none")."""
        if direction == "none":
            felt = self.no_wave_felt
            named = (1 - self.unsure_given_felt) / 2
            return {"none": 1 - felt, "left": felt * named, "right": felt * named,
                    "unsure": felt * self.unsure_given_felt}
        if direction not in _OPPOSITE:
            raise PinArrayError(
                f"observer: wave direction must be left, right or none, found {direction!r}"
            )
        felt = self.motion_felt
        wrong = 1 - self.direction_given_felt - self.unsure_given_felt
        return {"none": 1 - felt, direction: felt * self.direction_given_felt,
                _OPPOSITE[direction]: felt * wrong, "unsure": felt * self.unsure_given_felt}


@cache
def _distances(grid: Grid) -> np.ndarray:
    """Centre-to-centre distances between all pins, in grid pitches; read-only."""
    cells = np.array([grid.cell(p) for p in grid.pins], dtype=float)
    distances = np.sqrt(((cells[:, None, :] - cells[None, :, :]) ** 2).sum(axis=2))
    distances.flags.writeable = False
    return distances


@cache
def _log_anchor_sigmas(model: ObserverModel) -> tuple[list[float], list[float]]:
    # Models are frozen and hashable, so each one's bisections run once per process.
    anchors = sorted(model.correct_by_frequency)
    return ([math.log(f) for f, _ in anchors],
            [math.log(model._solve_sigma(c)) for _, c in anchors])


def _check_fraction(name: str, value: float) -> None:
    if not 0 <= value <= 1:
        raise PinArrayError(f"observer: {name} must be a fraction from 0 to 1, found {value}")


class SimulatedObserver:
    """Answers trials as `ObserverModel` says, drawing from its own seeded generator.

    Parameters
    ----------
    model : ObserverModel
        The subject's parameters; the defaults match the seed's figures.
    seed : int, numpy.random.Generator or None
        Same seed, same model and same trials give the same answers.
    """

    def __init__(self, model: ObserverModel | None = None,
                 seed: int | np.random.Generator | None = None):
        self.model = model or ObserverModel()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._cumulative: dict[float, np.ndarray] = {}

    def respond_localisation(self, stimulated_pin: int, frequency_hz: float) -> int | None:
        """The pin the subject names, or None when nothing was felt."""
        self.model.grid.check_pin(stimulated_pin)
        if frequency_hz not in self._cumulative:
            table = np.cumsum(self.model.report_probabilities(frequency_hz), axis=1)
            self._cumulative[frequency_hz] = table
        row = self._cumulative[frequency_hz][stimulated_pin - 1]
        # Clamp: rounding can leave the last cumulative entry a hair below the draw.
        answer = min(int(np.searchsorted(row, self.rng.random(), side="right")), len(row) - 1)
        return answer or None

    def respond_motion(self, direction: str) -> str:
        """'none', 'left', 'right' or 'unsure' for a wave going left, right or not at all."""
        probabilities = self.model.motion_probabilities(direction)
        draw, total = self.rng.random(), 0.0
        for answer in MOTION_ANSWERS:
            total += probabilities[answer]
            if draw < total:
                return answer
        return MOTION_ANSWERS[-1]


def parse_observer(spec: str) -> ObserverModel:
    """An `ObserverModel` from command-line text: ``default`` or ``name=value,...`` overrides.

    Scalar parameters are set by name (``motion_felt=0.9,miss_rate=0.05``); an anchor by
    ``correct_<f>hz=<fraction>`` (``correct_10hz=0.7``), replacing or adding that frequency.
    """
    model = ObserverModel()
    if spec.strip() in ("", "default"):
        return model
    scalars = {f.name for f in fields(ObserverModel) if f.type == "float"}
    anchors = dict(model.correct_by_frequency)
    changes: dict[str, float] = {}
    for item in spec.split(","):
        name, _, text = item.partition("=")
        name = name.strip()
        try:
            value = float(text)
        except ValueError:
            raise PinArrayError(f"observer: {item!r}: expected name=number") from None
        if name.startswith("correct_") and name.endswith("hz"):
            try:
                anchors[float(name[len("correct_"):-2])] = value
            except ValueError:
                raise PinArrayError(f"observer: {name!r}: expected correct_<Hz>hz") from None
        elif name in scalars:
            changes[name] = value
        else:
            raise PinArrayError(
                f"observer: unknown parameter {name!r}; expected one of "
                f"{sorted(scalars)} or correct_<Hz>hz"
            )
    return replace(model, correct_by_frequency=tuple(sorted(anchors.items())), **changes)
