"""`pinarray compile` writes CSV or a numpy archive; `pinarray validate` starts light."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pinarray.cli import main
from tests.test_protocol_load import MINIMAL

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"

# A scaled 40 Hz stroke makes `validate` print a note, which compiles the trial's drives.
SCALED = ("device:\n  feasibility: scale\n" + MINIMAL).replace(
    "frequencies_hz: [5]", "frequencies_hz: [40]"
)

HEAVY = ("numpy", "textual", "matplotlib", "serial", "scservo_sdk")


@pytest.mark.parametrize(
    "argv",
    [
        ["--help"],
        ["validate", "--help"],
        ["validate", "{protocols}/localisation.yaml", "{protocols}/apparent_motion.yaml"],
        ["validate", "{scaled}", "{protocols}/demo.yaml"],
        ["validate", "{broken}"],
    ],
)
def test_validate_and_help_load_neither_numpy_nor_the_ui_nor_plotting(argv, tmp_path):
    scaled, broken = tmp_path / "scaled.yaml", tmp_path / "broken.yaml"
    scaled.write_text(SCALED)
    broken.write_text(SCALED.replace("pins: [1, 2]", "pins: [1, 17]"))
    argv = [a.format(protocols=PROTOCOLS, scaled=scaled, broken=broken) for a in argv]
    code = (
        "import sys\n"
        "from pinarray.cli import main\n"
        "try:\n"
        f"    status = main({argv!r})\n"
        "except SystemExit as stop:\n"
        "    status = stop.code\n"
        f"heavy = sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r})\n"
        "print('loaded:', heavy[:5], 'status:', status)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )
    last = result.stdout.strip().splitlines()[-1]
    expected_status = 2 if "broken" in " ".join(argv) else 0
    assert last == f"loaded: [] status: {expected_status}"
    if "scaled" in " ".join(argv):
        assert "note: scaled to" in result.stdout  # the path that compiles drives did run


def read_csv(path: Path) -> tuple[list[str], list[list[int]]]:
    with path.open() as stream:
        header, *rows = csv.reader(stream)
    return header, [[int(x) for x in row] for row in rows]


def test_a_npz_out_holds_the_same_pulses_and_targets_as_the_csv(tmp_path):
    protocol = str(PROTOCOLS / "apparent_motion.yaml")
    csv_pulses, csv_targets = tmp_path / "p.csv", tmp_path / "t.csv"
    npz_pulses, npz_targets = tmp_path / "p.npz", tmp_path / "t.NPZ"
    common = ["compile", protocol, "--seed", "3"]
    assert main([*common, "--out", str(csv_pulses), "--targets", str(csv_targets)]) == 0
    assert main([*common, "--out", str(npz_pulses), "--targets", str(npz_targets)]) == 0

    for csv_path, npz_path in ((csv_pulses, npz_pulses), (csv_targets, npz_targets)):
        header, rows = read_csv(csv_path)
        with np.load(npz_path) as archive:
            assert sorted(archive.files) == sorted(header)
            columns = [archive[name].tolist() for name in header]
            times = archive[header[2]]
        assert len(rows) > 100
        assert [list(r) for r in zip(*columns, strict=True)] == rows
        assert times.dtype == np.int64


def test_an_unwritable_npz_is_one_line_and_leaves_no_file(tmp_path, capsys):
    nowhere = tmp_path / "missing" / "p.npz"
    assert main(["compile", str(PROTOCOLS / "demo.yaml"), "--out", str(nowhere)]) == 2
    assert capsys.readouterr().err.startswith(f"pinarray: {nowhere}: cannot write:")


def test_a_compile_that_fails_removes_its_half_made_npz(tmp_path, capsys):
    out = tmp_path / "p.npz"
    # the targets go to a folder that does not exist: the pulses' archive is not kept
    targets = tmp_path / "missing" / "t.csv"
    argv = ["compile", str(PROTOCOLS / "demo.yaml"), "--out", str(out), "--targets", str(targets)]
    assert main(argv) == 2
    assert "cannot write" in capsys.readouterr().err
    assert not out.exists()


def test_a_full_device_is_one_line_and_status_2(capsys):
    assert main(["compile", str(PROTOCOLS / "demo.yaml"), "--out", "/dev/full"]) == 2
    assert capsys.readouterr().err == "pinarray: /dev/full: cannot write: No space left on device\n"


def test_a_failed_compile_leaves_the_earlier_outputs_as_they_were(tmp_path, capsys):
    pulses, targets = tmp_path / "p.csv", tmp_path / "t.npz"
    pulses.write_text("yesterday's pulses\n")
    argv = ["compile", str(PROTOCOLS / "demo.yaml"), "--out", str(pulses), "--targets"]
    assert main([*argv, "/dev/full"]) == 2
    assert main([*argv, str(tmp_path)]) == 2  # a folder
    assert "it is a folder, expected a file name" in capsys.readouterr().err
    assert pulses.read_text() == "yesterday's pulses\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.csv"]  # no temporary file left
    assert main([*argv, str(targets)]) == 0
    assert pulses.read_text().startswith("trial,pin,start_ns,width_ns\n") and targets.exists()


def test_outputs_get_the_modes_of_ordinary_files(tmp_path):
    out, ordinary = tmp_path / "p.csv", tmp_path / "ordinary"
    ordinary.write_text("")
    assert main(["compile", str(PROTOCOLS / "demo.yaml"), "--out", str(out)]) == 0
    assert out.stat().st_mode == ordinary.stat().st_mode


def test_preview_says_where_the_png_really_went(tmp_path, capsys):
    name = tmp_path / "timeline"
    assert main(["preview", str(PROTOCOLS / "demo.yaml"), "--png", str(name)]) == 0
    assert capsys.readouterr().out.endswith(f"timeline drawn to {name}.png\n")
    assert (tmp_path / "timeline.png").read_bytes()[:4] == b"\x89PNG" and not name.exists()
