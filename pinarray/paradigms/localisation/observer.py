"""A simulated subject naming the pin that moved, for piloting a protocol and testing the runner
without people.

A subject who feels the stimulus reports pin ``r`` for stimulated pin ``s``
with probability proportional to ``exp(-d(s, r) / sigma)``, where ``d`` is the distance
between the pins in grid pitches and ``sigma`` (the spatial spread) shrinks as frequency
rises. ``sigma`` is not given directly: it is solved, per anchor frequency, so that the mean
correct rate over the calibration pins equals the anchor's target, and interpolated in
log-log between anchors (held constant beyond them). Corner pins have fewer near neighbours
than edge pins, and edge pins fewer than centre pins, so the model localises corners best
and the centre worst without being told to; a per-pin acuity factor scales ``sigma`` for
single pins (the seed found pin 4 best localised). Calibrate on the pins a protocol uses
(`ObserverModel.for_protocol`): averaged over other pins the same spread gives other rates.

Subjects differ. A simulated subject of the seed's experiments draws three independent offsets
from a normal distribution with standard deviation ``subject_sd_logit`` (`OFFSETS`, drawn
alike whichever of the two experiments it answers, so one seed is one subject): the first,
localisation's, shifts the logit of the share of the way from chance to perfect localisation
(the same offset at every frequency, so a good subject is good everywhere). The population is calibrated so the *average subject's*
rates are the targets: the model's anchors are population means, not the rates of a subject
with offset 0.

The defaults reproduce the seed's reported figures in expectation (section 9.7.1): 62.5 %
correct at 10 Hz, rising with frequency (the 3 and 5 Hz targets, 40 % and 50 %, are this
model's assumptions: the seed shows them only in a figure), error A the most frequent error
at every frequency. The seed reports no spread between its subjects; the default
``subject_sd_logit`` of 0.5 is an assumption that puts the middle 95 % of subjects between
about 41 % and 82 % correct at 10 Hz on the localisation protocol's 8 pins
(`ObserverModel.subject_range`). Set it to 0 for identical subjects.

Past 400 lines on purpose: the model of one simulated subject and the arithmetic that
calibrates a population of them on the seed's figures belong together; apart, neither reads.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from functools import cache, lru_cache
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from pinarray.analysis.observers import (
    QUADRATURE_NODES,
    centre,
    check_fraction,
    draw_offsets,
    expit,
    hermite,
    observer_items,
    observer_number,
    quoted,
)
from pinarray.errors import PinArrayError
from pinarray.grid import DEFAULT_GRID, Grid
from pinarray.paradigms.localisation.design import LocalisationCondition
from pinarray.protocol.model import Condition
from pinarray.protocol.yaml_nodes import exact_number

if TYPE_CHECKING:
    from pinarray.protocol import Protocol

DEFAULT_SUBJECT_SD_LOGIT = 0.5
_MAX_SUBJECT_SD_LOGIT = 5.0
OFFSETS = 3  # a subject of the seed's experiments draws three, whichever it answers


class SubjectOffsets(NamedTuple):
    """One simulated subject's random effects, on the logit scale (0 = the median subject):
    the seed's three, of which localisation takes the first (the others are the other
    experiment's)."""

    localisation_logit: float = 0.0
    second_logit: float = 0.0
    third_logit: float = 0.0


