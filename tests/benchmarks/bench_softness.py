"""Softness models: evaluation throughput on 1e6 samples beside one numpy pass over them (and
the Newton inverse beside the naive bracketed solver it replaced), and the tracking
simulation's error against its time step (measured against a run with a 100x finer step).

Target (issue 17): the Newton inverse at >= 10 M samples/s."""

import numpy as np

from pinarray.softness.control import (
    SEED_EXAMPLE_MATERIAL,
    ActuatorLags,
    ValveRange,
    control_commands,
    simulate_force_ramp,
)
from pinarray.softness.forceps import TissueModel
from pinarray.softness.hertz import HertzContact
from pinarray.softness.identification import M1_R11_FORCE_AREA
from pinarray.softness.tf_display import ConeDisplay
from tests.benchmarks._timing import (
    RUNS,
    SPREAD_HEADER,
    interleaved_seconds,
    median,
    ratio,
    spread,
)

SAMPLES = 1_000_000


def naive_newton_area_m2(tissue: TissueModel, force_n: np.ndarray) -> np.ndarray:
    """The inverse as it was first written: bracketed Newton with a bisection fallback, every
    step on whole arrays with fresh temporaries (the reference for the in-place solver)."""
    scale = 0.75 * force_n / tissue.radius_m**2
    e0, e1 = tissue.e0_pa, tissue.e1_pa
    high = np.cbrt(scale / e0)
    if e1 < 0:
        high = np.minimum(np.cbrt(scale / (0.25 * e0)), tissue.max_strain)
    low = np.zeros_like(high)
    x = high.copy()
    for _ in range(200):
        excess = x**3 * (e0 + e1 * x) - scale
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
    return np.pi * (tissue.radius_m * x) ** 2


def _throughput() -> None:
    rng = np.random.default_rng(0)
    # micro-newtons to tens of newtons, log-spread
    force = 10.0 ** rng.uniform(-6, np.log10(50), SAMPLES)
    cone = ConeDisplay()
    depth = rng.uniform(0, cone.height_m, SAMPLES)
    area = rng.uniform(0, cone.max_area_m2, SAMPLES)
    pressure = rng.uniform(1e3, 1e5, SAMPLES)
    hertz = HertzContact(0.01, 1e5)
    stiffening = TissueModel(0.01, 4e4, 2e5)
    softening = TissueModel(0.01, 1e5, -1e5)  # rises up to eps = 0.75
    soft_force = rng.uniform(0, float(softening.force_for_strain_n(0.75)), SAMPLES)
    cases = {
        "one numpy multiply (reference)": lambda: np.multiply(force, 2.0),
        "hertz contact_area_m2": lambda: hertz.contact_area_m2(force),
        "hertz force_for_area_n": lambda: hertz.force_for_area_n(area),
        "cone force_n": lambda: cone.force_n(pressure, depth),
        "cone indentation_for_area_m": lambda: cone.indentation_for_area_m(area),
        "eq. 9.4 area_m2 (stable inverse)": lambda: M1_R11_FORCE_AREA.area_m2(force),
        "control_commands": lambda: control_commands(SEED_EXAMPLE_MATERIAL, force),
        "tissue force_for_area_n": lambda: stiffening.force_for_area_n(area),
        "tissue area_for_force_m2 (Newton)": lambda: stiffening.area_for_force_m2(force),
        "  naive bracketed Newton": lambda: naive_newton_area_m2(stiffening, force),
        "softening tissue area_for_force_m2": lambda: softening.area_for_force_m2(soft_force),
        "  naive bracketed Newton, softening": lambda: naive_newton_area_m2(softening, soft_force),
        "tissue display_pressure_pa": lambda: stiffening.display_pressure_pa(area),
    }
    times = interleaved_seconds(cases)
    reference = times["one numpy multiply (reference)"]
    print(f"evaluation on 1e6 samples, ms over {RUNS} interleaved runs; target: Newton >= 10 M/s")
    print(f"{'what':<36} {SPREAD_HEADER} {'Msamples/s':>11} {'vs multiply':>12} {'vs naive':>9}")
    naive_of = {
        "tissue area_for_force_m2 (Newton)": "  naive bracketed Newton",
        "softening tissue area_for_force_m2": "  naive bracketed Newton, softening",
    }
    for name in cases:
        if name in naive_of:
            against_naive = ratio(times[name], times[naive_of[name]])
        else:
            against_naive = "1.00x" if name in naive_of.values() else ""
        print(
            f"{name:<36} {spread(times[name])} {SAMPLES / median(times[name]) / 1e6:>11.1f} "
            f"{ratio(times[name], reference):>12} {against_naive:>9}"
        )
    # the two solvers agree (the naive one's settled answer is the yardstick)
    for tissue, forces in ((stiffening, force), (softening, soft_force)):
        ours, theirs = tissue.area_for_force_m2(forces), naive_newton_area_m2(tissue, forces)
        worst = np.max(np.abs(ours - theirs) / np.where(theirs > 0, theirs, 1))
        print(f"  largest relative difference from the naive solver: {worst:.1e}")


