"""Combined CASR + DHD control (seed 001, 9.5.1, eqs. 9.6-9.9).

A material is reduced to its leading terms (eq. 9.6)::

    F_m = alpha_m A_m^2          force/area
    z_m = beta_m F_m             force/displacement

The CASR cone display renders the area: imposing F = p A(z_C) = F_m at A(z_C) = A_m gives
the pressure p = alpha_m A_m (eq. 9.7) = sqrt(alpha_m F). The DHD in series renders the rest
of the displacement, z_D = z_m - z_C (eqs. 9.8, 9.9). Two things can go wrong and are flagged
rather than hidden: z_D < 0 (the DHD must pull the display up towards the finger) and a
pressure outside the valve's range; a third, an area beyond the cone's base, means the
display has bottomed out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pinarray.softness._checks import SoftnessError, nonnegative, positive_scalar
from pinarray.softness.identification import LinearForceDisplacement, QuadraticForceArea
from pinarray.softness.tf_display import ConeDisplay
from pinarray.softness.units import M2_PER_CM2, M_PER_CM

# A force read off the material's curve at an area, F = alpha A^2 (two roundings), comes back
# as A' = sqrt(F / alpha) (two more, the first two halved under the root): within 2.5 u of A
# (u = 2^-53). A force at a pressure, F = p^2 / alpha, comes back as p' = alpha A' within
# 3.5 u. An area or a pressure at most 4 u past a limit is on it: a display filled to its base
# is not bottomed and a valve asked for its largest pressure can hold it, on every machine.
_AT_LIMIT = 2 * np.finfo(float).eps


@dataclass(frozen=True)
class Material:
    """A material to render, by the leading terms of its curves (eq. 9.6).

    Parameters
    ----------
    alpha_n_per_m4 : float
        alpha_m in F = alpha_m A^2, N/m^4.
    beta_m_per_n : float
        beta_m in z = beta_m F (a compliance), m/N.
    """

    alpha_n_per_m4: float
    beta_m_per_n: float

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "alpha_n_per_m4", positive_scalar("alpha_n_per_m4", self.alpha_n_per_m4)
        )
        object.__setattr__(self, "beta_m_per_n", positive_scalar("beta_m_per_n", self.beta_m_per_n))

    @classmethod
    def from_cm(cls, alpha_n_per_cm4: float, beta_cm_per_n: float) -> Material:
        """The material from the seed's units: alpha in N/cm^4, beta in cm/N."""
        return cls(alpha_n_per_cm4 / M2_PER_CM2**2, beta_cm_per_n * M_PER_CM)

    @classmethod
    def from_fits(
        cls, force_area: QuadraticForceArea, force_displacement: LinearForceDisplacement
    ) -> Material:
        """Keep the quadratic term of a force/area fit and the slope of a force/displacement fit,
        dropping the lower-order terms and the intercept as the seed does for eq. 9.6."""
        return cls(force_area.a_n_per_m4, 1.0 / force_displacement.slope_n_per_m)

    def area_m2(self, force_n: object) -> np.ndarray:
        """A_m = sqrt(F / alpha_m), m^2."""
        return np.sqrt(nonnegative("force_n", force_n) / self.alpha_n_per_m4)

    def displacement_m(self, force_n: object) -> np.ndarray:
        """z_m = beta_m F, m."""
        return self.beta_m_per_n * nonnegative("force_n", force_n)


@dataclass(frozen=True)
class ValveRange:
    """Gauge pressures the servo valve can hold, Pa.

    The seed names a Proportion-Air QB valve without its range; the default 0-100 kPa is an
    assumption to be replaced with the fitted valve's datasheet range.
    """

    min_pa: float = 0.0
    max_pa: float = 100e3

    def __post_init__(self) -> None:
        low = float(nonnegative("min_pa", self.min_pa))
        high = positive_scalar("max_pa", self.max_pa)
        if low >= high:
            raise SoftnessError(
                f"valve range must have min_pa < max_pa, found {low:g} Pa and {high:g} Pa"
            )
        object.__setattr__(self, "min_pa", low)
        object.__setattr__(self, "max_pa", high)


