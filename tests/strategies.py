"""Hypothesis strategies shared by the test suite."""

from hypothesis import strategies as st

from pinarray.grid import Grid

grids = st.builds(
    Grid,
    rows=st.integers(1, 12),
    columns=st.integers(1, 12),
    pitch_mm=st.sampled_from([1.0, 2.0, 2.5]),
)


@st.composite
def grid_and_two_pins(draw):
    grid = draw(grids)
    pins = st.integers(1, grid.pin_count)
    return grid, draw(pins), draw(pins)
