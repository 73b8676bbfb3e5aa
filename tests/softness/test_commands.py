"""`pinarray softness ...` as the lab would run it: tables on stdout, PNGs where asked,
one-line errors with status 2 for bad input."""

import subprocess
import sys

import pytest

from pinarray.cli import main

SUBCOMMANDS = ["hertz", "telescopic", "display", "fit", "track", "forceps"]


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_every_model_prints_a_table_and_writes_its_plot(name, tmp_path, capsys):
    assert main(["softness", name, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / (name + '.png')}" in out
    assert (tmp_path / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_hertz_table_has_the_hand_worked_millimetre_contact(capsys):
    # R = 10 mm, E = 75 kPa, nu = 0.5 -> E* = 100 kPa; 0.04/3 N gives a = 1 mm
    assert main(["softness", "hertz", "--max-force-n", str(0.04 / 3), "--rows", "2"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1].split()
    assert float(last[1]) == pytest.approx(1.0, rel=1e-5)


def test_display_solves_for_the_pressure(capsys):
    assert main(["softness", "display", "--force-n", "0.6636614", "--indentation-mm", "5"]) == 0
    assert "needs 20 kPa" in capsys.readouterr().out


def test_track_flags_where_the_dhd_must_pull(capsys):
    assert main(["softness", "track", "--peak-force-n", "3", "--valve-max-kpa", "20"]) == 0
    out = capsys.readouterr().out
    assert "DHD must pull: 100% of the ramp" in out
    assert "display bottomed: 18% of the ramp" in out  # above 2.4665 N of a ramp to 3 N
    assert "pressure off valve range: never" not in out


def test_fit_reads_a_csv_in_centimetres(tmp_path, capsys):
    data = tmp_path / "m2.csv"
    # eq. 9.5 sampled exactly: F = 23 z + 0.97, z in cm
    data.write_text("displacement_cm,force_n\n0,0.97\n0.1,3.27\n0.2,5.57\n0.4,10.17\n")
    assert main(["softness", "fit", "--csv", str(data)]) == 0
    assert "F = 23 z + 0.97   (z in cm, as eq. 9.5)" in capsys.readouterr().out


def test_forceps_reads_samples_from_a_csv(tmp_path, capsys):
    data = tmp_path / "tissue.csv"
    # R = 10 mm, E* = 100 kPa: F = (4/3) E* sqrt(R) delta^1.5, delta = 0.1 mm -> 0.04/3 N
    rows = [(d, 4 / 3 * 1e5 * 0.1 * (d * 1e-3) ** 1.5) for d in (0.1, 0.4, 0.9, 1.6)]
    data.write_text("displacement_mm,force_n\n" + "".join(f"{d},{f!r}\n" for d, f in rows))
    assert main(["softness", "forceps", "--csv", str(data), "--constant-modulus"]) == 0
    assert "E*(strain) = 100 kPa + 0 kPa * a/R" in capsys.readouterr().out


def test_bad_input_is_one_line_with_status_2(tmp_path):
    data = tmp_path / "bad.csv"
    data.write_text("area_cm2,force_n\n1,2\n2,oops\n")
    result = subprocess.run(
        [sys.executable, "-m", "pinarray", "softness", "fit", "--csv", str(data)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr.strip() == f"pinarray: {data}:3: expected two numbers, found 2,oops"


def test_a_negative_force_names_the_argument(capsys):
    assert main(["softness", "hertz", "--max-force-n", "-1"]) == 2
    assert "force_n must be finite and non-negative" in capsys.readouterr().err
