"""Least-squares identification of a specimen's force/area and force/displacement curves
(seed 001, 9.5), with residuals and numerically stable inverses.

The seed reports its fits in newtons and centimetres::

    F(A)|M1,R=1.1 cm = 1.4 A^2 + 0.33 A + 0.55      A in cm^2, F in N   (eq. 9.4)
    F(z)|M2,R=1.4 cm = 23 z + 0.97                   z in cm,   F in N   (eq. 9.5)

The models here hold SI coefficients; ``from_cm`` converts the seed's numbers explicitly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from pinarray.softness._checks import SoftnessError, finite, nonnegative, same_length
from pinarray.softness.units import M2_PER_CM2, M_PER_CM


@dataclass(frozen=True)
class QuadraticForceArea:
    """F(A) = a A^2 + b A + c.

    Parameters
    ----------
    a_n_per_m4 : float
        Quadratic coefficient, N/m^4.
    b_n_per_m2 : float
        Linear coefficient, N/m^2 (a pressure, Pa).
    c_n : float
        Force at zero area, N.
    """

    a_n_per_m4: float
    b_n_per_m2: float
    c_n: float

    @classmethod
    def from_cm(cls, a_n_per_cm4: float, b_n_per_cm2: float, c_n: float) -> QuadraticForceArea:
        """The model from coefficients of a fit with A in cm^2 (as in the seed's eq. 9.4)."""
        return cls(a_n_per_cm4 / (M2_PER_CM2 * M2_PER_CM2), b_n_per_cm2 / M2_PER_CM2, c_n)

    def force_n(self, area_m2: object) -> np.ndarray:
        """Force at contact areas, N; ``area_m2`` in m^2, >= 0."""
        area = nonnegative("area_m2", area_m2)
        return (self.a_n_per_m4 * area + self.b_n_per_m2) * area + self.c_n

    def area_m2(self, force_n: object) -> np.ndarray:
        """Contact area at which the curve reaches a force, m^2 (the inverse of `force_n`).

        Solves a A^2 + b A + (c - F) = 0 for its non-negative root in the cancellation-free
        form A = 2 (F - c) / (b + sqrt(b^2 + 4 a (F - c))): both terms of the denominator
        are non-negative, so tiny areas keep full precision where the textbook
        (-b + sqrt(...)) / 2a would subtract nearly equal numbers. Forces at or below F(0) = c
        lie outside the fitted curve and map to zero area.

        Raises `SoftnessError` unless a >= 0 and b >= 0 with one of them positive (the curve
        must rise from zero area to be invertible).
        """
        if (
            self.a_n_per_m4 < 0
            or self.b_n_per_m2 < 0
            or (self.a_n_per_m4 == 0 and self.b_n_per_m2 == 0)
        ):
            raise SoftnessError(
                "the force/area curve is not increasing from zero area "
                f"(a = {self.a_n_per_m4:.4g} N/m^4, b = {self.b_n_per_m2:.4g} N/m^2); "
                "expected a >= 0 and b >= 0, not both zero"
            )
        excess = np.clip(nonnegative("force_n", force_n) - self.c_n, 0.0, None)
        if self.b_n_per_m2 == 0:
            # The form above is 0/0 at F = c when b = 0; sqrt((F - c) / a) has no cancellation.
            return np.sqrt(excess / self.a_n_per_m4)
        # b b, not b**2: a product rounds alike on every machine, a power need not
        root = np.sqrt(self.b_n_per_m2 * self.b_n_per_m2 + 4 * self.a_n_per_m4 * excess)
        return 2 * excess / (self.b_n_per_m2 + root)


@dataclass(frozen=True)
class LinearForceDisplacement:
    """F(z) = k z + c.

    Parameters
    ----------
    slope_n_per_m : float
        Stiffness k, N/m.
    intercept_n : float
        Force at zero displacement, N.
    """

    slope_n_per_m: float
    intercept_n: float

    @classmethod
    def from_cm(cls, slope_n_per_cm: float, intercept_n: float) -> LinearForceDisplacement:
        """The model from a fit with z in cm (as in the seed's eq. 9.5)."""
        return cls(slope_n_per_cm / M_PER_CM, intercept_n)

    def force_n(self, displacement_m: object) -> np.ndarray:
        """Force at displacements, N; ``displacement_m`` in m, >= 0."""
        return self.slope_n_per_m * nonnegative("displacement_m", displacement_m) + self.intercept_n

    def displacement_m(self, force_n: object) -> np.ndarray:
        """Displacement at which the line reaches a force, m; forces at or below the intercept
        map to zero displacement. Raises `SoftnessError` for a slope that is not positive."""
        if not self.slope_n_per_m > 0:
            raise SoftnessError(
                f"the force/displacement slope must be positive, found {self.slope_n_per_m:.4g} N/m"
            )
        return (
            np.clip(nonnegative("force_n", force_n) - self.intercept_n, 0.0, None)
            / self.slope_n_per_m
        )


#: Seed 001 eq. 9.4, material M1, sphere of radius 1.1 cm.
M1_R11_FORCE_AREA = QuadraticForceArea.from_cm(1.4, 0.33, 0.55)
#: Seed 001 eq. 9.5, material M2, sphere of radius 1.4 cm.
M2_R14_FORCE_DISPLACEMENT = LinearForceDisplacement.from_cm(23.0, 0.97)


Model = TypeVar("Model")


@dataclass(frozen=True, eq=False)
class Fit(Generic[Model]):
    """A fitted curve and how far the samples lie from it."""

    model: Model
    residuals_n: np.ndarray
    """Measured minus fitted force at each sample, N."""

    @property
    def rms_residual_n(self) -> float:
        """Root-mean-square residual, N."""
        return float(np.sqrt(np.mean(self.residuals_n**2)))

    @property
    def max_residual_n(self) -> float:
        """Largest absolute residual, N."""
        return float(np.max(np.abs(self.residuals_n)))


def _scaled_polyfit(x: np.ndarray, y: np.ndarray, degree: int) -> np.ndarray:
    """Least-squares polynomial coefficients, highest power first, fitted on x / max|x|.

    Areas are ~1e-4 m^2, so the raw Vandermonde columns A^2, A, 1 differ by eight orders of
    magnitude; scaling x to order one keeps the least-squares problem well conditioned.
    """
    if x.size <= degree:
        raise SoftnessError(
            f"a degree-{degree} fit needs at least {degree + 1} samples, found {x.size}"
        )
    scale = float(np.max(np.abs(x)))
    if scale == 0:
        raise SoftnessError("every sample has zero area or displacement: nothing to fit")
    columns = np.vander(x / scale, degree + 1)
    coefficients, *_ = np.linalg.lstsq(columns, y, rcond=None)
    return coefficients / scale ** np.arange(degree, -1, -1)


def fit_force_area(area_m2: object, force_n: object) -> Fit[QuadraticForceArea]:
    """Fit F = a A^2 + b A + c to samples by least squares (the seed's quadratic interpolation).

    Parameters
    ----------
    area_m2 : array_like
        Contact areas, m^2, >= 0.
    force_n : array_like
        Forces at those areas, N.
    """
    area = nonnegative("area_m2", area_m2)
    force = finite("force_n", force_n)
    same_length(("area_m2", "force_n"), area, force)
    a, b, c = _scaled_polyfit(area, force, 2)
    model = QuadraticForceArea(float(a), float(b), float(c))
    return Fit(model, force - model.force_n(area))


def fit_force_displacement(displacement_m: object, force_n: object) -> Fit[LinearForceDisplacement]:
    """Fit F = k z + c to samples by least squares (the seed's linear interpolation).

    Parameters
    ----------
    displacement_m : array_like
        Indentations, m, >= 0.
    force_n : array_like
        Forces at those indentations, N.
    """
    displacement = nonnegative("displacement_m", displacement_m)
    force = finite("force_n", force_n)
    same_length(("displacement_m", "force_n"), displacement, force)
    k, c = _scaled_polyfit(displacement, force, 1)
    model = LinearForceDisplacement(float(k), float(c))
    return Fit(model, force - model.force_n(displacement))
