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


# -- simulated servo motion (pinarray.bus.sim_motion) ------------------------------------------

def servo_drives(lash: bool = True):
    """Speed and acceleration limits of a simulated servo, with or without backlash."""
    from pinarray.bus.sim_motion import Drive

    speeds = st.floats(20.0, 4000.0)
    return st.builds(
        lambda v, a, b: Drive(v, v, a, b),
        speeds,
        st.floats(200.0, 400_000.0),
        st.floats(0.0, 25.0) if lash else st.just(0.0),
    )


positions_steps = st.integers(0, 4095).map(float)
