"""The softness figures as the lab reads them: units as in the tables, scales set by the data
that matters."""

import pytest

from pinarray.softness.control import SEED_EXAMPLE_MATERIAL, simulate_force_ramp
from pinarray.softness.units import M2_PER_MM2, M_PER_MM

# The `softness track` default: eq. 9.4/9.5's material, 2 N in 2 s, 20 ms valve, 10 ms DHD.
RUN = simulate_force_ramp(SEED_EXAMPLE_MATERIAL, 2.0, 2.0, 1e-3)


def tracking_panels():
    """The tracking figure's two panels (displacement, area) for `RUN`."""
    # matplotlib loads in the process that runs these tests, not in every one that collects
    # this file (each test process of `make test` collects every file: 0.6 s of processor)
    from pinarray.softness.plots import tracking_figure

    return tracking_figure(RUN, "t").axes


def test_the_tracking_plot_is_scaled_by_the_ramp_not_by_the_start_up_spike():
    displacement, _ = tracking_panels()
    peak_mm = RUN.commands.material_displacement_m.max() / M_PER_MM  # 0.87 mm at 2 N
    spike_mm = RUN.rendered_displacement_m[RUN.in_startup].max() / M_PER_MM  # 8.6 mm at 1 ms
    bottom, top = displacement.get_ylim()
    assert peak_mm < top < 2 * peak_mm < spike_mm
    assert bottom <= 0
    notes = [text.get_text() for text in displacement.texts]
    assert notes == [f"start-up: rendered up to {spike_mm:.3g} mm, off scale"]


def test_the_start_up_is_shaded_and_named_on_both_panels():
    for axes in tracking_panels():
        labels = axes.get_legend_handles_labels()[1]
        assert "start-up (100 ms)" in labels


def test_the_tracking_plot_gives_areas_in_square_millimetres_as_the_table_does():
    _, area = tracking_panels()
    assert area.get_ylabel() == "area (mm$^2$)"
    material = next(line for line in area.lines if line.get_label() == "material")
    # the line is the model's area divided by M2_PER_MM2, nothing else
    assert material.get_ydata().max() == pytest.approx(
        RUN.commands.material_area_m2.max() / M2_PER_MM2, rel=1e-15)
    assert not area.texts  # the 108.7 mm^2 start-up peak is within the 119.5 mm^2 scale
