"""`pinarray plan`: the trial plan on paper is the order the run will present."""

import subprocess

from pinarray.journal.rows import read_trials
from tests.commands import pinarray_here
from tests.runs import REPO, write_short_localisation

LOCALISATION = REPO / "protocols" / "localisation.yaml"
MOTION = REPO / "protocols" / "apparent_motion.yaml"


def pinarray(*args: str) -> subprocess.CompletedProcess:
    return pinarray_here(*args, cwd=REPO)


def test_the_printed_plan_is_the_order_a_run_with_the_same_seed_presents(tmp_path):
    protocol = write_short_localisation(tmp_path)  # the seed's plan, 1 s stimuli
    printed = pinarray("plan", str(protocol), "--seed", "11", "--tsv")
    assert printed.returncode == 0, printed.stderr
    header, *lines = printed.stdout.splitlines()
    assert header.split("\t") == ["trial", "block", "practice", "stimulus", "pin", "frequency_hz"]
    plan = [line.split("\t") for line in lines]
    assert [int(row[0]) for row in plan] == list(range(1, len(plan) + 1))
    ran = pinarray("batch", str(protocol), "--subject", "p1", "--seed", "11",
                   "--observer", "default", "--results", str(tmp_path / "results"))
    assert ran.returncode == 0, ran.stderr
    (beh,) = tmp_path.rglob("*_beh.tsv")
    presented = [(r.trial, r.practice, r.pin, r.frequency_hz) for r in read_trials(beh)]
    assert presented == [(int(t), practice == "yes", int(pin), float(f))
                         for t, _block, practice, _stimulus, pin, f in plan]


def test_a_plan_drawn_now_says_its_seed_and_how_to_follow_it():
    printed = pinarray("plan", str(MOTION))
    assert printed.returncode == 0, printed.stderr
    first, header, *rows = printed.stdout.splitlines()
    seed = first.split("seed ")[1].split(",")[0]
    assert f"run with --seed {seed}" in first
    assert header.split() == ["trial", "block", "practice", "stimulus", "row", "direction",
                              "answer"]
    # Directions in the subject's words (left, right, none), each row with a line to write on.
    assert {row.split()[5] for row in rows} <= {"left", "right", "none"}
    assert all(row.endswith("______") for row in rows)
    again = pinarray("plan", str(MOTION), "--seed", seed)
    assert again.stdout.splitlines()[1:] == printed.stdout.splitlines()[1:]


def test_a_plan_of_a_broken_protocol_is_one_line_and_status_2(tmp_path):
    broken = tmp_path / "p.yaml"
    broken.write_text(LOCALISATION.read_text().replace("repetitions: 1", "repetitions: 0"))
    printed = pinarray("plan", str(broken))
    assert printed.returncode == 2 and printed.stdout == ""
    assert len(printed.stderr.strip().splitlines()) == 1 and str(broken) in printed.stderr
