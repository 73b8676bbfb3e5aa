"""Hertz contact of two elastic solids of revolution (seed 000, eqs. 1-7; seed 001, 9.3).

The contact is a circle of radius ``a``; with relative radius ``R`` (1/R = 1/R1 + 1/R2) and
effective modulus ``E*`` (1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2)::

    a     = (3 F R / (4 E*))^(1/3)          contact radius, m
    A     = pi a^2                           contact area, m^2 (eq. 7)
    delta = a^2 / R                          mutual approach, m (eq. 5, delta = pi a p0 / 2E*)
    p0    = 2 E* a / (pi R)                  peak pressure, Pa (eq. 5)
    F     = (4/3) E* sqrt(R) delta^(3/2)     the same law read from the approach

Near zero force the curves have infinite slope (a ~ F^(1/3)); every formula here is written
so that it is exact at zero and loses no relative precision for micro-newton forces: no
0/0 (the peak pressure comes from ``a``, not from ``F / a^2``) and ``cbrt`` instead of a
fractional power of a product that could underflow.

The theory holds while the contact is small against the bodies: seed 000 (4.1) asks that
"their dimensions must be significantly bigger than contact area", Johnson (Contact
Mechanics, 1985, 4.2, assumptions i-iii) that it be small against the radii, a << R. Past
``SMALL_CONTACT_FRACTION`` R the results are an extrapolation (see `small_contact_force_n`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pinarray.softness._checks import (
    SoftnessError,
    nonnegative,
    poisson_ratio,
    positive_or_infinite,
    positive_scalar,
)

#: Hertz replaces each surface by the parabola r^2 / 2R, which departs from a sphere's profile
#: by a relative r^2 / 4R^2: 0.25 % at a = 0.1 R, 6 % at 0.5 R, and the strains (about a / R)
#: stop being small. a <= 0.1 R is the usual reading of "a << R"; a convention, not a law.
SMALL_CONTACT_FRACTION = 0.1


def effective_modulus_pa(
    young_1_pa: object, poisson_1: object, young_2_pa: object = np.inf, poisson_2: object = 0.0
) -> np.ndarray:
    """Effective (contact) modulus E* of two bodies.

    Parameters
    ----------
    young_1_pa, young_2_pa : array_like
        Young's moduli, Pa. ``young_2_pa = inf`` (the default) is a rigid second body, and then
        ``1/E* = (1 - nu1^2)/E1``.
    poisson_1, poisson_2 : array_like
        Poisson's ratios, dimensionless, in (-1, 0.5].

    Returns
    -------
    ndarray
        E*, Pa.
    """
    young_1 = positive_or_infinite("young_1_pa", young_1_pa)
    young_2 = positive_or_infinite("young_2_pa", young_2_pa)
    nu_1 = poisson_ratio("poisson_1", poisson_1)
    nu_2 = poisson_ratio("poisson_2", poisson_2)
    # nu nu, not nu**2: a product rounds alike everywhere, and 1 - nu^2 magnifies the square's
    # error up to 49-fold at nu = -0.99
    compliance = (1 - nu_1 * nu_1) / young_1 + (1 - nu_2 * nu_2) / young_2
    if np.any(compliance == 0):
        raise SoftnessError(
            "young_1_pa and young_2_pa are both infinite: two rigid bodies never deform"
        )
    return 1.0 / compliance


def relative_radius_m(radius_1_m: object, radius_2_m: object = np.inf) -> np.ndarray:
    """Relative radius of curvature R, with 1/R = 1/R1 + 1/R2.

    Parameters
    ----------
    radius_1_m, radius_2_m : array_like
        Radii of curvature of the two bodies at the contact, m; ``inf`` is a flat surface
        (the default second body), and then R = R1.

    Returns
    -------
    ndarray
        R, m.
    """
    r1 = positive_or_infinite("radius_1_m", radius_1_m)
    r2 = positive_or_infinite("radius_2_m", radius_2_m)
    curvature = 1.0 / r1 + 1.0 / r2
    if np.any(curvature == 0):
        raise SoftnessError(
            "radius_1_m and radius_2_m are both infinite: two flat surfaces have no Hertz contact"
        )
    return 1.0 / curvature


@dataclass(frozen=True)
class HertzContact:
    """A Hertz contact between two bodies, described by R and E*.

    Parameters
    ----------
    relative_radius_m : float
        R, m (see `relative_radius_m`).
    effective_modulus_pa : float
        E*, Pa (see `effective_modulus_pa`).
    """

    relative_radius_m: float
    effective_modulus_pa: float

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "relative_radius_m", positive_scalar("relative_radius_m", self.relative_radius_m)
        )
        object.__setattr__(
            self,
            "effective_modulus_pa",
            positive_scalar("effective_modulus_pa", self.effective_modulus_pa),
        )

    @classmethod
    def sphere_on_rigid_plane(
        cls, radius_m: float, young_pa: float, poisson: float
    ) -> HertzContact:
        """An elastic sphere pressed on a rigid flat (the seed's rigid-body limit)."""
        return cls(
            float(relative_radius_m(radius_m)), float(effective_modulus_pa(young_pa, poisson))
        )

    def contact_radius_m(self, force_n: object) -> np.ndarray:
        """Radius a of the contact circle under a force F, m: a = (3 F R / 4 E*)^(1/3).

        Parameters
        ----------
        force_n : array_like
            Compressing force, N, finite and >= 0.
        """
        force = nonnegative("force_n", force_n)
        return np.cbrt(0.75 * force * (self.relative_radius_m / self.effective_modulus_pa))

    def contact_area_m2(self, force_n: object) -> np.ndarray:
        """Contact area A = pi (3 F R / 4 E*)^(2/3) under a force, m^2 (eq. 7)."""
        return np.pi * self.contact_radius_m(force_n) ** 2

    def approach_m(self, force_n: object) -> np.ndarray:
        """Mutual approach delta = a^2 / R of distant points under a force, m."""
        return self.contact_radius_m(force_n) ** 2 / self.relative_radius_m

    def peak_pressure_pa(self, force_n: object) -> np.ndarray:
        """Pressure p0 at the centre of the contact, Pa: p0 = 2 E* a / (pi R) (eq. 5)."""
        return (
            2
            * self.effective_modulus_pa
            * self.contact_radius_m(force_n)
            / (np.pi * self.relative_radius_m)
        )

    def pressure_pa(self, distance_m: object, force_n: float) -> np.ndarray:
        """Contact pressure p(r) = p0 sqrt(1 - (r/a)^2) at distances r from the centre, Pa (eq. 2).

        Zero outside the contact circle (r > a) and everywhere at zero force.

        Parameters
        ----------
        distance_m : array_like
            Radial distances r from the centre of the contact, m, >= 0.
        force_n : float
            Compressing force, N.
        """
        r = nonnegative("distance_m", distance_m)
        a = float(self.contact_radius_m(force_n))
        p0 = float(self.peak_pressure_pa(force_n))
        if a == 0.0:
            return np.zeros_like(r)
        # (a - r)(a + r) rather than a^2 - r^2: no cancellation at the rim.
        inside = np.clip((a - r) * (a + r), 0.0, None)
        return p0 * np.sqrt(inside) / a

    def force_for_area_n(self, area_m2: object) -> np.ndarray:
        """Force that makes a given contact area, N: F = 4 E* a^3 / (3 R), a = sqrt(A / pi).

        Parameters
        ----------
        area_m2 : array_like
            Contact area, m^2, finite and >= 0.
        """
        return self.force_for_contact_radius_n(np.sqrt(nonnegative("area_m2", area_m2) / np.pi))

    def force_for_contact_radius_n(self, contact_radius_m: object) -> np.ndarray:
        """Force that makes a contact circle of radius a, N: F = 4 E* a^3 / (3 R).

        Parameters
        ----------
        contact_radius_m : array_like
            a, m, finite and >= 0.
        """
        a = nonnegative("contact_radius_m", contact_radius_m)
        return 4 * self.effective_modulus_pa * a**3 / (3 * self.relative_radius_m)

    @property
    def small_contact_force_n(self) -> float:
        """Largest force inside Hertz's small-contact assumption, N: the force that makes
        a = `SMALL_CONTACT_FRACTION` R."""
        return float(
            self.force_for_contact_radius_n(SMALL_CONTACT_FRACTION * self.relative_radius_m)
        )

    def force_for_approach_n(self, approach_m: object) -> np.ndarray:
        """Force that makes a given approach, N: F = (4/3) E* sqrt(R) delta^(3/2).

        Parameters
        ----------
        approach_m : array_like
            Mutual approach delta, m, finite and >= 0.
        """
        delta = nonnegative("approach_m", approach_m)
        return (
            4
            / 3
            * self.effective_modulus_pa
            * np.sqrt(self.relative_radius_m)
            * delta
            * np.sqrt(delta)
        )
