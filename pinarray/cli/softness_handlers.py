"""Handlers of the ``pinarray softness ...`` subcommands (see `commands` for the options).

Each takes the parsed ``args`` in the lab's units, converts them to SI, prints a table and,
with ``--png``/``--out``, writes a plot. numpy and the models are imported inside each
handler so that the CLI starts without them.

Past 400 lines: one job, six short handlers (one per model) that share the table, plot and
sample-reading helpers; split by model, each file would import the others' helpers.
"""

import sys
from typing import Any

# A tracking run keeps every step in memory, about 100 bytes each: a million is 100 MB.
MAX_TRACK_STEPS = 1_000_000


def _table(headers: list[str], rows) -> None:
    cells = [[f"{v:.6g}" if isinstance(v, float) else str(v) for v in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) for i, h in enumerate(headers)]
    print("  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True)))
    for row in cells:
        print("  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)))


def _plot_path(args):
    from pathlib import Path

    from pinarray.cli.common import png_path

    if args.png:
        return Path(png_path(args.png))
    return Path(args.out) / f"{args.plot_name}.png" if args.out else None


def _rows(count: int, low: float, high: float):
    import numpy as np

    from pinarray.softness._checks import SoftnessError

    if count < 2:
        raise SoftnessError(f"--rows must be at least 2, found {count}")
    return np.linspace(low, high, count)


def _wrote(path) -> None:
    print(f"wrote {path}")


# A force typed as the small-contact limit (0.04/3 N for the seed's 10 mm, 100 kPa contact)
# differs from the limit computed here by a few roundings: a few ulps past it is on it.
_SAME_FORCE = 8 * 2.0**-53


def hertz(args) -> int:
    import numpy as np

    from pinarray.softness.hertz import (
        SMALL_CONTACT_FRACTION,
        HertzContact,
        effective_modulus_pa,
        relative_radius_m,
    )
    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA

    e_star = effective_modulus_pa(
        args.young_kpa * PA_PER_KPA, args.poisson, args.young2_kpa * PA_PER_KPA, args.poisson2
    )
    radius = relative_radius_m(args.radius_mm * M_PER_MM, args.radius2_mm * M_PER_MM)
    contact = HertzContact(float(radius), float(e_star))
    title = (
        f"Hertz contact: R = {contact.relative_radius_m / M_PER_MM:.4g} mm, "
        f"E* = {contact.effective_modulus_pa / PA_PER_KPA:.4g} kPa"
    )
    print(title)
    limit_n = contact.small_contact_force_n
    max_force_n = limit_n if args.max_force_n is None else args.max_force_n
    force = _rows(args.rows, 0.0, max_force_n)
    if max_force_n > limit_n * (1 + _SAME_FORCE):
        radius_mm = contact.relative_radius_m / M_PER_MM
        print(
            f"pinarray: warning: above {limit_n:.4g} N the contact radius passes "
            f"{SMALL_CONTACT_FRACTION:g} R ({SMALL_CONTACT_FRACTION * radius_mm:.4g} mm of "
            f"R = {radius_mm:.4g} mm), outside Hertz's small-contact assumption a << R "
            "(seed 000, 4.1; Johnson, Contact Mechanics, 4.2): rows past it are extrapolated",
            file=sys.stderr,
        )
    columns = (
        force,
        contact.contact_radius_m(force) / M_PER_MM,
        contact.contact_area_m2(force) / M2_PER_MM2,
        contact.approach_m(force) / M_PER_MM,
        contact.peak_pressure_pa(force) / PA_PER_KPA,
    )
    _table(["force_N", "radius_mm", "area_mm2", "approach_mm", "peak_kPa"], _zip(columns))
    if path := _plot_path(args):
        from pinarray.softness.plots import plot_hertz

        dense = np.linspace(0.0, max_force_n, 400)
        area, approach = contact.contact_area_m2(dense), contact.approach_m(dense)
        _wrote(plot_hertz(dense, area, approach, path, title))
    return 0


def _zip(columns):
    return zip(*(column.tolist() for column in columns), strict=True)


def telescopic(args) -> int:
    import numpy as np

    from pinarray.softness.forceps import TissueModel
    from pinarray.softness.hertz import effective_modulus_pa
    from pinarray.softness.telescopic import TelescopicDisplay, staircase_points
    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA

    display = TelescopicDisplay(
        args.central_area_mm2 * M2_PER_MM2, args.area_ratio, args.step_mm * M_PER_MM, args.cylinders
    )
    from pinarray.softness._checks import nonnegative

    pressure = float(nonnegative("--pressure-kpa", args.pressure_kpa)) * PA_PER_KPA
    areas = display.step_areas_m2
    steps = np.arange(display.cylinder_count)
    columns = [steps, steps * args.step_mm, areas / M2_PER_MM2, pressure * areas]
    headers = ["step", "from_mm", "area_mm2", f"force_N@{args.pressure_kpa:g}kPa"]
    target = None
    if args.match_young_kpa is not None:
        tissue = TissueModel(
            args.match_radius_mm * M_PER_MM,
            float(effective_modulus_pa(args.match_young_kpa * PA_PER_KPA, 0.5)),
        )
        schedule = display.pressure_schedule_pa(tissue.force_for_area_n)
        columns += [tissue.force_for_area_n(areas), schedule / PA_PER_KPA]
        headers += ["tissue_N", "pressure_kPa"]
        best = display.best_constant_pressure_pa(tissue.force_for_area_n)
        print(
            f"tissue E = {args.match_young_kpa:g} kPa (nu = 0.5), R = {args.match_radius_mm:g} mm: "
            f"best single pressure {best / PA_PER_KPA:.4g} kPa"
        )
        dense = np.linspace(0.0, areas[-1], 300)
        target = (dense, tissue.force_for_area_n(dense))
    _table(headers, _zip(columns))
    if path := _plot_path(args):
        from pinarray.softness.plots import plot_telescopic

        depth, force = staircase_points(display, pressure)
        title = f"Telescopic display at {args.pressure_kpa:g} kPa"
        _wrote(plot_telescopic(depth, force, areas, pressure * areas, target, path, title))
    return 0


def display(args) -> int:
    import numpy as np

    from pinarray.softness.tf_display import ConeDisplay
    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA

    cone = ConeDisplay()
    _check_display_options(cone, args)
    pressures = [p * PA_PER_KPA for p in args.pressure_kpa]
    print(
        f"CASR cone: R = {cone.base_radius_m / M_PER_MM:g} mm, "
        f"H = {cone.height_m / M_PER_MM:g} mm; F = p pi z^2 R^2 / H^2"
    )
    if args.force_n is not None:
        _solve_display(cone, args.force_n, args.indentation_mm, args.pressure_kpa)
        return 0
    depth = _rows(args.rows, 0.0, cone.height_m)
    forces = {p: cone.force_n(p, depth) for p in pressures}
    headers = ["z_mm", "area_mm2"] + [f"F_N@{p:g}kPa" for p in args.pressure_kpa]
    _table(headers, _zip([depth / M_PER_MM, cone.area_m2(depth) / M2_PER_MM2, *forces.values()]))
    if path := _plot_path(args):
        from pinarray.softness.plots import plot_cone

        dense = np.linspace(0.0, cone.height_m, 300)
        curves = {p: cone.force_n(p, dense) for p in pressures}
        _wrote(plot_cone(dense, curves, path, "TF/CASR display, F = p A(z)"))
    return 0


def _check_display_options(cone, args) -> None:
    """Refuse, in the lab's units, what the display cannot be asked."""
    from pinarray.softness._checks import SoftnessError
    from pinarray.softness.units import M_PER_MM

    for pressure_kpa in args.pressure_kpa:
        if pressure_kpa < 0:
            raise SoftnessError(f"--pressure-kpa must be at least 0 kPa, found {pressure_kpa:g}")
    if args.force_n is not None and args.force_n < 0:
        raise SoftnessError(f"--force-n must be at least 0 N, found {args.force_n:g}")
    if args.indentation_mm is None:
        return
    if args.force_n is None:
        raise SoftnessError("--indentation-mm needs --force-n: the force to deliver there")
    height_mm = cone.height_m / M_PER_MM
    if not 0 <= args.indentation_mm <= height_mm:
        raise SoftnessError(
            f"--indentation-mm must be from 0 to the display's height {height_mm:g} mm, "
            f"found {args.indentation_mm:g}"
        )
    if args.indentation_mm == 0 and args.force_n > 0:
        raise SoftnessError(
            f"{args.force_n:g} N at 0 mm: no pressure delivers it, the finger touches no area "
            "of the display there; give --indentation-mm above 0"
        )


def _solve_display(cone, force_n: float, indentation_mm: float | None, pressures_kpa) -> None:
    """Print where the cone balances ``force_n`` at each pressure, or why it cannot, and with
    an indentation the pressure that delivers the force there; all in the lab's units."""
    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA

    height_mm = cone.height_m / M_PER_MM
    if indentation_mm is not None:
        needed = cone.pressure_for_force_pa(force_n, indentation_mm * M_PER_MM)
        print(f"{force_n:g} N at {indentation_mm:g} mm needs {needed / PA_PER_KPA:.6g} kPa")
    base_mm2 = cone.max_area_m2 / M2_PER_MM2
    for pressure_kpa in pressures_kpa:
        pressure = pressure_kpa * PA_PER_KPA
        if cone.balances(force_n, pressure):
            # no force needs no indentation, even in an empty display
            depth = cone.indentation_for_force_m(force_n, pressure) if force_n > 0 else 0.0
            print(f"{force_n:g} N at {pressure_kpa:g} kPa balances at {depth / M_PER_MM:.6g} mm")
            continue
        least_kpa = force_n / cone.max_area_m2 / PA_PER_KPA
        print(
            f"{force_n:g} N at {pressure_kpa:g} kPa: out of reach, at most "
            f"{float(cone.max_force_n(pressure)):.6g} N with the display pressed its full "
            f"{height_mm:g} mm (base area {base_mm2:.4g} mm^2); {force_n:g} N needs at least "
            f"{least_kpa:.6g} kPa"
        )


def fit(args) -> int:
    import numpy as np

    from pinarray.softness.identification import (
        M1_R11_FORCE_AREA,
        Fit,
        fit_force_area,
        fit_force_displacement,
    )
    from pinarray.softness.samples import Samples
    from pinarray.softness.units import M2_PER_CM2, M_PER_CM

    if args.csv:
        samples = read_samples(args.csv)
    else:
        from pinarray.softness._checks import nonnegative

        nonnegative("--noise-n", args.noise_n)
        rng = np.random.default_rng(args.seed)
        area = np.linspace(0.0, 3 * M2_PER_CM2, 30)
        noisy = M1_R11_FORCE_AREA.force_n(area) + rng.normal(0.0, args.noise_n, area.size)
        samples = Samples("area", area, noisy)
        print(f"no --csv: eq. 9.4 (M1, R = 1.1 cm) sampled with {args.noise_n:g} N noise")
    fit: Fit[Any]
    m: Any
    if samples.kind == "area":
        fit = fit_force_area(samples.x_si, samples.force_n)
        m = fit.model
        print(f"F = {m.a_n_per_m4:.6g} A^2 + {m.b_n_per_m2:.6g} A + {m.c_n:.6g}   (A in m^2)")
        print(
            f"F = {m.a_n_per_m4 * M2_PER_CM2**2:.4g} A^2 + {m.b_n_per_m2 * M2_PER_CM2:.4g} A "
            f"+ {m.c_n:.4g}   (A in cm^2, as eq. 9.4)"
        )
        scale, label = M2_PER_CM2, "area (cm$^2$)"
    else:
        fit = fit_force_displacement(samples.x_si, samples.force_n)
        m = fit.model
        print(f"F = {m.slope_n_per_m:.6g} z + {m.intercept_n:.6g}   (z in m)")
        print(
            f"F = {m.slope_n_per_m * M_PER_CM:.4g} z + {m.intercept_n:.4g}   (z in cm, as eq. 9.5)"
        )
        scale, label = M_PER_CM, "displacement (cm)"
    print(
        f"{samples.x_si.size} samples, rms residual {fit.rms_residual_n:.4g} N, "
        f"max {fit.max_residual_n:.4g} N"
    )
    if path := _plot_path(args):
        from pinarray.softness.plots import plot_fit

        dense = np.linspace(0.0, samples.x_si.max(), 300)
        _wrote(
            plot_fit(
                samples.x_si / scale,
                samples.force_n,
                dense / scale,
                m.force_n(dense),
                fit.residuals_n,
                label,
                path,
                f"Least-squares force/{samples.kind} fit",
            )
        )
    return 0


def _flag_summary(name: str, force, mask) -> str:
    if not mask.any():
        return f"  {name}: never"
    return (
        f"  {name}: {mask.mean():.0%} of the ramp, at forces "
        f"{force[mask].min():.4g} N to {force[mask].max():.4g} N"
    )


def track(args) -> int:
    import numpy as np

    from pinarray.softness.control import (
        STARTUP_TIME_CONSTANTS,
        ActuatorLags,
        Material,
        ValveRange,
        simulate_force_ramp,
    )
    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA, S_PER_MS

    material = Material.from_cm(args.alpha_n_per_cm4, args.beta_cm_per_n)
    valve = ValveRange(args.valve_min_kpa * PA_PER_KPA, args.valve_max_kpa * PA_PER_KPA)
    lags = ActuatorLags(args.valve_lag_ms * S_PER_MS, args.dhd_lag_ms * S_PER_MS)
    from pinarray.softness._checks import SoftnessError

    steps = args.duration_s / (args.time_step_ms * S_PER_MS) if args.time_step_ms > 0 else 0
    if steps > MAX_TRACK_STEPS:
        raise SoftnessError(
            f"--time-step-ms {args.time_step_ms:g} gives {steps:.3g} steps over {args.duration_s:g} s; "
            f"expected at most {MAX_TRACK_STEPS:,} (a step of at least "
            f"{args.duration_s / MAX_TRACK_STEPS / S_PER_MS:.2g} ms)"
        )
    run = simulate_force_ramp(
        material,
        args.peak_force_n,
        args.duration_s,
        args.time_step_ms * S_PER_MS,
        valve=valve,
        lags=lags,
    )
    c = run.commands
    print(
        f"material alpha = {material.alpha_n_per_m4:.4g} N/m^4, "
        f"beta = {material.beta_m_per_n:.4g} m/N; "
        f"ramp to {args.peak_force_n:g} N in {args.duration_s:g} s, step {args.time_step_ms:g} ms"
    )
    pick = np.unique(np.round(_rows(args.rows, 0, run.time_s.size - 1)).astype(int))
    columns = [
        c.force_n[pick],
        c.material_displacement_m[pick] / M_PER_MM,
        run.rendered_displacement_m[pick] / M_PER_MM,
        c.material_area_m2[pick] / M2_PER_MM2,
        run.rendered_area_m2[pick] / M2_PER_MM2,
        c.pressure_pa[pick] / PA_PER_KPA,
        c.dhd_displacement_m[pick] / M_PER_MM,
    ]
    flags = [
        "".join(mark for mark, on in zip("PVB", row, strict=True) if on) or "-"
        for row in zip(
            c.dhd_must_pull[pick],
            c.pressure_out_of_range[pick],
            c.display_bottomed[pick],
            strict=True,
        )
    ]
    rows = [(*values, flag) for values, flag in zip(_zip(columns), flags, strict=True)]
    headers = ["force_N", "z_m_mm", "z_out_mm", "A_m_mm2", "A_out_mm2", "p_kPa", "z_D_mm", "flags"]
    _table(headers, rows)
    print(
        "flags: P = DHD must pull (z_D < 0), V = pressure off the valve range, B = display bottomed"
    )
    print(_flag_summary("DHD must pull", c.force_n, c.dhd_must_pull))
    print(_flag_summary("pressure off valve range", c.force_n, c.pressure_out_of_range))
    print(_flag_summary("display bottomed", c.force_n, c.display_bottomed))
    # The command's slope is infinite at zero force (A ~ F^(1/2), z_C ~ F^(1/4)), so lagging
    # actuators always miss the first instants; the rms over the ramp is the fairer number.
    rms_z = np.sqrt(np.mean(run.displacement_error_m**2)) / M_PER_MM
    rms_a = np.sqrt(np.mean(run.area_error_m2**2)) / M2_PER_MM2
    worst_z = np.max(np.abs(run.displacement_error_m)) / M_PER_MM
    worst_a = np.max(np.abs(run.area_error_m2)) / M2_PER_MM2
    print(
        f"tracking error, rms (worst): displacement {rms_z:.4g} mm ({worst_z:.4g} mm), "
        f"area {rms_a:.4g} mm^2 ({worst_a:.4g} mm^2)"
    )
    if run.startup_s > 0:
        print(_startup_summary(run, STARTUP_TIME_CONSTANTS))
    if path := _plot_path(args):
        from pinarray.softness.plots import plot_tracking

        _wrote(plot_tracking(run, path, "Combined CASR + DHD tracking of a force ramp"))
    return 0


def _startup_summary(run, time_constants: int) -> str:
    """Two lines on the start-up of a tracking run: why it overshoots, by how much, and the
    worst error after it."""
    import numpy as np

    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, S_PER_MS

    startup, settled = run.in_startup, ~run.in_startup
    peak_z = np.max(run.rendered_displacement_m[startup]) / M_PER_MM
    peak_a = np.max(run.rendered_area_m2[startup]) / M2_PER_MM2
    after = "; the whole ramp is start-up"
    if settled.any():
        worst_z = np.max(np.abs(run.displacement_error_m[settled])) / M_PER_MM
        worst_a = np.max(np.abs(run.area_error_m2[settled])) / M2_PER_MM2
        after = f"; worst error after it {worst_z:.4g} mm, {worst_a:.4g} mm^2"
    return (
        f"start-up, the first {run.startup_s / S_PER_MS:.4g} ms ({time_constants} time constants "
        "of the slower actuator): the actuators lag commands that are steepest at zero force\n"
        f"  rendered up to {peak_z:.4g} mm and {peak_a:.4g} mm^2 in it{after}"
    )


def forceps(args) -> int:
    import numpy as np

    from pinarray.softness._checks import SoftnessError

    # A radius far below any tissue's (--radius-mm 1e-300) makes the strains overflow: one
    # line naming it, not numpy's warnings and then an error about a quantity never typed.
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            return _forceps(args)
    except FloatingPointError as error:
        raise SoftnessError(
            f"--radius-mm {args.radius_mm:g}: the tissue's strains and forces leave the range "
            f"of floating point at that radius ({error}); a tissue's radius is millimetres"
        ) from None


def _forceps(args) -> int:
    import numpy as np

    from pinarray.softness._checks import SoftnessError
    from pinarray.softness.forceps import TissueModel, fit_tissue
    from pinarray.softness.tf_display import ConeDisplay
    from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA

    radius = args.radius_mm * M_PER_MM
    if args.csv:
        samples = read_samples(args.csv)
        if samples.kind != "displacement":
            raise SoftnessError(
                f"{args.csv}: forceps samples need a displacement column, found {samples.kind}"
            )
        approach, force = samples.x_si, samples.force_n
    else:
        # A stiffening tissue, E* = 40 kPa + 200 kPa * strain, sampled with 5 mN noise.
        approach = np.linspace(0.0, 3e-3, 31)
        truth = TissueModel(radius, 40e3, 200e3, args.poisson)
        noise = np.random.default_rng(1).normal(0.0, 5e-3, approach.size)
        force = truth.force_for_approach_n(approach) + noise
        print("no --csv: synthetic tissue E* = 40 kPa + 200 kPa * strain, 5 mN noise")
    fit = fit_tissue(
        approach, force, radius, args.poisson, strain_dependent=not args.constant_modulus
    )
    tissue = fit.model
    print(
        f"E*(strain) = {tissue.e0_pa / PA_PER_KPA:.4g} kPa "
        f"+ {tissue.e1_pa / PA_PER_KPA:.4g} kPa * a/R; "
        f"Young's E at zero strain {float(tissue.young_modulus_pa(0.0)) / PA_PER_KPA:.4g} kPa "
        f"(nu = {tissue.poisson:g}); rms residual {fit.rms_residual_n:.4g} N"
    )
    cone = ConeDisplay()
    top_area = min(cone.max_area_m2, float(tissue.area_for_force_m2(np.max(force))))
    area = _rows(args.rows, 0.0, top_area)
    columns = [
        area / M2_PER_MM2,
        tissue.strain_for_area(area),
        tissue.force_for_area_n(area),
        tissue.young_modulus_pa(tissue.strain_for_area(area)) / PA_PER_KPA,
        tissue.display_pressure_pa(area) / PA_PER_KPA,
        cone.indentation_for_area_m(area) / M_PER_MM,
    ]
    _table(
        ["area_mm2", "strain", "force_N", "young_kPa", "pressure_kPa", "cone_z_mm"], _zip(columns)
    )
    if path := _plot_path(args):
        from pinarray.softness.plots import plot_forceps

        order = np.argsort(approach)
        dense = np.linspace(0.0, top_area, 300)
        curves = (tissue.force_for_approach_n(approach[order]), tissue.force_for_area_n(dense),
                  tissue.display_pressure_pa(dense))
        with np.errstate(all="warn", under="ignore"):  # matplotlib's own numerics: numpy's default
            _wrote(plot_forceps(approach[order], force[order], curves[0], dense, *curves[1:],
                                path, "Forceps -> Hertz -> display pressure"))
    return 0


# A samples file: far more rows than any forceps or indenter records in a session.
MAX_SAMPLES_BYTES = 64 * 1024 * 1024


def read_samples(path: str):
    """A samples CSV read as any input is (bounded; a FIFO or a device refused), then parsed."""
    from pinarray.softness._checks import SoftnessError
    from pinarray.softness.samples import parse_samples
    from pinarray.text_files import NotText, decode_text, read_bounded

    try:
        text = decode_text(read_bounded(path, MAX_SAMPLES_BYTES, "samples"))
    except NotText as problem:
        raise SoftnessError(f"{path}: {problem}") from None
    return parse_samples(text, path)
