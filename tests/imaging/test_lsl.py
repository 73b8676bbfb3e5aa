"""The LSL marker outlet, read back by an independent inlet on 127.0.0.1."""

import json
import os
import subprocess
import sys

import pytest

from pinarray.clock import MonotonicClock
from pinarray.imaging.lsl import STREAM_TYPE, MarkerOutlet
from pinarray.imaging.markers import marker_text
from pinarray.paradigms.localisation.design import LocalisationCondition
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol
from tests.imaging.lsl_inlet import MarkerInlet, unique_stream_name
from tests.lsl_local import MACHINE_ONLY
from tests.runs import REPO

MOTION = REPO / "protocols" / "apparent_motion.yaml"
LOCALISATION = REPO / "protocols" / "localisation.yaml"


def test_the_suite_keeps_lsl_on_this_machine():
    config = open(os.environ["LSLAPICFG"]).read()
    assert "ResolveScope = machine" in config and "MachineAddresses = {127.0.0.1}" in config
    assert "IPv6 = disable" in config and "GlobalAddresses = {}" in config


def test_liblsl_takes_the_machine_only_configuration_whole():
    # liblsl rejects a whole file for one line it cannot read (a '#' comment, prose) and falls
    # back to its defaults, which announce streams on the lab's network: it says so on stderr.
    opened = subprocess.run(
        [sys.executable, "-c", "import pylsl; pylsl.StreamOutlet(pylsl.StreamInfo("
         "'pinarray-config-check', 'Markers', 1, 0, 'string', 'check'))"],
        capture_output=True, text=True, timeout=60, env={**os.environ, "LSLAPICFG": str(MACHINE_ONLY)})
    assert opened.returncode == 0, opened.stderr
    assert "config" not in opened.stderr.lower(), opened.stderr


def test_every_marker_arrives_stamped_with_the_time_it_stands_for():
    clock = MonotonicClock()
    name = unique_stream_name()
    outlet = MarkerOutlet(name, clock)
    try:
        inlet = MarkerInlet(name, count=3)
        assert inlet.found.wait(60)
        assert outlet.offset_s == 0  # on Linux LSL's clock is CLOCK_MONOTONIC, as pinarray's
        base_ns = clock.now_ns() - 5_000_000_000  # stamps may lie in the past (pushed at the end)
        for k in range(3):
            outlet.push(json.dumps({"k": k}), base_ns + k * 123_456_789)
        markers = inlet.join()
    finally:
        outlet.close()
    assert [m["k"] for m, _ in markers] == [0, 1, 2]
    assert [round(stamp - base_ns / 1e9, 9) for _, stamp in markers] == [0, 0.123456789,
                                                                          0.246913578]
    assert inlet.info.type() == STREAM_TYPE and inlet.info.name() == name
    assert inlet.info.channel_format() == 3  # cf_string
    assert inlet.info.source_id() == outlet.source_id
    assert outlet.pushed == 3


@pytest.mark.parametrize("path", [LOCALISATION, MOTION])
def test_a_marker_names_the_trial_and_its_stimulus(path):
    protocol = load_protocol(path)
    for planned in make_plan(protocol, 7).trials:
        data = json.loads(marker_text("onset", planned, protocol, "t"))
        assert (data["event"], data["trial"], data["block"], data["practice"], data["task"]) == (
            "onset", planned.trial, planned.block, planned.practice, "t")
        condition = planned.condition
        if isinstance(condition, LocalisationCondition):
            assert (data["pin"], data["frequency_hz"]) == (condition.pin, condition.frequency_hz)
            assert "direction" not in data
        else:
            assert data["row"] == condition.row
            assert data["direction"] == condition.direction.value
            assert data["frequency_hz"] > 0 and "pin" not in data
