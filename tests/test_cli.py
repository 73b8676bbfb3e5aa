"""The `pinarray` command as a user meets it: help, version, one-line errors, exit status 2."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pinarray import __version__
from pinarray.cli import main
from pinarray.journal.manifest import RunStatus, read_manifest

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pinarray", *args], capture_output=True, text=True, timeout=60
    )


def test_version_and_help():
    assert run("--version").stdout.strip() == f"pinarray {__version__}"
    helped = run("--help")
    assert helped.returncode == 0 and "grid" in helped.stdout


def test_grid_prints_the_layout_and_the_classes_around_pin_10(capsys):
    assert main(["grid", "--table"]) == 0
    out = capsys.readouterr().out
    assert "13 14 15 16" in out and " 1  2  3  4" in out
    # around pin 10: row of 13..16 reads B A B D
    assert "B A B D" in out
    assert "10 ->" in out


def test_a_users_mistake_is_one_line_on_stderr_with_status_2():
    result = run("grid", "--pin", "17")
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert lines == ["pinarray: pin 17 is not on the 4x4 grid: expected a pin from 1 to 16"]
    assert "Traceback" not in result.stderr


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full to stand for a full disk")
def test_standard_output_on_a_full_disk_is_one_line_and_status_2_and_a_batchs_results_stand(
        tmp_path):
    # Stranger attack (attack-launch): `pinarray validate ... > /dev/full` ended in an OSError
    # traceback, status 1; so did a batch, at its last line, after its run was written.
    # Standard output to a file is written in blocks (unless PYTHONUNBUFFERED says not, as it
    # does here): the failure then comes with the last flush.
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    with open("/dev/full", "w") as full:
        validated = subprocess.run(
            [sys.executable, "-m", "pinarray", "validate", str(PROTOCOLS / "localisation.yaml")],
            stdout=full, stderr=subprocess.PIPE, text=True, timeout=60, env=env)
        unbuffered = subprocess.run(
            [sys.executable, "-m", "pinarray", "validate", str(PROTOCOLS / "localisation.yaml")],
            stdout=full, stderr=subprocess.PIPE, text=True, timeout=60,
            env={**env, "PYTHONUNBUFFERED": "1"})
        batched = subprocess.run(
            [sys.executable, "-m", "pinarray", "batch", str(PROTOCOLS / "demo.yaml"),
             "--subject", "01", "--observer", "default", "--sim", "--results", str(tmp_path)],
            stdout=full, stderr=subprocess.PIPE, text=True, timeout=120, env=env)
    for done in (validated, unbuffered, batched):
        assert (done.returncode, done.stderr) == (
            2, "pinarray: standard output: No space left on device\n")
    (manifest,) = tmp_path.rglob("*_manifest.json")
    assert read_manifest(manifest).status is RunStatus.COMPLETED


def test_a_command_started_with_its_standard_output_closed_does_its_work_silently(tmp_path):
    # Stranger review: `pinarray validate FILE >&-` (Python's sys.stdout is then None) ended in
    # a traceback, status 1, once standard output was guarded.
    validated = subprocess.run(
        [sys.executable, "-m", "pinarray", "validate", str(PROTOCOLS / "localisation.yaml")],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=60,
        preexec_fn=lambda: os.close(1))
    assert (validated.returncode, validated.stderr) == (0, "")


@pytest.mark.parametrize(("folder", "encoding"), [
    (b"M\xfcller", "utf-8:strict"),  # named in Latin-1, read on a UTF-8 system (en_US.UTF-8)
    ("Müller".encode(), "ascii:strict"),  # a terminal that takes ASCII only
    ("Müller".encode(), "ascii:surrogateescape"),  # Python's way in an ASCII locale (C)
])
def test_a_protocol_whose_name_the_terminal_cannot_show_is_still_validated(tmp_path, folder,
                                                                          encoding):
    # Python prints to a UTF-8 locale's terminal strictly (but not under C.UTF-8): the name of
    # a protocol in such a folder once made `validate` end in a traceback, status 1.
    place = os.path.join(os.fsencode(tmp_path), folder)
    os.mkdir(place)
    protocol = os.path.join(place, b"localisation.yaml")
    shutil.copyfile(Path(__file__).parent.parent / "protocols" / "localisation.yaml", protocol)
    done = subprocess.run([sys.executable, "-m", "pinarray", "validate", protocol],
                          capture_output=True, timeout=60,
                          env={**os.environ, "PYTHONIOENCODING": encoding})
    assert done.returncode == 0 and b"Traceback" not in done.stderr, done.stderr
    assert b"localisation.yaml: ok (localisation," in done.stdout


def test_preview_prints_the_seed_of_the_plan_it_drew_so_the_same_plan_can_be_seen_again(capsys):
    import re

    localisation = str(Path(__file__).resolve().parent.parent / "protocols" / "localisation.yaml")
    assert main(["preview", localisation, "--trial", "5"]) == 0
    first = capsys.readouterr().out
    seed = re.search(r"--seed (\d+) shows the same plan", first).group(1)
    assert main(["preview", localisation, "--trial", "5", "--seed", seed]) == 0
    again = capsys.readouterr().out
    assert again.splitlines()[:-1] == first.splitlines()[:-1]


def test_sim_serve_help_lists_every_url_key_the_simulator_takes():
    from pinarray.cli.bus import SERVE_EPILOG
    from pinarray.hardware.feetech.faults import _KNOWN_KEYS

    # ids has its own option; fidelity behind sim-serve is always wire.
    said = set(re.findall(r"([a-z_]+)=", SERVE_EPILOG))
    assert sorted(_KNOWN_KEYS - {"ids", "fidelity"} - said) == []
