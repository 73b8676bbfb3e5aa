"""From sensorised-forceps samples to a display pressure (seed 000, 4.1).

The forceps measure force F and jaw displacement delta on a tissue. Treating the jaw as
rigid (the seed's rigid-body limit: 1/E* = (1 - nu^2)/E) and the tissue as a body of
radius of curvature R, Hertz gives F = (4/3) E* sqrt(R) delta^(3/2). The seed notes the
modulus "generally has nonlinear behaviour"; here it may depend linearly on the Hertz
indentation strain eps = a / R = sqrt(delta / R)::

    E*(eps) = e0 + e1 eps
    F       = (4/3) E*(eps) sqrt(R) delta^(3/2) = (4/3) R^2 eps^3 E*(eps)
    A       = pi a^2 = pi R^2 eps^2

which is linear in (e0, e1), so both come from one least-squares fit. A display whose force
is F = p A (the TF cone, or each step of the telescopic display) replicates the tissue at
area A with p = F / A = 4 E*(eps) eps / (3 pi), computed in that form so that it is exact,
not 0/0, at zero area.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pinarray.softness._checks import (
    SoftnessError,
    finite,
    nonnegative,
    poisson_ratio,
    positive_scalar,
    same_length,
)
from pinarray.softness.identification import Fit

_MAX_STEPS = 200


@dataclass(frozen=True)
class TissueModel:
    """A tissue's Hertz contact with a rigid jaw, with a strain-dependent modulus.

    Parameters
    ----------
    radius_m : float
        R, radius of curvature of the tissue at the contact, m.
    e0_pa : float
        Effective modulus E* at zero strain, Pa, > 0.
    e1_pa : float
        Change of E* per unit strain eps = a / R, Pa; 0 for a constant modulus.
    poisson : float
        Poisson's ratio of the tissue, to turn E* into Young's modulus.
    """

    radius_m: float
    e0_pa: float
    e1_pa: float = 0.0
    poisson: float = 0.5

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius_m", positive_scalar("radius_m", self.radius_m))
        object.__setattr__(self, "e0_pa", positive_scalar("e0_pa", self.e0_pa))
        object.__setattr__(self, "e1_pa", float(finite("e1_pa", self.e1_pa)))
        object.__setattr__(self, "poisson", float(poisson_ratio("poisson", self.poisson)))

    @property
    def max_strain(self) -> float:
        """Largest strain up to which force rises with area (inf unless e1 < 0).

        dF/d eps is proportional to eps^2 (3 e0 + 4 e1 eps), positive while eps < 3 e0 / (-4 e1).
        """
        return np.inf if self.e1_pa >= 0 else 0.75 * self.e0_pa / -self.e1_pa

    def _strain(self, strain: np.ndarray) -> np.ndarray:
        beyond = strain > self.max_strain
        if beyond.any():
            raise SoftnessError(
                f"strain {strain[beyond].flat[0]:.4g} is past {self.max_strain:.4g}, where the "
                "fitted "
                "modulus softens so fast that force stops rising with area"
            )
        return strain

    def effective_modulus_pa(self, strain: object) -> np.ndarray:
        """E*(eps) = e0 + e1 eps, Pa; ``strain`` is eps = a / R, >= 0."""
        return self.e0_pa + self.e1_pa * self._strain(nonnegative("strain", strain))

    def young_modulus_pa(self, strain: object) -> np.ndarray:
        """Young's modulus E = E*(eps) (1 - nu^2) of the tissue, Pa."""
        return self.effective_modulus_pa(strain) * (1 - self.poisson**2)

    def strain_for_area(self, area_m2: object) -> np.ndarray:
        """eps = a / R for a contact area, a = sqrt(A / pi)."""
        return np.sqrt(nonnegative("area_m2", area_m2) / np.pi) / self.radius_m

    def force_for_strain_n(self, strain: object) -> np.ndarray:
        """F = (4/3) R^2 eps^3 E*(eps), N."""
        eps = nonnegative("strain", strain)
        return 4 / 3 * self.radius_m**2 * eps**3 * self.effective_modulus_pa(eps)

    def force_for_area_n(self, area_m2: object) -> np.ndarray:
        """Force at which the contact reaches an area, N (the predicted force/area curve)."""
        return self.force_for_strain_n(self.strain_for_area(area_m2))

    def force_for_approach_n(self, approach_m: object) -> np.ndarray:
        """Force at a jaw displacement delta, N (eps = sqrt(delta / R))."""
        return self.force_for_strain_n(
            np.sqrt(nonnegative("approach_m", approach_m) / self.radius_m)
        )

    def display_pressure_pa(self, area_m2: object) -> np.ndarray:
        """Pressure p = F / A = 4 E*(eps) eps / (3 pi) at which an F = p A display matches the
        tissue at an area, Pa."""
        eps = self.strain_for_area(area_m2)
        return 4 * self.effective_modulus_pa(eps) * eps / (3 * np.pi)

    def area_for_force_m2(self, force_n: object) -> np.ndarray:
        """Contact area at a force, m^2 (the inverse of `force_for_area_n`).

        Closed form for a constant modulus; otherwise a safeguarded Newton iteration on the
        strain, bracketed by the closed form with the smallest modulus on the rising branch,
        so a micro-newton force keeps the same relative precision as a ten-newton one.
        """
        force = nonnegative("force_n", force_n)
        scale = 0.75 * force / self.radius_m**2  # eps^3 E*(eps) must equal this
        if self.e1_pa == 0:
            return np.pi * (self.radius_m * np.cbrt(scale / self.e0_pa)) ** 2
        if self.e1_pa < 0:
            reachable = float(self.force_for_strain_n(self.max_strain))
            too_big = force > reachable
            if too_big.any():
                raise SoftnessError(
                    f"force_n {force[too_big].flat[0]:.4g} N is beyond the largest force the "
                    "fitted "
                    f"modulus reaches while rising, {reachable:.4g} N"
                )
            # On [0, max_strain], E* >= e0 + e1 max_strain = e0 / 4.
            high = np.minimum(np.cbrt(scale / (0.25 * self.e0_pa)), self.max_strain)
        else:
            high = np.cbrt(scale / self.e0_pa)
        strain = _safeguarded_newton(self.e0_pa, self.e1_pa, scale, high)
        return np.pi * (self.radius_m * strain) ** 2


