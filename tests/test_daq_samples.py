"""`pinarray compile --daq-rate HZ --out FILE.npz`: the 16 digital lines' samples for a DAQ card,
exact to the sample from the pulse list, streamed to the file in bounded memory."""

import json
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pinarray.cli import main
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol
from pinarray.schedule import compile_trial, daq_words, render_dense
from tests.test_compile_outputs import long_protocol

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"

# 3 Hz x 10 pulses: a slot of 33 333 333 1/3 ns, so the starts are rounded one by one; pins 1 and
# 16 are the first and the last of the DAQ's lines.
CORNERS = """\
protocol: corners
stimuli:
  buzz:
    frequency_hz: 3
    duration_s: 2
    pulse_width_ms: {up: 2.0, down: 1.5}
design:
  paradigm: localisation
  stimulus: buzz
  pins: [1, 16]
  frequencies_hz: [3, 7]
  order: sequential
"""


def compile_daq(tmp_path: Path, protocol: Path | str, rate_hz: int, *more: str) -> Path:
    out = tmp_path / "samples.npz"
    argv = ["compile", str(protocol), "--seed", "7", "--daq-rate", str(rate_hz), "--out", str(out)]
    assert main([*argv, *more]) == 0
    return out


def corners(tmp_path: Path) -> Path:
    path = tmp_path / "corners.yaml"
    path.write_text(CORNERS)
    return path


def trials_and_schedules(protocol_path, seed=7):
    protocol = load_protocol(protocol_path)
    plan = make_plan(protocol, seed)
    return [(planned, compile_trial(protocol, planned)) for planned in plan.trials]


