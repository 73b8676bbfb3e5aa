"""`pinarray softness ...` as the lab would run it: tables on stdout, PNGs where asked,
one-line errors with status 2 for bad input."""

import argparse
import math
import subprocess
import sys

import pytest

from pinarray.cli import build_parser, main
from pinarray.softness.hertz import SMALL_CONTACT_FRACTION
from tests.commands import pinarray_here

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
    result = pinarray_here("softness", "fit", "--csv", data)
    assert result.returncode == 2
    assert result.stderr.strip() == f"pinarray: {data}:3: expected two numbers, found 2,oops"


@pytest.mark.parametrize(("row", "found"), [
    ("0.1", "0.1"),  # the force missing: once read as 0.1 mm and 0.1 N
    ("0.1,0.2,0.3", "0.1,0.2,0.3"),
    ("0.1,\u0663", "0.1,\u0663"),  # an Arabic-Indic three: once read as 3 N
    ("0.1,1_0", "0.1,1_0"),  # Python's digit groups: once read as 10 N
])
def test_a_samples_row_that_is_not_two_plain_numbers_is_refused_at_its_line(tmp_path, capsys,
                                                                            row, found):
    data = tmp_path / "tissue.csv"
    data.write_text(f"displacement_mm,force_n\n0,0\n{row}\n0.4,0.1\n", encoding="utf-8")
    assert main(["softness", "forceps", "--csv", str(data)]) == 2
    out, err = capsys.readouterr()
    assert err == f"pinarray: {data}:3: expected two numbers, found {found}\n"


