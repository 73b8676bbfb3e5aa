"""The pin grid and the seed's localisation error classes (section 9.7.1, Fig. 9.12)."""

import math
from collections import Counter

import pytest
from hypothesis import given

from pinarray.errors import PinArrayError
from pinarray.grid import DEFAULT_GRID, Grid, classify, render_layout
from tests.strategies import grid_and_two_pins, grids


def test_numbering_matches_fig_9_12_as_the_subject_sees_it():
    assert render_layout(DEFAULT_GRID).split("\n") == [
        "13 14 15 16",
        " 9 10 11 12",
        " 5  6  7  8",
        " 1  2  3  4",
    ]


def test_pin_1_is_bottom_left_and_pin_16_top_right():
    assert DEFAULT_GRID.cell(1) == (0, 0)
    assert DEFAULT_GRID.cell(4) == (0, 3)
    assert DEFAULT_GRID.cell(13) == (3, 0)
    assert DEFAULT_GRID.cell(16) == (3, 3)
    assert DEFAULT_GRID.position_mm(16) == (6.0, 6.0)
    assert DEFAULT_GRID.position_mm(2) == (2.0, 0.0)


def test_seed_worked_example_for_stimulated_pin_10():
    # "pin stimulated=10, pin indicated by the subject= 9 or 11 or 14 or 6" ... (seed 9.7.1)
    assert [classify(10, p) for p in (9, 11, 14, 6)] == ["A"] * 4
    assert [classify(10, p) for p in (13, 15, 5, 7)] == ["B"] * 4
    assert [classify(10, p) for p in (2, 12)] == ["C"] * 2
    assert [classify(10, p) for p in (16, 1, 4)] == ["D"] * 3
    assert classify(10, 10) == "correct"


def test_every_class_on_4x4_has_the_expected_number_of_ordered_pairs():
    counts = Counter(classify(s, r) for s in range(1, 17) for r in range(1, 17))
    # 16 pins; 24 orthogonally adjacent pairs; 18 diagonal pairs; 24 same-line
    # non-adjacent pairs; each unordered pair counted twice, the rest is D.
    assert counts == {"correct": 16, "A": 48, "B": 36, "C": 48, "D": 108}


def test_neighbours_of_a_corner_an_edge_and_an_inner_pin():
    assert DEFAULT_GRID.neighbours(1) == {2, 5, 6}
    assert DEFAULT_GRID.neighbours(2) == {1, 3, 5, 6, 7}
    assert DEFAULT_GRID.neighbours(10) == {5, 6, 7, 9, 11, 13, 14, 15}


def test_rows_and_columns_read_as_the_lab_reads_them():
    assert DEFAULT_GRID.row_pins(0) == (1, 2, 3, 4)
    assert DEFAULT_GRID.row_pins(3) == (13, 14, 15, 16)
    assert DEFAULT_GRID.column_pins(3) == (4, 8, 12, 16)


@pytest.mark.parametrize("pin", [0, 17, -1, 2.5, True, "3"])
def test_an_out_of_range_pin_names_the_pin_and_the_valid_range(pin):
    with pytest.raises(PinArrayError, match=r"pin .* expected a pin from 1 to 16"):
        classify(pin, 1)
    with pytest.raises(PinArrayError, match="from 1 to 16"):
        classify(1, pin)


def test_a_grid_must_have_pins_and_a_positive_pitch():
    with pytest.raises(PinArrayError, match="at least 1 row"):
        Grid(0, 4)
    with pytest.raises(PinArrayError, match="pitch"):
        Grid(4, 4, 0.0)


@given(grid_and_two_pins())
def test_classes_are_symmetric(case):
    grid, a, b = case
    assert grid.classify(a, b) == grid.classify(b, a)


@given(grid_and_two_pins())
def test_classes_agree_with_the_geometry_in_millimetres(case):
    grid, s, r = case
    (xs, ys), (xr, yr) = grid.position_mm(s), grid.position_mm(r)
    distance = math.hypot(xs - xr, ys - yr)
    same_line = xs == xr or ys == yr
    expected = (
        "correct" if distance == 0
        else "A" if math.isclose(distance, grid.pitch_mm)
        else "B" if math.isclose(distance, grid.pitch_mm * math.sqrt(2))
        else "C" if same_line
        else "D"
    )
    assert grid.classify(s, r) == expected


@given(grids)
def test_class_counts_follow_from_the_grid_size(grid):
    r, c = grid.rows, grid.columns
    counts = Counter(grid.classify(s, p) for s in grid.pins for p in grid.pins)
    assert counts["correct"] == r * c
    assert counts["A"] == 2 * (r * (c - 1) + c * (r - 1))
    assert counts["B"] == 4 * (r - 1) * (c - 1)
    assert counts["C"] == r * (c - 1) * (c - 2) + c * (r - 1) * (r - 2)
    assert sum(counts.values()) == (r * c) ** 2


@given(grids)
def test_cell_and_pin_at_are_inverse(grid):
    for pin in grid.pins:
        assert grid.pin_at(*grid.cell(pin)) == pin
    assert all(len(grid.neighbours(p)) <= 8 for p in grid.pins)
