"""The telescopic softness display: concentric cylinders under one pressure (seed 000, 4.2).

The finger first meets the central cylinder of area A_0; every further step of height
dh brings the next cylinder into contact, and the areas grow by a constant ratio,
A_i = A_{i-1} dA = A_0 dA^i. Under a pressure p_0 the display pushes back with
F_i = p_0 A_i, so its force/area (and force/indentation) characteristic is a staircase.
A pneumatic servo valve can set a different pressure on each step to follow a target
force/area curve of a tissue.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pinarray.softness._checks import SoftnessError, nonnegative, positive, positive_scalar

_LARGEST_LOG10 = math.log10(sys.float_info.max)


@dataclass(frozen=True)
class TelescopicDisplay:
    """The display's geometry.

    Parameters
    ----------
    central_area_m2 : float
        A_0, area of the central cylinder, m^2.
    area_ratio : float
        dA, ratio of each cylinder's contact area to the previous one's, > 1.
    step_height_m : float
        dh, indentation between one cylinder and the next coming into contact, m.
    cylinder_count : int
        Number of cylinders, >= 1.
    """

    central_area_m2: float
    area_ratio: float
    step_height_m: float
    cylinder_count: int

    def __post_init__(self) -> None:
        for name in ("central_area_m2", "area_ratio", "step_height_m"):
            object.__setattr__(self, name, positive_scalar(name, getattr(self, name)))
        if self.area_ratio <= 1:
            raise SoftnessError(f"area_ratio must be greater than 1, found {self.area_ratio!r}")
        if not isinstance(self.cylinder_count, int) or self.cylinder_count < 1:
            raise SoftnessError(
                f"cylinder_count must be a whole number >= 1, found {self.cylinder_count!r}"
            )
        # The outermost area A_0 dA^(n-1), in logarithms: past the largest float it would be
        # infinite, and every force and fit after it with it.
        outermost_log10 = (math.log10(self.central_area_m2)
                           + (self.cylinder_count - 1) * math.log10(self.area_ratio))
        if outermost_log10 >= _LARGEST_LOG10:
            raise SoftnessError(
                f"expected an outermost cylinder's area below 10^{_LARGEST_LOG10:.0f} m^2 (the "
                f"largest number a float holds), found 10^{outermost_log10:.0f} m^2 "
                f"({self.cylinder_count} cylinders, area_ratio {self.area_ratio:g}): fewer "
                "cylinders or a smaller area_ratio"
            )

    @property
    def step_areas_m2(self) -> np.ndarray:
        """A_i = A_0 dA^i for each cylinder i = 0 .. n-1, m^2."""
        return self.central_area_m2 * self.area_ratio ** np.arange(self.cylinder_count)

    def step_index(self, indentation_m: object) -> np.ndarray:
        """Index of the outermost cylinder in contact at an indentation (0 = the central one).

        Step i starts at indentation i dh; past the last step the index stays at n - 1.
        """
        z = nonnegative("indentation_m", indentation_m)
        steps = z / self.step_height_m
        # A step's start i dh, computed as `staircase_points` does, rounds once, and the
        # quotient once more: i dh / dh comes back as low as i (1 - u)^2 (u = 2^-53), a rounding
        # step below i, which would floor into the step before. Scaling by 1 + 4 u (1 + 2 eps,
        # the second float above 1) lifts it to at least i (1 + u) > i, and i is a float, so its
        # rounding cannot fall below i: an indentation within rounding of a step's start is on
        # that step.
        steps *= 1 + 2 * np.finfo(float).eps
        return np.minimum(np.floor(steps), self.cylinder_count - 1).astype(int)

    def area_m2(self, indentation_m: object) -> np.ndarray:
        """Contact area at an indentation, m^2 (a staircase)."""
        return self.step_areas_m2[self.step_index(indentation_m)]

    def force_n(self, pressure_pa: object, indentation_m: object) -> np.ndarray:
        """Reaction force F_i = p_0 A_i at an indentation under a constant pressure, N."""
        return nonnegative("pressure_pa", pressure_pa) * self.area_m2(indentation_m)

    def pressure_schedule_pa(
        self, force_at_area_n: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """Pressure on each step that makes the display follow a force/area curve, Pa.

        p_i = F(A_i) / A_i, so at the area of every cylinder the display's force equals the
        target's.

        Parameters
        ----------
        force_at_area_n : callable
            The target curve: areas in m^2 -> forces in N (e.g. ``HertzContact.force_for_area_n``).
        """
        areas = self.step_areas_m2
        return nonnegative("target force", force_at_area_n(areas)) / areas

    def best_constant_pressure_pa(
        self, force_at_area_n: Callable[[np.ndarray], np.ndarray]
    ) -> float:
        """The single pressure p_0 whose staircase p_0 A_i fits the target best, Pa.

        Minimising sum_i (p A_i - F(A_i))^2 over p gives p = sum F_i A_i / sum A_i^2, computed
        with the areas over the largest (s): p = sum F_i (A_i / s) / (s sum (A_i / s)^2), so
        no square of an area overflows.
        """
        areas = self.step_areas_m2
        forces = nonnegative("target force", force_at_area_n(areas))
        largest = float(areas[-1])
        scaled = areas / largest
        with np.errstate(over="ignore"):
            pressure = float(np.dot(forces, scaled) / (largest * np.dot(scaled, scaled)))
        if not math.isfinite(pressure):
            raise SoftnessError("expected a best single pressure a float can hold, found one "
                                "past the largest: a smaller target force or display")
        return pressure


def staircase_points(
    display: TelescopicDisplay, pressure_pa: object
) -> tuple[np.ndarray, np.ndarray]:
    """Corner points (indentation_m, force_n) of the staircase, for plotting.

    ``pressure_pa`` is one pressure for every step, or one per step (a schedule).
    """
    pressure = np.broadcast_to(positive("pressure_pa", pressure_pa), (display.cylinder_count,))
    starts = np.arange(display.cylinder_count) * display.step_height_m
    ends = starts + display.step_height_m
    forces = pressure * display.step_areas_m2
    return np.column_stack([starts, ends]).ravel(), np.repeat(forces, 2)