def test_a_display_too_large_to_compute_is_one_line_with_status_2_and_no_numpy_warning():
    result = subprocess.run(
        [sys.executable, "-W", "error", "-m", "pinarray", "softness", "telescopic",
         "--area-ratio", "1e9", "--cylinders", "1000", "--match-young-kpa", "10"],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "expected an outermost cylinder's area below" \
        in result.stderr and "fewer cylinders or a smaller area_ratio" in result.stderr


def test_a_tissue_radius_too_small_to_compute_is_one_line_naming_it_and_no_numpy_warning(tmp_path):
    result = subprocess.run(
        [sys.executable, "-W", "error", "-m", "pinarray", "softness", "forceps",
         "--radius-mm", "1e-300", "--png", str(tmp_path / "forceps.png")],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(
        "pinarray: --radius-mm 1e-300: the tissue's strains and forces leave the range")
    assert not (tmp_path / "forceps.png").exists()


def test_a_negative_force_names_the_argument(capsys):
    assert main(["softness", "hertz", "--max-force-n", "-1"]) == 2
    assert "force_n must be finite and non-negative" in capsys.readouterr().err


# The unit each option's name ends in, as its help must spell it.
UNIT_OF_SUFFIX = {"-mm": "(mm)", "-mm2": "(mm^2)", "-kpa": "(kPa)", "-n": "(N)", "-ms": "(ms)",
                  "-s": "(s)", "-n-per-cm4": "(N/cm^4)", "-cm-per-n": "(cm/N)"}
# Options that are not quantities: files, folders and flags.
NOT_QUANTITIES = {"--png", "--out", "--csv", "--constant-modulus"}


def softness_options():
    """(model, option, its argparse action) for every option of every softness model."""
    models = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    softness = models.choices["softness"]
    sub = next(a for a in softness._actions if isinstance(a, argparse._SubParsersAction))
    for model, parser in sub.choices.items():
        for action in parser._actions:
            if action.option_strings and action.option_strings[0] != "-h":
                yield model, action.option_strings[0], action


def test_every_softness_option_says_its_unit_and_its_default():
    missing = []
    for model, option, action in softness_options():
        text = action.help or ""
        suffix = max((s for s in UNIT_OF_SUFFIX if option.endswith(s)), key=len, default=None)
        if suffix:
            unit_ok = UNIT_OF_SUFFIX[suffix] in text
        else:
            unit_ok = option in NOT_QUANTITIES or any(
                kind in text for kind in ("(dimensionless)", "(a count)", "(a whole number)"))
        if isinstance(action.default, list):
            default_ok = all(f"{v:g}" in text.split("default:")[-1] for v in action.default)
        elif action.default not in (None, False):
            default_ok = "default: " in text and "%(default" in text  # the value itself
        else:
            default_ok = "default: " in text  # what happens without the option
        if not (unit_ok and default_ok):
            missing.append(f"{model} {option}: {text!r}")
    assert missing == []


def test_the_help_of_every_softness_model_shows_its_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["softness", "track", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--peak-force-n PEAK_FORCE_N force at the end of the ramp (N); default: 2.0" in help_text


def test_hertz_by_default_stays_inside_the_small_contact_assumption(capsys):
    # R = 10 mm, E* = 100 kPa: the last row is the force that makes a = 0.1 R = 1 mm, 0.04/3 N
    assert main(["softness", "hertz"]) == 0
    out, err = capsys.readouterr()
    last = out.strip().splitlines()[-1].split()
    # the table prints 6 significant digits: a half unit in the 6th is 5e-6 relative
    assert float(last[0]) == pytest.approx(0.04 / 3, rel=5e-6)
    assert float(last[1]) == pytest.approx(1.0, rel=5e-6)
    assert err == ""


def test_hertz_warns_in_one_line_when_the_contact_outgrows_the_sphere(capsys):
    # 10 N on the 10 mm sphere: a = 9.09 mm, nearly the sphere's own radius
    assert main(["softness", "hertz", "--max-force-n", "10"]) == 0
    out, err = capsys.readouterr()
    assert float(out.strip().splitlines()[-1].split()[1]) == pytest.approx(9.0856, rel=1e-5)
    assert err.count("\n") == 1
    assert err.startswith("pinarray: warning: above 0.01333 N the contact radius passes 0.1 R "
                          "(1 mm of R = 10 mm), outside Hertz's small-contact assumption a << R")


def test_the_small_contact_limit_in_the_help_is_the_models():
    help_text = next(action.help for model, option, action in softness_options()
                     if (model, option) == ("hertz", "--max-force-n"))
    assert f"contact radius {SMALL_CONTACT_FRACTION:g} R" in help_text


def test_display_delivers_a_force_at_the_pressures_that_can_and_says_why_not_at_the_others(
        capsys):
    # base area pi (6.5 mm)^2 = 132.73 mm^2: 10 kPa gives at most 1.3273 N, so 2 N needs
    # 15.068 kPa; at 20 kPa z = (10 / 6.5) sqrt(2 N / (pi 20 kPa)) = 8.6798 mm, at 40 kPa 6.1376
    assert main(["softness", "display", "--force-n", "2"]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert err == ""
    assert lines[1] == ("2 N at 10 kPa: out of reach, at most 1.32732 N with the display pressed "
                        "its full 10 mm (base area 132.7 mm^2); 2 N needs at least 15.0679 kPa")
    # printed to 6 significant digits: a half unit in the 6th is 5e-6 relative
    assert float(lines[2].removeprefix("2 N at 20 kPa balances at ").split()[0]) == \
        pytest.approx(10 / 6.5 * math.sqrt(2 / (math.pi * 20e3)) * 1e3, rel=5e-6)
    assert float(lines[3].removeprefix("2 N at 40 kPa balances at ").split()[0]) == \
        pytest.approx(10 / 6.5 * math.sqrt(2 / (math.pi * 40e3)) * 1e3, rel=5e-6)


@pytest.mark.parametrize(("argv", "message"), [
    (["--force-n", "2", "--indentation-mm", "12"],
     "--indentation-mm must be from 0 to the display's height 10 mm, found 12"),
    (["--force-n", "2", "--indentation-mm", "0"],
     "2 N at 0 mm: no pressure delivers it, the finger touches no area of the display there; "
     "give --indentation-mm above 0"),
    (["--force-n", "-1"], "--force-n must be at least 0 N, found -1"),
    (["--pressure-kpa", "-5"], "--pressure-kpa must be at least 0 kPa, found -5"),
    (["--indentation-mm", "3"], "--indentation-mm needs --force-n: the force to deliver there"),
])
def test_display_refuses_in_the_lab_s_units_never_by_an_internal_name(argv, message, capsys):
    assert main(["softness", "display", *argv]) == 2
    out, err = capsys.readouterr()
    assert (out, err) == ("", f"pinarray: {message}\n")


def test_track_explains_its_start_up_and_gives_the_error_after_it(capsys):
    assert main(["softness", "track"]) == 0
    out = capsys.readouterr().out
    assert ("start-up, the first 100 ms (5 time constants of the slower actuator): the actuators "
            "lag commands that are steepest at zero force\n  rendered up to ") in out
    assert "; worst error after it " in out
