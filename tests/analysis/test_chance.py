"""Chance levels, as the lab defines them: a subject naming any nameable pin at random."""

from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pinarray.paradigms.localisation.stats import localisation_chance


def test_naming_any_of_16_pins_at_random_is_right_one_time_in_16():
    chance = localisation_chance([1, 4, 6, 7, 10, 11, 13, 16])
    # exact on any IEEE machine: 1/128 added eight times (1/64 eight times below), all dyadic
    assert chance.correct == 1 / 16
    assert "any of 16 pins" in chance.definition() and "6.25 %" in chance.definition()


def test_error_class_chance_is_the_share_of_pins_in_each_class():
    # Pin 10: A = 6, 9, 11, 14; B = 5, 7, 13, 15; C = 2, 12; D = 1, 3, 4, 8, 16.
    chance = localisation_chance([10])
    assert_allclose([chance.fractions[c] for c in ("correct", "A", "B", "C", "D")],
                    [1 / 16, 4 / 16, 4 / 16, 2 / 16, 5 / 16])


def test_when_subjects_may_name_only_the_8_stimulated_pins_chance_is_one_in_8():
    pins = [1, 4, 6, 7, 10, 11, 13, 16]
    assert localisation_chance(pins, answer_pins=pins).correct == 1 / 8


@given(st.sets(st.integers(1, 16), min_size=1), st.sets(st.integers(1, 16), min_size=1))
def test_chance_levels_are_a_distribution_over_the_answer_categories(stimulated, answers):
    chance = localisation_chance(stimulated, answers | stimulated)
    assert_allclose(sum(chance.fractions.values()), 1.0)
    assert_allclose(chance.correct, 1 / len(answers | stimulated))