def _minimal_loop(steps: int) -> float:
    x = 0.0
    for _ in range(steps):
        x = x * 0.5 + 1.0
    return x


def _tracking_error(valve: ValveRange, label: str) -> None:
    lags = ActuatorLags(valve_s=0.02, dhd_s=0.01)
    duration_s, peak_n = 2.0, 2.0
    reference_step_s = 10e-6  # every step below is a whole multiple of it
    reference = simulate_force_ramp(
        SEED_EXAMPLE_MATERIAL, peak_n, duration_s, reference_step_s, valve=valve, lags=lags
    )
    print()
    print(
        f"tracking run, {label}: seed material, ramp to 2 N in 2 s, lags valve 20 ms / DHD 10 ms;"
    )
    print("  d* = difference from a 10 us reference run; track = rendered vs material, rms")
    print(
        f"  ms/run over {RUNS} interleaved runs; vs loop = against a bare Python loop of one "
        "multiply-add per step"
    )
    print(
        f"{'step_ms':>8} {'steps':>7} {SPREAD_HEADER} {'vs loop':>8} {'max_dz_um':>10} "
        f"{'rms_dz_um':>10} {'max_dA_mm2':>11} {'order':>6} {'track_um':>9}"
    )
    previous = None
    for step_ms in (20.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.1, 0.05):
        steps = round(duration_s / (step_ms * 1e-3))
        times = interleaved_seconds(
            {
                "run": lambda s=step_ms: simulate_force_ramp(
                    SEED_EXAMPLE_MATERIAL, peak_n, duration_s, s * 1e-3, valve=valve, lags=lags
                ),
                "loop": lambda n=steps: _minimal_loop(n),
            }
        )
        run = simulate_force_ramp(
            SEED_EXAMPLE_MATERIAL, peak_n, duration_s, step_ms * 1e-3, valve=valve, lags=lags
        )
        stride = round(step_ms * 1e-3 / reference_step_s)
        dz = run.rendered_displacement_m - reference.rendered_displacement_m[::stride]
        da = run.rendered_area_m2 - reference.rendered_area_m2[::stride]
        max_dz = np.max(np.abs(dz))
        order = (
            ""
            if previous is None
            else f"{np.log(previous[1] / max_dz) / np.log(previous[0] / step_ms):.2f}"
        )
        tracking = np.sqrt(np.mean(run.displacement_error_m**2))
        print(
            f"{step_ms:>8g} {run.time_s.size - 1:>7} {spread(times['run'], digits=2)} "
            f"{ratio(times['run'], times['loop']):>8} {max_dz * 1e6:>10.3g} "
            f"{np.sqrt(np.mean(dz**2)) * 1e6:>10.3g} {np.max(np.abs(da)) * 1e6:>11.3g} "
            f"{order:>6} {tracking * 1e6:>9.4g}"
        )
        previous = (step_ms, max_dz)


def run() -> None:
    _throughput()
    # Without preload the pressure command sqrt(alpha F) starts with infinite slope and the
    # lagging valve lets the display collapse for the first instants: errors converge slowly.
    _tracking_error(ValveRange(0.0, 100e3), "valve from 0 kPa")
    # A 1 kPa preload removes that singularity; the first-order-hold lag then converges fast.
    _tracking_error(ValveRange(1e3, 100e3), "valve preloaded to 1 kPa")
