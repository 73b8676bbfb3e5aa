"""Softness models: evaluation throughput on 1e6 samples, and the tracking simulation's
error against its time step (measured against a run with a 100x finer step)."""

import time

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

SAMPLES = 1_000_000


def _best_seconds(call, repeats: int = 3) -> float:
    best = np.inf
    for _ in range(repeats):
        started = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - started)
    return best


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
    cases = [
        ("hertz contact_area_m2", lambda: hertz.contact_area_m2(force)),
        ("hertz force_for_area_n", lambda: hertz.force_for_area_n(area)),
        ("cone force_n", lambda: cone.force_n(pressure, depth)),
        ("cone indentation_for_area_m", lambda: cone.indentation_for_area_m(area)),
        ("eq. 9.4 area_m2 (stable inverse)", lambda: M1_R11_FORCE_AREA.area_m2(force)),
        ("control_commands", lambda: control_commands(SEED_EXAMPLE_MATERIAL, force)),
        ("tissue force_for_area_n", lambda: stiffening.force_for_area_n(area)),
        ("tissue area_for_force_m2 (Newton)", lambda: stiffening.area_for_force_m2(force)),
        ("tissue display_pressure_pa", lambda: stiffening.display_pressure_pa(area)),
    ]
    print(f"{'evaluation on 1e6 samples':<38} {'ms':>8} {'ns/sample':>10} {'Msamples/s':>11}")
    for name, call in cases:
        seconds = _best_seconds(call)
        print(
            f"{name:<38} {seconds * 1e3:>8.1f} {seconds * 1e9 / SAMPLES:>10.1f} "
            f"{SAMPLES / seconds / 1e6:>11.1f}"
        )


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
        f"{'step_ms':>8} {'steps':>7} {'ms/run':>7} {'max_dz_um':>10} {'rms_dz_um':>10} "
        f"{'max_dA_mm2':>11} {'order':>6} {'track_um':>9}"
    )
    previous = None
    for step_ms in (20.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.1, 0.05):
        started = time.perf_counter()
        run = simulate_force_ramp(
            SEED_EXAMPLE_MATERIAL, peak_n, duration_s, step_ms * 1e-3, valve=valve, lags=lags
        )
        elapsed_ms = (time.perf_counter() - started) * 1e3
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
            f"{step_ms:>8g} {run.time_s.size - 1:>7} {elapsed_ms:>7.1f} {max_dz * 1e6:>10.3g} "
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
