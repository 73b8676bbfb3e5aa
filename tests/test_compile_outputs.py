"""`pinarray compile` writes CSV or a numpy archive; `pinarray validate` starts light (numpy
only to play a valid protocol's stimuli on the simulated array)."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pinarray.cli import main
from tests.test_protocol_load import MINIMAL
from tests.test_schedule import exact_start_ns, seed_train

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"

# A 40 Hz stroke scaled to what the datasheet's figures reach: played on the simulated array,
# which accelerates as a servo does, it falls short, and `validate` refuses it.
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
    """... numpy only where a valid protocol's stimuli are played on the simulated array
    (`pinarray.player.rehearsal`)."""
    scaled, broken = tmp_path / "scaled.yaml", tmp_path / "broken.yaml"
    scaled.write_text(SCALED)
    broken.write_text(SCALED.replace("pins: [1, 2]", "pins: [1, 17]"))
    argv = [a.format(protocols=PROTOCOLS, scaled=scaled, broken=broken) for a in argv]
    played = argv[0] == "validate" and "--help" not in argv and "broken" not in " ".join(argv)
    heavy = tuple(h for h in HEAVY if not (played and h in ("numpy", "serial")))
    code = (
        "import sys\n"
        "from pinarray.cli import main\n"
        "try:\n"
        f"    status = main({argv!r})\n"
        "except SystemExit as stop:\n"
        "    status = stop.code\n"
        f"heavy = sorted(m for m in sys.modules if m.split('.')[0] in {heavy!r})\n"
        "print('loaded:', heavy[:5], 'status:', status)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )
    last = result.stdout.strip().splitlines()[-1]
    expected_status = 2 if "broken" in " ".join(argv) or "scaled" in " ".join(argv) else 0
    assert last == f"loaded: [] status: {expected_status}"
    if "scaled" in " ".join(argv):
        assert "scaled.yaml:12:20: played as a run plays it" in result.stderr  # it was played


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



def long_protocol(hours: int, frequency_hz: int = 10) -> str:
    """The seed train on pin 6 for ``hours``: a servo endurance run, too long to play."""
    return f"""\
protocol: endurance
stimuli:
  seed_train:
    frequency_hz: {frequency_hz}
    duration_s: {hours * 3600}
    pulses_per_cycle: 10
    duty_cycle: 0.5
    pulse_width_ms: {{up: 2.0, down: 1.5}}
design:
  paradigm: localisation
  stimulus: seed_train
  pins: [6]
  frequencies_hz: [{frequency_hz}]