def ceil_sample(time_ns: int, rate_hz: int) -> int:
    """The first sample at or after ``time_ns``, in plain integers."""
    return -(-time_ns * rate_hz // 1_000_000_000)


def test_every_edge_lands_on_the_first_sample_at_or_after_the_pulse_lists_time(tmp_path):
    rate_hz = 7919  # a prime: no pulse time falls on a sample instant by luck
    with np.load(compile_daq(tmp_path, corners(tmp_path), rate_hz)) as archive:
        samples, first, count = (archive[k] for k in
                                 ("samples", "trial_first_sample", "trial_sample_count"))
    for planned, schedule in trials_and_schedules(corners(tmp_path)):
        expected = np.zeros(schedule.end_ns * rate_hz // 1_000_000_000 + 1, dtype=np.uint16)
        pulses = schedule.pulses
        for pin, start, width in zip(pulses.pin.tolist(), pulses.start_ns.tolist(),
                                     pulses.width_ns.tolist(), strict=True):
            rise, fall = ceil_sample(start, rate_hz), ceil_sample(start + width, rate_hz)
            assert fall > rise  # every pulse of these trains is at least one sample wide
            expected[rise:fall] |= 1 << (pin - 1)
        index = planned.trial - 1
        assert count[index] == len(expected)
        assert np.array_equal(samples[first[index] : first[index] + count[index]], expected)
        assert expected[-1] == 0  # a trial ends low on every line


def test_pin_1_drives_bit_0_and_pin_16_bit_15(tmp_path):
    with np.load(compile_daq(tmp_path, corners(tmp_path), 10_000)) as archive:
        samples, pins = archive["samples"], archive["trial_pin"]
        first, count = archive["trial_first_sample"], archive["trial_sample_count"]
    assert sorted(set(pins.tolist())) == [1, 16]
    for pin, a, n in zip(pins.tolist(), first.tolist(), count.tolist(), strict=True):
        # the trains of 3 and 7 Hz: 60 and 140 pulses of 1.5 or 2 ms, each 15 or 20 samples
        assert set(np.unique(samples[a : a + n]).tolist()) == {0, 1 << (pin - 1)}
        assert int(np.count_nonzero(samples[a : a + n])) in (60 * 175 // 10, 140 * 175 // 10)


@pytest.mark.parametrize("protocol", ["apparent_motion.yaml", "demo.yaml"])
def test_the_streamed_samples_are_render_dense_packed_into_words(tmp_path, protocol):
    rate_hz = 10_000
    with np.load(compile_daq(tmp_path, PROTOCOLS / protocol, rate_hz)) as archive:
        samples, first, count = (archive[k] for k in
                                 ("samples", "trial_first_sample", "trial_sample_count"))
    for planned, schedule in trials_and_schedules(PROTOCOLS / protocol):
        dense = render_dense(schedule.pulses, range(1, 17), rate_hz, schedule.end_ns)
        words = (dense.astype(np.uint16) << np.arange(16, dtype=np.uint16)[:, None]).sum(
            axis=0, dtype=np.uint16)
        trial = samples[first[planned.trial - 1] :][: count[planned.trial - 1]]
        assert np.array_equal(trial[: len(words)], words)
        assert not trial[len(words) :].any() and len(trial) - len(words) in (0, 1)


@pytest.mark.parametrize("block", [1, 7, 1000, 1 << 20])
def test_the_blocks_a_trial_is_streamed_in_do_not_change_its_samples(block):
    # a wave: three pins whose pulses meet and straddle the blocks' edges
    planned, schedule = trials_and_schedules(PROTOCOLS / "apparent_motion.yaml")[0]
    count = 4001  # 0.8 s at 5 kHz, and the low sample at the end
    words = np.concatenate(list(daq_words(schedule.pulses, 5000, count, block)))
    dense = render_dense(schedule.pulses, range(1, 17), 5000, schedule.end_ns)
    assert len(words) == count and dense.shape[1] == count - 1
    for pin in range(1, 17):
        assert np.array_equal((words[:-1] >> (pin - 1)) & 1, dense[pin - 1])


def test_np_load_reads_the_rate_and_every_trials_place_condition_and_order(tmp_path):
    rate_hz = 2000
    with np.load(compile_daq(tmp_path, PROTOCOLS / "localisation.yaml", rate_hz)) as archive:
        assert archive["samples"].dtype == np.dtype("<u2")
        assert archive["sample_rate_hz"] == rate_hz
        layout = {name: archive[name] for name in archive.files if name.startswith("trial")}
        plan = json.loads(str(archive["plan"]))
        total = len(archive["samples"])
    trials = trials_and_schedules(PROTOCOLS / "localisation.yaml")
    assert plan["seed"] == 7 and len(plan["trials"]) == len(trials) == len(layout["trial"])
    assert layout["trial"].tolist() == list(range(1, len(trials) + 1))  # plan order
    counts = [s.end_ns * rate_hz // 1_000_000_000 + 1 for _, s in trials]
    assert layout["trial_sample_count"].tolist() == counts
    assert layout["trial_first_sample"].tolist() == np.cumsum([0, *counts[:-1]]).tolist()
    assert total == sum(counts)
    for (planned, _), pin, frequency_hz, practice in zip(
        trials, layout["trial_pin"], layout["trial_frequency_hz"], layout["trial_practice"],
        strict=True,
    ):
        assert (pin, frequency_hz) == (planned.condition.pin, planned.condition.frequency_hz)
        assert practice == planned.practice


def sample_at(path: Path, k: int) -> int:
    """Sample ``k`` of an archive, read where the stored member keeps it without loading the
    rest (zipfile's own seek would read, and check, all the bytes before it: 360 MB here)."""
    with zipfile.ZipFile(path) as archive:
        member = archive.getinfo("samples.npy")
    assert member.compress_type == zipfile.ZIP_STORED
    with open(path, "rb") as handle:
        handle.seek(member.header_offset)
        local = handle.read(30)  # the member's local header; its name and extra field follow
        assert local[:4] == b"PK\x03\x04"
        handle.seek(member.header_offset + 30 + int.from_bytes(local[26:28], "little")
                    + int.from_bytes(local[28:30], "little"))
        np.lib.format.read_magic(handle)
        np.lib.format.read_array_header_1_0(handle)
        handle.seek(handle.tell() + 2 * k)
        return int.from_bytes(handle.read(2), "little")


def test_half_an_hour_at_100_khz_is_streamed_in_memory_far_below_the_file_and_exact_at_its_end(
    tmp_path,
):
    # 180 000 000 samples, a 360 MB file. Measured: a peak of about 5 MB (also for an hour,
    # 720 MB): the trial's pulse list and a few blocks of samples.
    protocol = tmp_path / "half_hour.yaml"
    protocol.write_text(long_protocol(1, frequency_hz=1).replace("3600", "1800"))
    tracemalloc.start()
    try:
        out = compile_daq(tmp_path, protocol, 100_000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    size = out.stat().st_size
    assert size > 360_000_000
    assert peak < 16_000_000 < size // 20
    # the last pulse (1.5 ms at 1799.9 s) rises and falls on its samples, half an hour in
    last_start = 1_799_900_000_000
    rise, fall = last_start // 10_000, (last_start + 1_500_000) // 10_000
    assert [sample_at(out, k) for k in (rise - 1, rise, fall - 1, fall)] == [0, 32, 32, 0]


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (["--daq-rate", "0", "--out", "{tmp}/s.npz"], "expected a whole number from 1 to 10,000,000"),
        (["--daq-rate", "-3", "--out", "{tmp}/s.npz"], "expected a whole number from 1 to 10,000,000"),
        (["--daq-rate", "1e9", "--out", "{tmp}/s.npz"], "expected a whole number, found '1e9'"),
        (["--daq-rate", "10000001", "--out", "{tmp}/s.npz"], "found '10000001'"),
        (["--daq-rate", "1000"], "the following arguments are required: --out"),
        (["--daq-rate", "1000", "--out", "-"], "pinarray: --daq-rate: expected --out FILE.npz"),
        (["--daq-rate", "1000", "--out", "{tmp}/s.csv"], "expected --out FILE.npz"),
        (["--daq-rate", "1000", "--out", "{tmp}/folder.npz"], "it is a folder, expected a file"),
        (["--daq-rate", "1000", "--out", "{tmp}/full.npz"], "cannot write: No space left on"),
    ],
)
def test_a_bad_rate_or_output_is_refused_with_status_2_and_leaves_no_file(
    tmp_path, capsys, options, expected
):
    (tmp_path / "folder.npz").mkdir()
    (tmp_path / "full.npz").symlink_to("/dev/full")
    argv = ["compile", str(PROTOCOLS / "demo.yaml"), *(o.format(tmp=tmp_path) for o in options)]
    try:
        status = main(argv)
    except SystemExit as stop:
        status = stop.code
    err = capsys.readouterr().err
    assert status == 2 and expected in err.splitlines()[-1]
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.npz", "full.npz"]


def test_a_protocol_driving_a_pin_past_the_16_lines_is_refused_before_any_file(tmp_path, capsys):
    protocol = tmp_path / "wide.yaml"
    protocol.write_text(CORNERS.replace("protocol: corners", "protocol: wide\ndevice:\n  grid: "
                                        "{rows: 5, columns: 5}").replace("[1, 16]", "[1, 20]"))
    out = tmp_path / "s.npz"
    assert main(["compile", str(protocol), "--daq-rate", "1000", "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"pinarray: {protocol}: trial 2 drives pin 20: expected pins 1 to 16, one per line of "
        "the DAQ's uint16 samples\n")
    assert not out.exists()


def test_samples_that_would_take_hours_and_terabytes_are_refused_with_the_rate_that_fits(
        tmp_path, capsys):
    protocol = tmp_path / "two_days.yaml"
    protocol.write_text(long_protocol(48, frequency_hz=3))  # a 48 h train, inside every input limit
    out = tmp_path / "s.npz"
    assert main(["compile", str(protocol), "--allow-long", "--daq-rate", "10000000",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "1,728,000,000,001 samples at 10,000,000 Hz" in err
    assert "3.46 TB" in err and "lower --daq-rate (at most 57,870 Hz for this plan)" in err
    assert sorted(tmp_path.iterdir()) == [protocol]


def test_samples_that_would_not_fit_on_the_disk_are_refused_before_a_byte_is_written(
        tmp_path, capsys, monkeypatch):
    class AlmostFull:
        f_bavail, f_frsize = 10, 4096

    monkeypatch.setattr("pinarray.cli.daq_samples.os.statvfs", lambda folder: AlmostFull)
    out = tmp_path / "s.npz"
    assert main(["compile", str(corners(tmp_path)), "--daq-rate", "100000", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (f"pinarray: {out}: cannot write: 800,004 samples take 1.6 MB, the disk has "
                   "41 kB free; lower --daq-rate or make room\n")
    assert not out.exists()


def test_a_large_samples_file_says_how_far_it_is_a_line_per_tenth(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("pinarray.cli.common.PROGRESS_AFTER_S", 0.0)
    compile_daq(tmp_path, corners(tmp_path), 100_000)
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("compile:")]
    assert lines[-1] == "compile: samples written: 800,004 of 800,004 (100 %)"
    assert 2 <= len(lines) <= 10
