"""The example experiment's own tests, on pinarray's simulated array (the ``simulated_array``
fixture comes with pinarray: pytest loads its plugin by entry point)."""

from __future__ import annotations

from pathlib import Path

from which_pin import PROTOCOL, check_pins, correct_by_frequency, main

import pinarray
from pinarray.testing import ArrayOpener

# Two pins of the seed's protocol, two trials each: the whole script in about a second.
SHORT = PROTOCOL.read_text().replace("pins: [1, 4, 6, 7, 10, 11, 13, 16]", "pins: [4, 6]") \
    .replace("frequencies_hz: [3, 5, 10]", "frequencies_hz: [10]") \
    .replace("practice_trials: 2", "practice_trials: 0").replace("repetitions: 1", "repetitions: 2")


def test_every_pin_of_the_design_makes_its_stroke_at_10_hz(simulated_array: ArrayOpener) -> None:
    checks = check_pins(simulated_array(PROTOCOL))
    assert [c.pin for c in checks] == [1, 4, 6, 7, 10, 11, 13, 16]
    assert all(c.delivered and c.achieved_steps == c.commanded_steps == 65 for c in checks)


def test_worn_servos_that_fall_short_are_caught_before_a_session(
        simulated_array: ArrayOpener) -> None:
    checks = check_pins(simulated_array(PROTOCOL, "sim://?speed=1500"))
    assert not any(c.delivered for c in checks)
    assert all("moved" in c.problem for c in checks)


def test_a_session_writes_one_row_per_trial_and_scores_them(tmp_path: Path) -> None:
    protocol = tmp_path / "short.yaml"
    protocol.write_text(SHORT)
    assert main(["--protocol", str(protocol), "--subject", "01", "--seed", "3",
                 "--results", str(tmp_path / "results")]) == 0
    (run,) = pinarray.read_results(tmp_path / "results")
    assert run.status == "completed" and [r.trial for r in run.records] == [1, 2, 3, 4]
    assert set(correct_by_frequency([run])) == {10.0}
