"""A stimulus must not give its answer away by how long it lasts."""

from pinarray.protocol.cues import duration_cues, stimulus_duration_ns
from pinarray.protocol.load import load_protocol
from tests.commands import pinarray_here
from tests.lab_protocols import short_copy
from tests.runs import REPO

PROTOCOLS = REPO / "protocols"
MS = 1_000_000


def test_the_shipped_motion_configurations_last_equally_long():
    protocol = load_protocol(PROTOCOLS / "apparent_motion.yaml")
    durations = {c.stimulus: stimulus_duration_ns(protocol, c) for c in protocol.design.conditions}
    assert durations == {"rightwards": 800 * MS, "leftwards": 800 * MS, "no_wave": 800 * MS}
    assert duration_cues(protocol) == []


def test_no_shipped_protocol_gives_a_duration_cue():
    for path in sorted(PROTOCOLS.glob("*.yaml")):
        assert duration_cues(load_protocol(path)) == [], path.name


# The shipped motion protocol as it was: the no-wave at a 250 ms SOA lasts 0.9 s.
LONGER_NO_WAVE = ("    soa_ms: 200              # centre 0-400 ms",
                  "    soa_ms: 250              # centre 0-400 ms")


def _longer_no_wave(tmp_path):
    text = (PROTOCOLS / "apparent_motion.yaml").read_text()
    assert LONGER_NO_WAVE[0] in text
    path = tmp_path / "motion.yaml"
    path.write_text(text.replace(*LONGER_NO_WAVE))
    return path


def test_validate_warns_when_the_no_wave_lasts_longer_than_the_waves(tmp_path):
    path = _longer_no_wave(tmp_path)
    result = pinarray_here("validate", path)
    assert result.returncode == 0  # a warning, not a refusal: the lab may have its reasons
    assert result.stdout.startswith(f"{path}: ok")
    assert result.stderr.splitlines() == [
        f"{path}: warning: the stimuli a subject must tell apart last different times (no_wave "
        "0.900 s; rightwards, leftwards 0.800 s): duration alone could give the answer away; "
        "make them last equally long"]


def test_batch_shows_the_duration_cue_warning_before_it_runs(tmp_path):
    # Its short copy (one block, one repetition): the warning is the point, not the trials.
    path = short_copy("apparent_motion", tmp_path, LONGER_NO_WAVE)
    result = pinarray_here("batch", path, "--subject", "01", "--observer", "default",
                           "--results", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    first = result.stderr.splitlines()[0]
    assert first.startswith(f"pinarray: warning: {path}: the stimuli a subject must tell apart "
                            "last different times (no_wave 0.900 s; rightwards, leftwards 0.800 s)")

