"""The TF/CASR display: a cone of air-filled telescopic cylinders (seed 001, 9.4.1).

A finger pressing the top by z sees the contact area of a cone of base radius R and height H::

    A(z)  = pi z^2 R^2 / H^2          contact area, m^2
    dV(z) = pi z^3 R^2 / (3 H^2)      volume swept by the indentation, m^3 (|delta V| in the seed)
    F     = -p dV/dz = p A(z)         reaction force at pressure p, N (eqs. 9.2, 9.3)

so the display's force/area law at a constant pressure is the straight line F = p A. The
inverse problems take square roots near zero indentation; they are written so that a zero
force or area gives exactly zero indentation and tiny ones keep full relative precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pinarray.softness._checks import SoftnessError, nonnegative, positive, positive_scalar

#: Seed 001, 9.4.1: "H = 0.01 m is the maximum height, and R = 0.0065 m is the radius".
CASR_BASE_RADIUS_M = 0.0065
CASR_HEIGHT_M = 0.01

_U = np.finfo(float).eps / 2  # the unit of rounding, 2^-53: + - * / and sqrt err by at most u
# The area at full indentation, pi (H (R / H))^2 in `area_m2`, rounds four times (R / H, the
# product, the square, pi times it), the first two squared: within 6 u of pi R^2; the base area
# pi R R rounds twice: within 2 u. A force p A(H) divided back by the pressure rounds twice more.
# An area at most 10 u (at most 10 ulps) past the base is the base, come back through the
# display's own forward functions.
_AREA_ROUND_TRIP = 10 * _U


@dataclass(frozen=True)
class ConeDisplay:
    """The CASR display's geometry.

    Parameters
    ----------
    base_radius_m : float
        R, radius at the base of the cone, m.
    height_m : float
        H, height of the cone, which is also the largest indentation, m.
    """

    base_radius_m: float = CASR_BASE_RADIUS_M
    height_m: float = CASR_HEIGHT_M

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "base_radius_m", positive_scalar("base_radius_m", self.base_radius_m)
        )
        object.__setattr__(self, "height_m", positive_scalar("height_m", self.height_m))

    @property
    def max_area_m2(self) -> float:
        """Area at full indentation, pi R^2, m^2."""
        return float(np.pi * self.base_radius_m * self.base_radius_m)

    def _indentation(self, indentation_m: object) -> np.ndarray:
        z = nonnegative("indentation_m", indentation_m)
        beyond = z > self.height_m
        if beyond.any():
            raise SoftnessError(
                f"indentation_m must be at most the display height {self.height_m:g} m, "
                f"found {z[beyond].flat[0]:.6g}"
            )
        return z

    def area_m2(self, indentation_m: object) -> np.ndarray:
        """Contact area A(z) = pi z^2 R^2 / H^2, m^2.

        Parameters
        ----------
        indentation_m : array_like
            z, m, in [0, H].
        """
        z = self._indentation(indentation_m)
        radius = z * (self.base_radius_m / self.height_m)  # of the contact circle
        return np.pi * (radius * radius)  # a product, not a power: rounded alike everywhere

    def swept_volume_m3(self, indentation_m: object) -> np.ndarray:
        """Volume swept by an indentation z, pi z^3 R^2 / (3 H^2), m^3."""
        z = self._indentation(indentation_m)
        return np.pi * z**3 * (self.base_radius_m / self.height_m) ** 2 / 3

    def force_n(self, pressure_pa: object, indentation_m: object) -> np.ndarray:
        """Reaction force F = p A(z), N (eq. 9.3).

        Parameters
        ----------
        pressure_pa : array_like
            Gauge pressure inside the display, Pa, >= 0.
        indentation_m : array_like
            z, m, in [0, H]; broadcast against ``pressure_pa``.
        """
        return nonnegative("pressure_pa", pressure_pa) * self.area_m2(indentation_m)

    def indentation_for_area_m(self, area_m2: object) -> np.ndarray:
        """Indentation that exposes a contact area, z = (H / R) sqrt(A / pi), m.

        Raises `SoftnessError` for an area beyond the base, pi R^2; one within rounding of the
        base (see `_AREA_ROUND_TRIP`) is the base, at the full height.
        """
        area = nonnegative("area_m2", area_m2)
        beyond = area > self.max_area_m2 * (1 + _AREA_ROUND_TRIP)
        if beyond.any():
            raise SoftnessError(
                f"area_m2 must be at most the display's base area {self.max_area_m2:.6g} m^2, "
                f"found {area[beyond].flat[0]:.6g}"
            )
        depth = np.minimum(
            (self.height_m / self.base_radius_m) * np.sqrt(area / np.pi), self.height_m
        )
        # the base's own area, or one within rounding past it: the full height, exactly
        return np.where(area >= self.max_area_m2, self.height_m, depth)

    def max_force_n(self, pressure_pa: object) -> np.ndarray:
        """Largest force the display balances at a pressure, p pi R^2, N (pressed to its base)."""
        return nonnegative("pressure_pa", pressure_pa) * self.max_area_m2

    def balances(self, force_n: object, pressure_pa: object) -> np.ndarray:
        """Whether the display balances a force at a pressure before bottoming out: the forces
        `indentation_for_force_m` answers rather than refuses (an empty display, at zero
        pressure, balances only zero force)."""
        force = nonnegative("force_n", force_n)
        pressure = nonnegative("pressure_pa", pressure_pa)
        area = np.divide(force, pressure, out=np.where(force > 0, np.inf, 0.0), where=pressure > 0)
        return area <= self.max_area_m2 * (1 + _AREA_ROUND_TRIP)

    def indentation_for_force_m(self, force_n: object, pressure_pa: object) -> np.ndarray:
        """Indentation at which the display balances a force at a pressure, m.

        z = (H / R) sqrt(F / (pi p)). A force needing more than the height H raises
        `SoftnessError` (the display bottoms out).

        Parameters
        ----------
        force_n : array_like
            Force, N, >= 0.
        pressure_pa : array_like
            Pressure, Pa, > 0.
        """
        force = nonnegative("force_n", force_n)
        pressure = positive("pressure_pa", pressure_pa)
        return self.indentation_for_area_m(force / pressure)

    def pressure_for_force_pa(self, force_n: object, indentation_m: object) -> np.ndarray:
        """Pressure at which the display pushes back with a force at an indentation, Pa.

        p = F / A(z).

        Zero force needs zero pressure at any indentation. A positive force at zero
        indentation has no finite answer (no area to push on) and raises `SoftnessError`.
        """
        force, area = np.broadcast_arrays(
            nonnegative("force_n", force_n), self.area_m2(indentation_m)
        )
        impossible = (area == 0) & (force > 0)
        if impossible.any():
            raise SoftnessError(
                f"force_n {force[impossible].flat[0]:.6g} at zero indentation_m needs an unbounded "
                "pressure: "
                "the display has no contact area there"
            )
        return np.divide(force, area, out=np.zeros_like(force, dtype=float), where=area > 0)