@dataclass(frozen=True)
class ObserverModel:
    """Parameters of a simulated population of subjects; probabilities are fractions in [0, 1].

    Parameters
    ----------
    correct_by_frequency : tuple of (frequency_hz, fraction)
        Anchors: expected fraction of localisation trials answered with the stimulated pin,
        averaged over ``calibration_pins`` and over subjects. Must not fall as frequency rises.
    miss_rate : float
        Fraction of localisation trials on which nothing is felt (answer ``None``).
    pin_acuity : tuple of (pin, factor)
        Multiplies ``sigma`` for single pins; below 1 localises that pin better.
    calibration_pins : tuple of int, optional
        Pins the anchors average over; all pins of ``grid`` when empty.
    subject_sd_logit : float
        Standard deviation of the subject random effects, in logit units (module docstring);
        0 makes every subject the same. Default 0.5.
    """

    correct_by_frequency: tuple[tuple[float, float], ...] = ((3.0, 0.40), (5.0, 0.50),
                                                             (10.0, 0.625))
    miss_rate: float = 0.0
    pin_acuity: tuple[tuple[int, float], ...] = ((4, 0.8),)
    calibration_pins: tuple[int, ...] = ()
    grid: Grid = DEFAULT_GRID
    subject_sd_logit: float = DEFAULT_SUBJECT_SD_LOGIT

    def __post_init__(self) -> None:
        # Tuples all the way down keep the model hashable, so its calibration is cached.
        object.__setattr__(self, "correct_by_frequency",
                           tuple((float(f), float(c)) for f, c in self.correct_by_frequency))
        object.__setattr__(self, "pin_acuity",
                           tuple((int(p), float(a)) for p, a in self.pin_acuity))
        object.__setattr__(self, "calibration_pins", tuple(self.calibration_pins))
        check_fraction("miss_rate", self.miss_rate)
        if not 0 <= self.subject_sd_logit <= _MAX_SUBJECT_SD_LOGIT:
            raise PinArrayError(
                f"observer: subject_sd_logit must lie from 0 to {_MAX_SUBJECT_SD_LOGIT:g} "
                f"(logit units), found {self.subject_sd_logit}"
            )
        anchors = sorted(self.correct_by_frequency)
        if not anchors:
            raise PinArrayError("observer: correct_by_frequency needs at least one anchor")
        for frequency_hz, fraction in anchors:
            if not frequency_hz > 0:
                raise PinArrayError(
                    f"observer: anchor frequency must be > 0 Hz, found {frequency_hz}"
                )
            if not self.chance < fraction < self.ceiling:
                raise PinArrayError(
                    f"observer: correct fraction at {frequency_hz:g} Hz must lie between "
                    f"chance ({self.chance:.3f}) and 1 - miss_rate ({self.ceiling:.3f}), "
                    f"found {fraction}"
                )
        targets = [fraction for _, fraction in anchors]
        # Level anchors are allowed: a subject of a population maps rising anchors through one
        # increasing function, and two an ulp apart can round to the same fraction.
        if any(b < a for a, b in zip(targets, targets[1:], strict=False)):
            raise PinArrayError(
                f"observer: correct fractions must not fall as frequency rises, found {anchors}"
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

    @property
    def chance(self) -> float:
        """Correct fraction of a subject who feels and names any grid pin at random."""
        return (1 - self.miss_rate) / self.grid.pin_count

    @property
    def ceiling(self) -> float:
        """Correct fraction of a subject who names every felt pin right."""
        return 1 - self.miss_rate

    def calibrated_on(self, pins: Iterable[int]) -> ObserverModel:
        """This model with its anchors averaged over ``pins`` (all grid pins when empty)."""
        return replace(self, calibration_pins=tuple(sorted(set(pins))))

    def for_protocol(self, protocol: Protocol) -> ObserverModel:
        """This model on the protocol's grid, calibrated on the pins its design stimulates."""
        pins = {c.pin for c in protocol.design.conditions if isinstance(c, LocalisationCondition)}
        return replace(self, grid=protocol.device.grid).calibrated_on(pins)

    # -- subjects ---------------------------------------------------------------------------

    def draw_subject(self, rng: np.random.Generator) -> SubjectOffsets:
        """One subject's offsets, drawn from ``rng`` (nothing is drawn when the SD is 0)."""
        return SubjectOffsets(*draw_offsets(rng, self.subject_sd_logit, OFFSETS))

    def individual(self, offsets: SubjectOffsets) -> ObserverModel:
        """The model of one subject: its own anchors, no further spread."""
        if self.subject_sd_logit == 0 and offsets == SubjectOffsets():
            return self  # every subject of a population without spread is the same one
        anchors = tuple(
            (f, self.chance + (self.ceiling - self.chance)
             * expit(at + offsets.localisation_logit))
            for (f, _), at in zip(sorted(self.correct_by_frequency), _anchor_centres(self),
                                  strict=True)
        )
        return replace(self, correct_by_frequency=anchors, subject_sd_logit=0.0)

    def subject_range(self, frequency_hz: float, coverage: float = 0.95) -> tuple[float, float]:
        """Correct fractions between which the middle ``coverage`` of subjects fall."""
        from scipy.special import ndtri  # the standard normal quantile

        z = float(ndtri(0.5 + coverage / 2)) * self.subject_sd_logit
        return tuple(  # type: ignore[return-value]
            self.individual(SubjectOffsets(u)).expected_localisation(frequency_hz)["correct"]
            for u in (-z, z)
        )

    # -- one subject's spread ---------------------------------------------------------------

    def _acuity(self) -> np.ndarray:
        factors = np.ones(self.grid.pin_count)
        for pin, factor in self.pin_acuity:
            factors[pin - 1] = factor
        return factors

    def _felt_matrix(self, sigma: float) -> np.ndarray:
        """P(report column pin | stimulated row pin, felt) for a spread of ``sigma`` pitches."""
        weights = np.exp(-_distances(self.grid) / (sigma * self._acuity()[:, None]))
        return weights / weights.sum(axis=1, keepdims=True)

    def _mean_correct(self, sigmas: np.ndarray) -> np.ndarray:
        """Correct fraction over the calibration pins for each spread in ``sigmas``."""
        return self._correct_over(self._near_calibration_pins(), sigmas)

    def _near_calibration_pins(self) -> np.ndarray:
        """Minus each calibration pin's distance to every pin in its own acuity's pitches,
        shaped (1, pins, all pins) for `_correct_over`."""
        rows = np.array(self.pins) - 1
        return -(_distances(self.grid)[rows] / self._acuity()[rows][:, None])[None]

    def _correct_over(self, near: np.ndarray, sigmas: np.ndarray) -> np.ndarray:
        # The stimulated pin is at distance 0, so its weight is 1 and its share 1 / row sum.
        sums = np.exp(near / sigmas[:, None, None]).sum(axis=2)
        return self.ceiling * (1 / sums).mean(axis=1)

    def _solve_sigmas(self, fractions: Sequence[float]) -> np.ndarray:
        # The correct rate falls strictly as sigma grows: a table over log(sigma) brackets
        # each anchor's spread, and bisection inside the bracket pins it down (to ~1e-9).
        log_sigmas, correct = _correct_table(self.grid, self.pin_acuity, self.pins)
        targets = np.asarray(fractions, dtype=float) / self.ceiling
        # `correct` falls along the table, so count the entries still above each target.
        above = np.searchsorted(-correct, -targets, side="right").clip(1, len(correct) - 1)
        low, high = log_sigmas[above - 1], log_sigmas[above]
        near = self._near_calibration_pins()  # the same at every step
        for _ in range(24):
            middle = (low + high) / 2
            up = self._correct_over(near, np.exp(middle)) / self.ceiling > targets
            low = np.where(up, middle, low)
            high = np.where(up, high, middle)
        return np.exp((low + high) / 2)

    def sigma(self, frequency_hz: float) -> float:
        """Spatial spread at ``frequency_hz``, in grid pitches (before per-pin acuity).

        For a population (``subject_sd_logit > 0``) this is the spread of the median subject.
        """
        median = self if self.subject_sd_logit == 0 else self.individual(SubjectOffsets())
        log_f, log_sigma = _log_anchor_sigmas(median)
        return math.exp(float(np.interp(math.log(frequency_hz), log_f, log_sigma)))

    def _own_report_probabilities(self, frequency_hz: float) -> np.ndarray:
        felt = self.ceiling * self._felt_matrix(self.sigma(frequency_hz))
        missed = np.full((self.grid.pin_count, 1), self.miss_rate)
        return np.hstack([missed, felt])

    # -- what the population answers ---------------------------------------------------------

    def report_probabilities(self, frequency_hz: float) -> np.ndarray:
        """Exact answer probabilities of a subject drawn at random: row ``s - 1`` for pin ``s``.

        Column 0 is "nothing felt"; column ``r`` is pin ``r``. Each row sums to 1.
        """
        if self.subject_sd_logit == 0:
            return self._own_report_probabilities(frequency_hz)
        total = np.zeros((self.grid.pin_count, self.grid.pin_count + 1))
        for weight, subject in _population(self):
            total += weight * subject._own_report_probabilities(frequency_hz)
        return total

    def expected_localisation(
        self, frequency_hz: float, pins: Sequence[int] | None = None
    ) -> dict[str, float]:
        """Expected fraction of each answer class ("correct", "A".."D", "none").

        Averaged over ``pins`` stimulated equally often (the calibration pins by default)
        and over subjects.
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


@cache
def _anchor_centres(model: ObserverModel) -> tuple[float, ...]:
    """Each anchor's logit centre of its share above chance, over the population."""
    sd = model.subject_sd_logit
    span = model.ceiling - model.chance
    return tuple(centre((c - model.chance) / span, sd) for _, c in sorted(model.correct_by_frequency))


@cache
def _population(model: ObserverModel) -> tuple[tuple[float, ObserverModel], ...]:
    """Quadrature weights and the subjects at their nodes, for averages over subjects."""
    z, w = hermite(QUADRATURE_NODES)
    sd = model.subject_sd_logit
    return tuple((float(weight), model.individual(SubjectOffsets(float(sd * node))))
                 for node, weight in zip(z, w, strict=True))


@cache
def _correct_table(grid: Grid, pin_acuity: tuple[tuple[int, float], ...],
                   pins: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Felt-correct fraction over ``pins`` on a grid of log(sigma) from 1e-3 to 1e3 pitches."""
    probe = ObserverModel(grid=grid, pin_acuity=pin_acuity, calibration_pins=pins,
                          correct_by_frequency=((1.0, 0.5),), subject_sd_logit=0.0)
    log_sigmas = np.linspace(math.log(1e-3), math.log(1e3), 513)
    return log_sigmas, probe._mean_correct(np.exp(log_sigmas))


@cache
def _distances(grid: Grid) -> np.ndarray:
    """Centre-to-centre distances between all pins, in grid pitches; read-only."""
    cells = np.array([grid.cell(p) for p in grid.pins], dtype=float)
    distances = np.sqrt(((cells[:, None, :] - cells[None, :, :]) ** 2).sum(axis=2))
    distances.flags.writeable = False
    return distances


@lru_cache(maxsize=4096)
def _log_anchor_sigmas(model: ObserverModel) -> tuple[list[float], list[float]]:
    # Models are frozen and hashable, so each one's bisections run once per process (bounded:
    # a power analysis makes thousands of simulated subjects, each a model of its own).
    anchors = sorted(model.correct_by_frequency)
    sigmas = model._solve_sigmas([c for _, c in anchors])
    return [math.log(f) for f, _ in anchors], [math.log(s) for s in sigmas]


class SimulatedObserver:
    """One simulated subject: drawn from `ObserverModel`'s population, answering trials.

    Parameters
    ----------
    model : ObserverModel
        The population's parameters; the defaults match the seed's figures on average.
    seed : int, numpy.random.Generator or None
        Same seed, same model and same trials give the same subject and the same answers.

    Attributes
    ----------
    offsets : SubjectOffsets
        This subject's random effects, drawn first from the generator.
    subject : ObserverModel
        This subject's own parameters (``model.individual(offsets)``).
    """

    def __init__(self, model: ObserverModel | None = None,
                 seed: int | np.random.Generator | None = None):
        self.model = model or ObserverModel()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.offsets = self.model.draw_subject(self.rng)
        self.subject = self.model.individual(self.offsets)
        self._cumulative: dict[float, np.ndarray] = {}

    def respond_localisation(self, stimulated_pin: int, frequency_hz: float) -> int | None:
        """The pin the subject names, or None when nothing was felt."""
        self.subject.grid.check_pin(stimulated_pin)
        if frequency_hz not in self._cumulative:
            table = np.cumsum(self.subject.report_probabilities(frequency_hz), axis=1)
            self._cumulative[frequency_hz] = table
        row = self._cumulative[frequency_hz][stimulated_pin - 1]
        # Clamp: rounding can leave the last cumulative entry a hair below the draw.
        answer = min(int(np.searchsorted(row, self.rng.random(), side="right")), len(row) - 1)
        return answer or None

    def __call__(self, condition: Condition) -> str:
        """The subject's answer to a trial presenting ``condition``: a pin, or none."""
        assert isinstance(condition, LocalisationCondition)
        named = self.respond_localisation(condition.pin, float(condition.frequency_hz))
        return "none" if named is None else str(named)


def parse_observer(spec: str) -> ObserverModel:
    """An `ObserverModel` from command-line text: ``default`` or ``name=value,...`` overrides.

    Scalar parameters are set by name (``miss_rate=0.1,subject_sd_logit=0``); an anchor by
    ``correct_<f>hz=<fraction>`` (``correct_10hz=0.7``), replacing or adding that frequency.
    """
    model = ObserverModel()
    if spec.strip() in ("", "default"):
        return model
    scalars = {"miss_rate", "subject_sd_logit"}
    anchors = dict(model.correct_by_frequency)
    changes: dict[str, Any] = {}
    for item, name, text in observer_items(spec):
        value = observer_number(item, text)
        if name.startswith("correct_") and name.endswith("hz"):
            try:
                frequency = exact_number(name[len("correct_"):-2])
            except ValueError:
                frequency = Fraction(0)
            if not 0 < frequency <= 1000:
                raise PinArrayError(f"observer: {quoted(name)}: expected correct_<Hz>hz with a "
                                    "frequency above 0 and at most 1000 Hz")
            anchors[float(frequency)] = value
        elif name in scalars:
            changes[name] = value
        else:
            raise PinArrayError(
                f"observer: unknown parameter {quoted(name)}; expected one of "
                f"{sorted(scalars)} or correct_<Hz>hz"
            )
    return replace(model, correct_by_frequency=tuple(sorted(anchors.items())), **changes)


def observer(protocol: Protocol, spec: str, seed: int | None) -> SimulatedObserver:
    """The simulated subject ``--observer`` names for a localisation design, calibrated on its
    pins."""
    return SimulatedObserver(parse_observer(spec).for_protocol(protocol), seed=seed)