@dataclass(frozen=True, eq=False)
class ControlCommands:
    """Set points for a series of forces, all arrays of the forces' shape (SI units)."""

    force_n: np.ndarray
    material_area_m2: np.ndarray
    material_displacement_m: np.ndarray
    pressure_pa: np.ndarray
    """p = alpha_m A_m (eq. 9.7), as wanted; see ``pressure_out_of_range``."""
    casr_displacement_m: np.ndarray
    """z_C, capped at the cone's height when the display bottoms out."""
    dhd_displacement_m: np.ndarray
    """z_D = z_m - z_C (eq. 9.9)."""
    dhd_must_pull: np.ndarray
    pressure_out_of_range: np.ndarray
    display_bottomed: np.ndarray


def control_commands(
    material: Material,
    force_n: object,
    display: ConeDisplay = ConeDisplay(),  # noqa: B008 - frozen, so one shared default is safe
    valve: ValveRange = ValveRange(),  # noqa: B008
) -> ControlCommands:
    """Pressure and DHD displacement that render a material at each force (eqs. 9.7-9.9).

    Parameters
    ----------
    material : Material
    force_n : array_like
        Forces the finger applies, N, >= 0.
    display : ConeDisplay
    valve : ValveRange
    """
    force = nonnegative("force_n", force_n)
    area = material.area_m2(force)
    pressure = material.alpha_n_per_m4 * area
    bottomed = area > display.max_area_m2 * (1 + _AT_LIMIT)
    casr = display.indentation_for_area_m(np.minimum(area, display.max_area_m2))
    dhd = material.displacement_m(force) - casr
    return ControlCommands(
        force_n=force,
        material_area_m2=area,
        material_displacement_m=material.displacement_m(force),
        pressure_pa=pressure,
        casr_displacement_m=casr,
        dhd_displacement_m=dhd,
        dhd_must_pull=dhd < 0,
        pressure_out_of_range=(pressure < valve.min_pa * (1 - _AT_LIMIT))
        | (pressure > valve.max_pa * (1 + _AT_LIMIT)),
        display_bottomed=bottomed,
    )


#: The seed reports one force/area fit (eq. 9.4, M1, R = 1.1 cm: alpha = 1.4 N/cm^4) and one
#: force/displacement fit (eq. 9.5, M2, R = 1.4 cm: beta = 1/23 cm/N); this pairs them.
SEED_EXAMPLE_MATERIAL = Material.from_cm(1.4, 1 / 23)


@dataclass(frozen=True)
class ActuatorLags:
    """First-order time constants of the valve's pressure and the DHD's position loop, s.

    Zero is an ideal actuator that follows its command at once.
    """

    valve_s: float = 0.02
    dhd_s: float = 0.01

    def __post_init__(self) -> None:
        object.__setattr__(self, "valve_s", float(nonnegative("valve_s", self.valve_s)))
        object.__setattr__(self, "dhd_s", float(nonnegative("dhd_s", self.dhd_s)))


#: A first-order lag forgets where it started within e^-5 < 1 % after five time constants;
#: behind the square-root command its relative error, about tau / 2t, is 10 % by then.
STARTUP_TIME_CONSTANTS = 5


@dataclass(frozen=True, eq=False)
class TrackingRun:
    """A simulated force ramp: desired (material) and rendered (display) curves over time."""

    time_s: np.ndarray
    commands: ControlCommands
    pressure_pa: np.ndarray
    """Pressure the valve actually holds."""
    rendered_area_m2: np.ndarray
    rendered_displacement_m: np.ndarray
    dhd_displacement_m: np.ndarray
    """DHD displacement the position loop actually reaches."""
    valve: ValveRange = field(default_factory=ValveRange)
    lags: ActuatorLags = field(default_factory=ActuatorLags)

    @property
    def startup_s(self) -> float:
        """Length of the start-up, s: `STARTUP_TIME_CONSTANTS` of the slower actuator.

        The commands are infinitely steep at zero force (p = sqrt(alpha_m F), z_C ~ F^(1/4)).
        A valve that lags holds almost no pressure at the first touch, so the display sinks
        towards its base (area up to pi R^2, displacement up to H) until the pressure catches
        up; a lagging DHD likewise trails its command. Both overshoot at the start.
        """
        return STARTUP_TIME_CONSTANTS * max(self.lags.valve_s, self.lags.dhd_s)

    @property
    def in_startup(self) -> np.ndarray:
        """Which samples fall in the start-up (see `startup_s`), a boolean array."""
        return self.time_s < self.startup_s

    @property
    def area_error_m2(self) -> np.ndarray:
        """Rendered minus desired area, m^2."""
        return self.rendered_area_m2 - self.commands.material_area_m2

    @property
    def displacement_error_m(self) -> np.ndarray:
        """Rendered minus desired displacement, m."""
        return self.rendered_displacement_m - self.commands.material_displacement_m