"""


@pytest.mark.parametrize(
    "command", [["compile", "--out", "{out}"], ["validate"], ["play", "--sim"]]
)
def test_a_trial_too_long_to_play_is_refused_in_one_line_that_names_the_opt_in(
    command, tmp_path, capsys
):
    protocol, out = tmp_path / "day.yaml", tmp_path / "pulses.npz"
    protocol.write_text(long_protocol(3))  # 1 080 001 pulse slots
    argv = [command[0], str(protocol), *(a.format(out=out) for a in command[1:])]
    assert main(argv) == 2
    prefix = "" if command[0] == "validate" else "pinarray: "
    assert capsys.readouterr().err == (
        f"{prefix}{protocol}:13:20: expected at most 1,000,000 pulses in one trial, found "
        "1,080,001 (frequency x pulses per cycle x signal length, for each pin); shorten the "
        "signal, or, to write a longer schedule to a file, use pinarray compile --allow-long\n"
    )
    assert list(tmp_path.iterdir()) == [protocol]


def test_with_the_opt_in_a_10_hour_train_is_written_and_every_pulse_starts_at_its_exact_time(
    tmp_path,
):
    # 3 Hz x 10 pulses: a slot of 33 333 333 1/3 ns, so every start is rounded on its own
    protocol, out = tmp_path / "long.yaml", tmp_path / "pulses.npz"
    protocol.write_text(long_protocol(10, frequency_hz=3))
    argv = ["compile", str(protocol), "--allow-long", "--out", str(out), "--targets"]
    assert main([*argv, str(tmp_path / "targets.npz")]) == 0

    with np.load(out) as archive:
        trial, pin = archive["trial"], archive["pin"]
        start, width = archive["start_ns"], archive["width_ns"]
    assert len(start) == 10 * 3600 * 30 == 1_080_000
    assert (trial == 1).all() and (pin == 6).all() and start.dtype == np.int64
    train = seed_train(3, 10 * 3600)
    for k in (0, 1, 2, 299_999, 540_001, 1_079_998, 1_079_999):
        assert int(start[k]) == exact_start_ns(k, train)
    # every pulse, against k * 10^9 / 30 ns rounded halves up in plain integers
    k = np.arange(1_080_000, dtype=np.int64)
    assert np.array_equal(start, (2 * k * 1_000_000_000 + 30) // 60)
    assert np.array_equal(width, np.where(k % 10 < 5, 2_000_000, 1_500_000))
    with np.load(tmp_path / "targets.npz") as targets:
        # the pin lifts at each cycle's first pulse and lowers at its sixth (its rest position)
        assert np.array_equal(targets["time_ns"][0::2], start[0::10])
        assert np.array_equal(targets["time_ns"][1::2], start[5::10])


def test_with_the_opt_in_a_long_train_is_written_as_csv_too(tmp_path):
    protocol, out = tmp_path / "long.yaml", tmp_path / "pulses.csv"
    protocol.write_text(long_protocol(3))
    assert main(["compile", str(protocol), "--allow-long", "--out", str(out)]) == 0
    with out.open() as stream:
        lines = stream.read().splitlines()
    assert len(lines) == 1 + 1_080_000
    assert lines[:3] == ["trial,pin,start_ns,width_ns", "1,6,0,2000000", "1,6,10000000,2000000"]
    assert lines[-1] == f"1,6,{1_079_999 * 10_000_000},1500000"


def test_even_with_the_opt_in_a_trial_past_the_plans_10_million_pulses_is_refused(
    tmp_path, capsys
):
    protocol = tmp_path / "two_days.yaml"
    protocol.write_text(long_protocol(48))
    out = tmp_path / "pulses.npz"
    assert main(["compile", str(protocol), "--allow-long", "--out", str(out)]) == 2
    assert capsys.readouterr().err.startswith(
        f"pinarray: {protocol}:13:20: expected at most 10,000,000 pulses in one trial written "
        "to a file, found 17,280,001"
    )
    assert not out.exists()


def test_a_long_npz_replaces_the_earlier_file_only_once_every_output_is_complete(
    tmp_path, capsys
):
    protocol, out, full = tmp_path / "long.yaml", tmp_path / "pulses.npz", tmp_path / "full.npz"
    protocol.write_text(long_protocol(3))
    out.write_bytes(b"yesterday's archive")
    full.symlink_to("/dev/full")
    argv = ["compile", str(protocol), "--allow-long", "--out", str(out), "--targets"]
    # the pulses' archive is written whole, then the targets' fails on a full device
    assert main([*argv, str(full)]) == 2
    assert capsys.readouterr().err == f"pinarray: {full}: cannot write: No space left on device\n"
    assert out.read_bytes() == b"yesterday's archive"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full.npz", "long.yaml", "pulses.npz"]
    assert main([*argv, str(tmp_path / "targets.npz")]) == 0
    with np.load(out) as archive:
        assert len(archive["start_ns"]) == 1_080_000


def test_a_npz_sent_to_a_device_such_as_dev_null_is_written_straight_through(tmp_path):
    protocol, out = tmp_path / "mini.yaml", tmp_path / "nowhere.npz"
    protocol.write_text(MINIMAL)
    out.symlink_to("/dev/null")
    assert main(["compile", str(protocol), "--out", str(out)]) == 0
    assert out.is_symlink()
