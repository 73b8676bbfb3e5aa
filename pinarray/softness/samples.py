"""Measured samples from CSV files, converted to SI from the units named in the header.

A file has a header row naming each column with its unit, e.g.::

    area_cm2,force_n            (a force/area curve, as the seed's Fig. 9.7)
    displacement_mm,force_n     (a force/displacement curve, or forceps samples)

Recognised units: lengths ``m``, ``cm``, ``mm``; areas ``m2``, ``cm2``, ``mm2``; forces ``n``.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import numpy as np

from pinarray.softness._checks import SoftnessError
from pinarray.softness.units import M2_PER_CM2, M2_PER_MM2, M_PER_CM, M_PER_MM

_TO_SI = {
    "area_m2": 1.0,
    "area_cm2": M2_PER_CM2,
    "area_mm2": M2_PER_MM2,
    "displacement_m": 1.0,
    "displacement_cm": M_PER_CM,
    "displacement_mm": M_PER_MM,
    "force_n": 1.0,
}


@dataclass(frozen=True, eq=False)
class Samples:
    """Paired samples in SI: ``kind`` is ``"area"`` (x in m^2) or ``"displacement"`` (x in m)."""

    kind: str
    x_si: np.ndarray
    force_n: np.ndarray


def _number(cell: str) -> float:
    """A decimal number as a lab's spreadsheet writes it: float() alone also reads other
    scripts' digits (an Arabic-Indic 3 as 3) and Python's digit groups (1_0 as 10)."""
    if not cell.isascii() or "_" in cell:
        raise ValueError(cell)
    return float(cell)


def parse_samples(text: str, name: str) -> Samples:
    """Read a two-column CSV of force against area or displacement from its text.

    ``name`` is the file's name for messages. Raises `SoftnessError` naming the file and line
    of anything it cannot read. (Reading the file is the caller's: the library does no I/O.)
    """
    path = name
    rows = list(csv.reader(io.StringIO(text, newline="")))
    if not rows:
        raise SoftnessError(f"{path}: empty file; expected a header such as area_cm2,force_n")
    header = [name.strip().lower() for name in rows[0]]
    unknown = [name for name in header if name not in _TO_SI]
    if unknown or "force_n" not in header or len(header) != 2:
        raise SoftnessError(
            f"{path}:1: expected two columns, force_n and one of "
            f"{', '.join(n for n in _TO_SI if n != 'force_n')}; found {','.join(header)}"
        )
    x_name = header[1 - header.index("force_n")]
    values = np.empty((len(rows) - 1, 2))
    for line, row in enumerate(rows[1:], start=2):
        try:
            if len(row) != 2:  # one number would be taken for both columns
                raise ValueError(row)
            values[line - 2] = [_number(cell) for cell in row]
        except ValueError:
            raise SoftnessError(
                f"{path}:{line}: expected two numbers, found {','.join(row)}"
            ) from None
    columns = dict(zip(header, values.T, strict=True))
    return Samples(x_name.split("_")[0], columns[x_name] * _TO_SI[x_name], columns["force_n"])
