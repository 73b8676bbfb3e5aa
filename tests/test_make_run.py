"""`make run` ends as the UI does: a rehearsal quit with the run unfinished is a normal end."""

import shutil
import subprocess

import pytest

from tests.runs import REPO


def make_run_with_a_ui_that_exits(tmp_path, status: int, folder: str = "bin"
                                  ) -> subprocess.CompletedProcess:
    # The real recipe, with a stand-in for the UI (the venv's set-up counted as done).
    fake = tmp_path / folder
    fake.mkdir(parents=True)
    script = fake / "pinarray"
    script.write_text(f"#!/bin/sh\nexit {status}\n")
    script.chmod(0o755)
    return subprocess.run(
        ["make", "--no-print-directory", "-o", ".venv/.installed", "run", f"BIN={fake}"],
        cwd=REPO, capture_output=True, text=True, timeout=60)


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
@pytest.mark.parametrize(("status", "make_fails"), [(0, False), (4, False), (2, True),
                                                    (130, True)])
def test_a_rehearsal_quit_unfinished_is_no_error_of_make_a_failure_still_is(tmp_path, status,
                                                                           make_fails):
    done = make_run_with_a_ui_that_exits(tmp_path, status)
    assert (done.returncode != 0) == make_fails, done.stderr
    assert ("Error" in done.stderr) == make_fails, done.stderr


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_run_finds_the_ui_in_a_folder_whose_name_has_a_space(tmp_path):
    # The other tests' stand-in lives in the test's temporary folder, which is wherever the
    # system's temporary folder is (tests/suite.py: where /dev/shm has no room, as in a
    # container) and may have a space in its name: the recipe split it in two there.
    done = make_run_with_a_ui_that_exits(tmp_path, 4, folder="a folder/bin")
    assert done.returncode == 0, done.stderr
