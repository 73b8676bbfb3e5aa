"""PNG figures of the softness models; the only module here that imports matplotlib.

Every function takes SI arrays, draws them in the lab's units (mm, mm^2, kPa) and
writes one PNG, returning its path.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402 - the backend must be chosen first
import numpy as np  # noqa: E402

from pinarray.softness.units import M2_PER_MM2, M_PER_MM, PA_PER_KPA  # noqa: E402


def _panels(count: int, title: str):
    figure, axes = plt.subplots(1, count, figsize=(5.2 * count, 4.2), squeeze=False)
    figure.suptitle(title)
    return figure, axes[0]


def _save(figure, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.tight_layout()
    # No layout engine left behind, so that savefig does not draw the figure a second time
    # without output (as `pinarray.analysis.figures.lay_out`, which this package may not
    # import); zlib at level 1: the same pixels, sooner, in a file about a tenth larger.
    with matplotlib.rc_context({"figure.autolayout": False,
                                "figure.constrained_layout.use": False}):
        figure.set_layout_engine(None)
    figure.savefig(path, dpi=110, pil_kwargs={"compress_level": 1})
    plt.close(figure)
    return path


def plot_hertz(force_n, area_m2, approach_m, path: str | Path, title: str) -> Path:
    """Contact area and approach against force (seed 000, eq. 7)."""
    figure, (left, right) = _panels(2, title)
    left.plot(area_m2 / M2_PER_MM2, force_n)
    left.set(xlabel="contact area (mm$^2$)", ylabel="force (N)", title="force / area")
    right.plot(approach_m / M_PER_MM, force_n)
    right.set(xlabel="approach (mm)", ylabel="force (N)", title="force / displacement")
    return _save(figure, path)


def plot_telescopic(depth_m, force_n, step_area_m2, step_force_n, target, path, title) -> Path:
    """The staircase against indentation, and the step forces against area beside a target.

    ``target`` is ``(area_m2, force_n)`` of the curve to replicate, or None.
    """
    figure, (left, right) = _panels(2, title)
    left.plot(depth_m / M_PER_MM, force_n, drawstyle="steps-post")
    left.set(xlabel="indentation (mm)", ylabel="force (N)", title="force / indentation")
    right.plot(step_area_m2 / M2_PER_MM2, step_force_n, "o", label="display steps")
    if target is not None:
        right.plot(target[0] / M2_PER_MM2, target[1], "-", label="target")
        right.legend()
    right.set(xlabel="contact area (mm$^2$)", ylabel="force (N)", title="force / area")
    return _save(figure, path)


def plot_cone(indentation_m, forces_by_pressure, path, title) -> Path:
    """Force against indentation and against area for several pressures (eq. 9.3).

    ``forces_by_pressure`` maps a pressure in Pa to forces at ``indentation_m``; areas follow
    from the forces and pressure as A = F / p.
    """
    figure, (left, right) = _panels(2, title)
    for pressure_pa, force_n in forces_by_pressure.items():
        label = f"{pressure_pa / PA_PER_KPA:g} kPa"
        left.plot(indentation_m / M_PER_MM, force_n, label=label)
        right.plot(force_n / pressure_pa / M2_PER_MM2, force_n, label=label)
    left.set(xlabel="indentation (mm)", ylabel="force (N)", title="force / displacement")
    right.set(xlabel="contact area (mm$^2$)", ylabel="force (N)", title="force / area")
    left.legend()
    return _save(figure, path)


def plot_fit(x, force_n, curve_x, curve_force_n, residuals_n, x_label, path, title) -> Path:
    """Samples with their fitted curve, and the residuals (x already in display units)."""
    figure, (left, right) = _panels(2, title)
    left.plot(x, force_n, "o", ms=3, label="samples")
    left.plot(curve_x, curve_force_n, "-", label="fit")
    left.set(xlabel=x_label, ylabel="force (N)", title="fit")
    left.legend()
    right.axhline(0, color="0.6", lw=0.8)
    right.plot(x, residuals_n, "o", ms=3)
    right.set(xlabel=x_label, ylabel="residual (N)", title="measured - fitted")
    return _save(figure, path)


def _shade(axes, force_n, mask, colour, label) -> None:
    if np.any(mask):
        axes.fill_between(
            force_n,
            0,
            1,
            where=mask,
            color=colour,
            alpha=0.15,
            label=label,
            transform=axes.get_xaxis_transform(),
            step="mid",
        )


def _scale_past_startup(axes, desired, rendered, startup, unit) -> None:
    """Set the y-axis by the tracked signal: the desired curve and the rendered one after the
    start-up; a start-up excursion beyond that is clipped and its peak written on the plot."""
    shown = np.concatenate([desired, rendered[~startup]]) if (~startup).any() else rendered
    low, high = min(0.0, float(shown.min())), float(shown.max())
    margin = 0.05 * (high - low) or 1.0
    if not startup.any() or float(rendered[startup].max()) <= high + margin:
        return  # nothing would be clipped: matplotlib's own limits show everything
    axes.set_ylim(low - margin, high + margin)
    axes.text(
        0.2,
        0.97,
        f"start-up: rendered up to {float(rendered[startup].max()):.3g} {unit}, off scale",
        transform=axes.transAxes,
        va="top",
        fontsize="small",
    )


def plot_tracking(run, path, title) -> Path:
    """`tracking_figure` written to a PNG."""
    return _save(tracking_figure(run, title), path)


def tracking_figure(run, title):
    """Displacement and area against force, desired (solid) and rendered (dashed), as in the
    seed's Figs. 9.9/9.10, with flagged stretches shaded.

    The start-up (`TrackingRun.startup_s`: the valve's pressure catching up with a command
    that is infinitely steep at zero force) is shaded grey; the axes are scaled by the rest of
    the ramp, and a start-up peak beyond them is written on the plot rather than setting the
    scale.
    """
    commands = run.commands
    force = commands.force_n
    startup = run.in_startup
    figure, (left, right) = _panels(2, title)
    displacement = (
        commands.material_displacement_m / M_PER_MM,
        run.rendered_displacement_m / M_PER_MM,
    )
    area = (commands.material_area_m2 / M2_PER_MM2, run.rendered_area_m2 / M2_PER_MM2)
    for axes, (desired, rendered), unit in (
        (left, displacement, "mm"),
        (right, area, "mm$^2$"),
    ):
        axes.plot(force, desired, "-", label="material")
        axes.plot(force, rendered, "--", label="rendered")
        _shade(axes, force, startup, "0.5", f"start-up ({run.startup_s * 1e3:.3g} ms)")
        _scale_past_startup(axes, desired, rendered, startup, unit)
    left.set(xlabel="force (N)", ylabel="displacement (mm)", title="displacement")
    right.set(xlabel="force (N)", ylabel="area (mm$^2$)", title="area")
    _shade(left, force, commands.dhd_must_pull, "tab:red", "DHD must pull")
    _shade(right, force, commands.pressure_out_of_range, "tab:orange", "pressure off valve range")
    _shade(right, force, commands.display_bottomed, "tab:purple", "display bottomed")
    left.legend(fontsize="small", loc="lower right")
    right.legend(fontsize="small", loc="lower right")
    return figure


def plot_forceps(approach_m, force_n, fitted_n, area_m2, curve_force_n, pressure_pa, path, title):
    """Forceps samples with the Hertz fit; predicted force/area; display pressure against area."""
    figure, (left, middle, right) = _panels(3, title)
    left.plot(approach_m / M_PER_MM, force_n, "o", ms=3, label="forceps")
    left.plot(approach_m / M_PER_MM, fitted_n, "-", label="Hertz fit")
    left.set(xlabel="jaw displacement (mm)", ylabel="force (N)", title="force / displacement")
    left.legend()
    middle.plot(area_m2 / M2_PER_MM2, curve_force_n)
    middle.set(xlabel="contact area (mm$^2$)", ylabel="force (N)", title="predicted force / area")
    right.plot(area_m2 / M2_PER_MM2, pressure_pa / PA_PER_KPA)
    right.set(xlabel="contact area (mm$^2$)", ylabel="pressure (kPa)", title="display pressure")
    return _save(figure, path)
