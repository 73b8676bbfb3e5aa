"""Hypothesis strategies for the softness models: physical quantities over wide ranges."""

from hypothesis import strategies as st


def log_uniform(low: float, high: float) -> st.SearchStrategy[float]:
    """Floats spread evenly in order of magnitude between ``low`` and ``high`` (both > 0)."""
    import math

    return st.floats(math.log10(low), math.log10(high)).map(lambda exponent: 10.0**exponent)


def with_zero(strategy: st.SearchStrategy[float]) -> st.SearchStrategy[float]:
    """The strategy, or exactly zero (the square-root singularities live there)."""
    return st.one_of(st.just(0.0), strategy)


# Micro-newtons (a feather) to tens of newtons (a hard press), as the issue asks.
forces_n = log_uniform(1e-6, 50.0)
# From a gel (100 Pa) to a rigid plastic (a few GPa).
moduli_pa = log_uniform(1e2, 3e9)
# From a 0.1 mm tip to a 1 m flat-ish body.
radii_m = log_uniform(1e-4, 1.0)
poisson_ratios = st.floats(-0.99, 0.5)
pressures_pa = log_uniform(1.0, 1e6)
areas_m2 = log_uniform(1e-14, 1e-2)
# Coefficients of a rising quadratic force/area law, spread over many decades.
quadratic_a_n_per_m4 = log_uniform(1e2, 1e12)
quadratic_b_n_per_m2 = log_uniform(1e-2, 1e8)
quadratic_c_n = st.floats(0.0, 5.0)
strains = log_uniform(1e-6, 1.0)
# Magnitudes far beyond any lab's, for the edges of the inverses: from 1e-200 to 1e200 every
# intermediate of the models (a cube of a contact radius, a square of a pressure) stays a
# normal float, so rounding stays relative.
tiny_to_huge = log_uniform(1e-200, 1e200)

# Tolerances are counted in the unit of rounding u = 2^-53: +, -, *, / and sqrt are correctly
# rounded (IEEE 754), so each errs by at most u relative. numpy's cbrt, power, exp and log are
# not: they differ by a few ulps between SIMD paths and versions (1.26 to 2.x), so a tolerance
# counts each call as FEW_ULPS ulps, 2 u each (an ulp of x is at most 2 u |x|).
U = 2.0**-53
FEW_ULPS = 4
