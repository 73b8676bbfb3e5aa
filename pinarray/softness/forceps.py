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

_MAX_STEPS = 100

_U = np.finfo(float).eps / 2  # the unit of rounding, 2^-53: + - * / and sqrt err by at most u
# An area from `area_for_force_m2` comes back to a strain through `strain_for_area`:
# A = (eps eps)(pi R R) rounds four times (eps^2, pi R, pi R R, the product) and
# eps' = sqrt(A / pi) / R three more (the quotient under the root, the root, the division).
# Under the root the five roundings count half, so eps' = eps (1 + r), |r| <= 4.5 u (plus
# O(u^2)), which is at most 4.5 ulps of eps. A strain that far past the largest strain is the
# largest strain, come back through its area; 6 u covers the O(u^2) terms.
_STRAIN_ROUND_TRIP = 6 * _U
# The force F = (4/3 R^2)(eps eps eps)(e0 + e1 eps) at a strain rounds four times in the
# products and twice in E* = e0 + e1 eps; at the largest force e1 eps = -3 E*, so E*'s two
# roundings weigh 3 u + u there: a computed force lies within 8 u of the exact curve. The curve
# is flat at its top, so a force the forward function returns at a strain on the rising branch
# is at most 16 u above the computed largest force.
_FORCE_ROUNDING = 16 * _U


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
        """The strain, with one within rounding past the largest strain taken as the largest
        (`area_for_force_m2` returns that strain's area, which comes back up to 4.5 ulps past)."""
        top = self.max_strain
        beyond = strain > top * (1 + _STRAIN_ROUND_TRIP)
        if beyond.any():
            raise SoftnessError(
                f"strain {strain[beyond].flat[0]:.4g} is past {top:.4g}, where the "
                "fitted "
                "modulus softens so fast that force stops rising with area"
            )
        return np.minimum(strain, top)

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
        eps = self._strain(nonnegative("strain", strain))
        # eps eps eps, not eps**3: products round correctly on every machine, pow need not.
        return 4 / 3 * self.radius_m**2 * (eps * eps * eps) * self.effective_modulus_pa(eps)

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

        Closed form for a constant modulus; otherwise Newton's method on the strain from a
        start on the side where it converges monotonically (see `_strain_for_load`), so a
        micro-newton force keeps the same relative precision as a ten-newton one.
        """
        force = nonnegative("force_n", force_n)
        if self.e1_pa == 0:
            scale = 0.75 * force / self.radius_m**2  # eps^3 E* must equal this
            return np.pi * (self.radius_m * np.cbrt(scale / self.e0_pa)) ** 2
        if self.e1_pa < 0:
            reachable = float(self.force_for_strain_n(self.max_strain))
            too_big = force > reachable * (1 + _FORCE_ROUNDING)
            if too_big.any():
                raise SoftnessError(
                    f"force_n {force[too_big].flat[0]:.4g} N is beyond the largest force the "
                    "fitted "
                    f"modulus reaches while rising, {reachable:.4g} N"
                )
            # within rounding of the top (see _FORCE_ROUNDING): the top
            force = np.minimum(force, reachable)
        # eps^3 (e0 + e1 eps) = 3 F / (4 R^2)  <=>  eps^3 (1 + g eps) = w, w = 3 F / (4 R^2 e0)
        area = _strain_for_load(
            force.ravel(), 0.75 / (self.radius_m**2 * self.e0_pa), self.e1_pa / self.e0_pa
        )
        # Near the top the strain is ill-conditioned (the curve is flat): a root found a
        # rounding step past the largest strain is the largest strain.
        np.minimum(area, self.max_strain, out=area)
        area *= area  # A = pi (R eps)^2, in place
        area *= np.pi * self.radius_m * self.radius_m  # products: rounded alike everywhere
        return area.reshape(force.shape)


# Newton's method works through the samples in blocks this long, so that its few scratch
# arrays stay in the processor's cache.
_BLOCK = 16_384
# Relative step after which the step just taken lands within an ulp of a stiffening tissue's
# root (quadratic convergence with a constant below 1.5 on a convex curve).
_LAST_STEP = 1e-9
# Near a softening tissue's largest force that constant grows without bound: there the steps
# themselves must shrink to a few ulps.
_SETTLED = 4 * np.finfo(float).eps


def _strain_for_load(force_n: np.ndarray, per_newton: float, growth: float) -> np.ndarray:
    """Solve ``eps^3 (1 + growth eps) = per_newton * force_n`` for ``eps >= 0``, elementwise.

    Newton's method on the relative step ``r = (1 + g eps - w / eps^3) / (3 + 4 g eps)``,
    ``eps <- eps (1 - r)``. The curve is convex where ``g eps < 1/2`` (everywhere when
    stiffening): there Newton steps from above the root never overshoot it, so the start is
    an upper bound, the root's fixed point ``cbrt(w / (1 + g eps))`` taken at a lower bound.
    Past that inflection (a softening tissue near its largest force) the curve is concave and
    the start is a lower bound instead. No bracket, no bisection, and no array is allocated
    per iteration: five block-sized scratch arrays are updated in place.
    """
    strain = np.empty_like(force_n)
    # A load on the convex side of the curve, for zero forces to be solved with (eps = 0 would
    # be 0 / 0 in the step).
    stand_in = 1.0 if growth > 0 else 0.5 * min(0.5 / -growth, 1.0) ** 3
    size = min(_BLOCK, len(force_n))
    w_all, a_all, b_all, previous_all = (np.empty(size) for _ in range(4))
    shrinks_all = np.empty(size, dtype=bool)
    for low in range(0, len(force_n), _BLOCK):
        eps = strain[low : low + _BLOCK]
        w, a, b, previous, shrinks = (
            array[: len(eps)] for array in (w_all, a_all, b_all, previous_all, shrinks_all)
        )
        np.multiply(force_n[low : low + _BLOCK], per_newton, out=w)
        zero = None if w.all() else w == 0
        if zero is not None:
            w[zero] = stand_in  # solved as any other, then set to the exact 0
        if growth > 0:
            _start_stiffening(eps, w, growth, a, b)
            last_step = _LAST_STEP
        else:
            _start_softening(eps, w, growth, a, b)
            last_step = _SETTLED
        previous.fill(np.inf)
        for _ in range(_MAX_STEPS):
            np.multiply(eps, eps, out=a)
            a *= eps
            np.divide(w, a, out=a)  # w / eps^3
            np.multiply(eps, growth, out=b)
            np.subtract(b, a, out=a)
            a += 1  # 1 + g eps - w / eps^3
            b *= 4
            b += 3  # 3 + 4 g eps
            a /= b  # r
            # Monotone convergence shrinks every step of a sample; one that does not shrink is
            # rounding noise (a softening tissue near its largest force, where the curve is
            # flat and the residual is all rounding): it is not taken, and that sample is done.
            np.absolute(a, out=b)
            np.less(b, previous, out=shrinks)
            a *= shrinks
            np.multiply(b, shrinks, out=previous)
            np.subtract(1, a, out=a)
            eps *= a
            if previous.max() <= last_step:
                break
        if zero is not None:
            eps[zero] = 0.0
    return strain


def _start_stiffening(eps: np.ndarray, w: np.ndarray, g: float, a, b) -> None:
    # eps^3 (1 + g eps) <= 2 max(eps^3, g eps^4): the root is at least the smaller of the two
    # single-term roots at w / 2; the fixed point at that lower bound is an upper bound.
    np.multiply(w, 0.5, out=a)
    np.cbrt(a, out=a)
    np.multiply(w, 0.5 / g, out=b)
    np.sqrt(b, out=b)
    np.sqrt(b, out=b)
    np.minimum(a, b, out=a)
    _fixed_point(eps, w, g, a)


def _start_softening(eps: np.ndarray, w: np.ndarray, g: float, a, b) -> None:
    # On the rising branch (g eps <= 3/4) 1/4 <= 1 + g eps <= 1: cbrt(w) <= root <= cbrt(4 w).
    # The inflection is at eps = 1 / (2 |g|), where the curve is at w = eps^3 / 2.
    inflection = 0.5 / -g
    concave = w > (0.5 * inflection**3 if inflection < 1e100 else np.inf)
    np.multiply(w, 4, out=a)
    np.cbrt(a, out=a)
    np.minimum(a, inflection, out=a)
    _fixed_point(eps, w, g, a)  # at an upper bound: an upper bound, for the convex side
    np.cbrt(w, out=a)
    _fixed_point(b, w, g, a)  # at a lower bound: a lower bound, for the concave side
    np.maximum(b, inflection, out=b)
    np.copyto(eps, b, where=concave)


def _fixed_point(out: np.ndarray, w: np.ndarray, g: float, bound: np.ndarray) -> None:
    """``out = cbrt(w / (1 + g bound))``; ``bound`` is overwritten."""
    bound *= g
    bound += 1
    np.divide(w, bound, out=out)
    np.cbrt(out, out=out)


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