def _safeguarded_newton(e0: float, e1: float, target: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Solve eps^3 (e0 + e1 eps) = target for eps in [0, high], elementwise.

    Newton's method from the upper end of the bracket, falling back to bisection whenever a
    step would leave the bracket, which shrinks every iteration; stops when no element moves
    by more than a few ulps.
    """
    low = np.zeros_like(high)
    x = high.copy()
    for _ in range(_MAX_STEPS):
        excess = x**3 * (e0 + e1 * x) - target
        below = excess < 0
        low = np.where(below, x, low)
        high = np.where(below, high, x)
        slope = x**2 * (3 * e0 + 4 * e1 * x)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = x - excess / slope
        step = np.where((newton >= low) & (newton <= high), newton, 0.5 * (low + high))
        settled = np.all(np.abs(step - x) <= 4 * np.finfo(float).eps * step)
        x = step
        if settled:
            break
    return x


def fit_tissue(
    approach_m: object,
    force_n: object,
    radius_m: float,
    poisson: float = 0.5,
    strain_dependent: bool = True,
) -> Fit[TissueModel]:
    """Fit a tissue's modulus to forceps samples by least squares.

    Parameters
    ----------
    approach_m : array_like
        Jaw displacement into the tissue at each sample, m, >= 0.
    force_n : array_like
        Force at each sample, N.
    radius_m : float
        Radius of curvature of the tissue at the contact, m.
    poisson : float
        Poisson's ratio of the tissue (0.5: incompressible, usual for soft tissue).
    strain_dependent : bool
        Fit E* = e0 + e1 eps; when False, a constant E* = e0.
    """
    delta = nonnegative("approach_m", approach_m)
    force = finite("force_n", force_n)
    same_length(("approach_m", "force_n"), delta, force)
    radius = positive_scalar("radius_m", radius_m)
    # F = e0 (4/3) sqrt(R) delta^1.5 + e1 (4/3) delta^2: one column per coefficient.
    columns = [4 / 3 * np.sqrt(radius) * delta**1.5]
    if strain_dependent:
        columns.append(4 / 3 * delta**2)
    design = np.column_stack(columns)
    if design.shape[0] < design.shape[1]:
        raise SoftnessError(
            f"the fit needs at least {design.shape[1]} samples, found {design.shape[0]}"
        )
    norms = np.linalg.norm(design, axis=0)
    if np.any(norms == 0):
        raise SoftnessError(
            "every sample has zero approach_m: the forceps never closed on the tissue"
        )
    # Scale columns to unit norm: delta^1.5 and delta^2 differ by orders of magnitude.
    coefficients, *_ = np.linalg.lstsq(design / norms, force, rcond=None)
    coefficients = coefficients / norms
    if coefficients[0] <= 0:
        raise SoftnessError(
            f"the fitted modulus at zero strain is {coefficients[0]:.4g} Pa, not positive: "
            "the samples do not look like a Hertz contact"
        )
    e1 = float(coefficients[1]) if strain_dependent else 0.0
    tissue = TissueModel(radius, float(coefficients[0]), e1, poisson)
    return Fit(tissue, force - design @ coefficients)
