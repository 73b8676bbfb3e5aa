"""Input checks shared by the softness models: arrays of floats, rejected with a message
that names the argument, the offending value and where it sits in the array."""

from __future__ import annotations

import numpy as np

from pinarray.errors import PinArrayError


class SoftnessError(PinArrayError):
    """A softness-model input or result outside the model's domain; the message names it."""


def _as_float_array(name: str, value: object) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SoftnessError(
            f"{name} must be a number or an array of numbers, found {value!r}"
        ) from None


def _where(array: np.ndarray, bad: np.ndarray) -> str:
    index = np.argwhere(bad)[0]
    found = float(array[tuple(index)])
    if array.ndim == 0:
        return f"found {found!r}"
    where = tuple(int(i) for i in index) if index.size > 1 else int(index[0])
    return f"found {found!r} at index {where}"


def nonnegative(name: str, value: object) -> np.ndarray:
    """``value`` as a float array; every element finite and >= 0, else a `SoftnessError`."""
    array = _as_float_array(name, value)
    bad = ~np.isfinite(array) | (array < 0)
    if bad.any():
        raise SoftnessError(f"{name} must be finite and non-negative: {_where(array, bad)}")
    return array


def positive(name: str, value: object) -> np.ndarray:
    """``value`` as a float array; every element finite and > 0, else a `SoftnessError`."""
    array = _as_float_array(name, value)
    bad = ~np.isfinite(array) | (array <= 0)
    if bad.any():
        raise SoftnessError(f"{name} must be finite and positive: {_where(array, bad)}")
    return array


def positive_or_infinite(name: str, value: object) -> np.ndarray:
    """Like `positive`, but +inf is allowed (a rigid body, a flat surface)."""
    array = _as_float_array(name, value)
    bad = np.isnan(array) | (array <= 0)
    if bad.any():
        raise SoftnessError(f"{name} must be positive (inf allowed): {_where(array, bad)}")
    return array


def finite(name: str, value: object) -> np.ndarray:
    """``value`` as a float array with no NaN or infinity, else a `SoftnessError`."""
    array = _as_float_array(name, value)
    bad = ~np.isfinite(array)
    if bad.any():
        raise SoftnessError(f"{name} must be finite: {_where(array, bad)}")
    return array


def poisson_ratio(name: str, value: object) -> np.ndarray:
    """A Poisson's ratio: finite and in (-1, 0.5], the range of a stable isotropic solid."""
    nu = finite(name, value)
    bad = (nu <= -1) | (nu > 0.5)
    if bad.any():
        raise SoftnessError(f"{name} must lie in (-1, 0.5]: {_where(nu, bad)}")
    return nu


def positive_scalar(name: str, value: object) -> float:
    """A single finite positive number, for dataclass fields."""
    array = positive(name, value)
    if array.ndim != 0:
        raise SoftnessError(
            f"{name} must be a single number, found an array of shape {array.shape}"
        )
    return float(array)


def same_length(names: tuple[str, str], first: np.ndarray, second: np.ndarray) -> None:
    """Paired samples must be 1-D and equally long."""
    if first.ndim != 1 or second.ndim != 1 or first.shape != second.shape:
        raise SoftnessError(
            f"{names[0]} and {names[1]} must be 1-D arrays of the same length, "
            f"found shapes {first.shape} and {second.shape}"
        )