def first_order_lag(command: np.ndarray, time_step_s: float, time_constant_s: float) -> np.ndarray:
    """Response of tau x' = u - x to a command sampled every step, starting settled at u[0].

    Exact for a command that is linear between samples (first-order hold), so the only
    discretisation error comes from how far the command bends within a step; unconditionally
    stable for any step, unlike explicit Euler, which diverges past two time constants.
    """
    if time_constant_s == 0:
        return command.copy()
    ratio = time_step_s / time_constant_s
    decay = float(np.exp(-ratio))
    # For u = u0 + s t over a step h: x(h) = u1 - s tau (1 - e^(-h/tau)) + (x0 - u0) e^(-h/tau);
    # expm1 keeps 1 - e^(-h/tau) precise when the step is tiny against tau.
    ramp_gain = float(-np.expm1(-ratio) / ratio)
    values = command.tolist()
    out = [values[0]]
    x = values[0]
    for u0, u1 in zip(values, values[1:], strict=False):
        x = u1 - (u1 - u0) * ramp_gain + (x - u0) * decay
        out.append(x)
    return np.asarray(out)


def simulate_force_ramp(
    material: Material,
    peak_force_n: float,
    duration_s: float,
    time_step_s: float,
    display: ConeDisplay = ConeDisplay(),  # noqa: B008
    valve: ValveRange = ValveRange(),  # noqa: B008
    lags: ActuatorLags = ActuatorLags(),  # noqa: B008
) -> TrackingRun:
    """Push on the combined system with a force rising linearly from 0 to a peak.

    The valve follows the pressure command (clipped to its range) with its lag; the display
    settles where F = p A(z_C), i.e. A = F / p, up to its base area; the DHD's position loop
    follows z_D = z_m - z_C, with z_C read from the display as in the seed, with its lag.
    The rendered displacement is z_C + z_D (Figs. 9.9, 9.10).

    Parameters
    ----------
    material : Material
    peak_force_n : float
        Force at the end of the ramp, N.
    duration_s : float
        Ramp duration, s.
    time_step_s : float
        Simulation step, s; the ramp is split into round(duration / step) equal steps.
    display, valve, lags
        The hardware.
    """
    peak = positive_scalar("peak_force_n", peak_force_n)
    duration = positive_scalar("duration_s", duration_s)
    step = positive_scalar("time_step_s", time_step_s)
    if step > duration:
        raise SoftnessError(
            f"time_step_s {step:g} s is longer than the ramp's duration_s {duration:g} s"
        )
    count = max(1, round(duration / step))
    time = np.linspace(0.0, duration, count + 1)
    step = duration / count
    commands = control_commands(material, peak * time / duration, display, valve)
    pressure = first_order_lag(
        np.clip(commands.pressure_pa, valve.min_pa, valve.max_pa), step, lags.valve_s
    )
    force = commands.force_n
    # F = p A; with no pressure a pushed display collapses to its base, an untouched one
    # stays at zero.
    area = np.divide(force, pressure, out=np.where(force > 0, np.inf, 0.0), where=pressure > 0)
    area = np.minimum(area, display.max_area_m2)
    casr = display.indentation_for_area_m(area)
    dhd = first_order_lag(material.displacement_m(force) - casr, step, lags.dhd_s)
    return TrackingRun(time, commands, pressure, area, casr + dhd, dhd, valve, lags)
