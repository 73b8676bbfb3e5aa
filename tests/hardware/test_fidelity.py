"""The simulated bus at each level of its ladder: the packet level is the wire without the bytes
(the same trial, to the nanosecond and the byte counted, faults and all), the motion level
samples as the wire would with none held back, and a level is named in the URL or refused."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinarray.clock import VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.feetech.faults import parse_sim_url
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.hardware.feetech.sim_levels import Fidelity
from pinarray.hardware.feetech.transport import fidelity_of
from pinarray.player.families import open_array
from pinarray.player.playback import PlaybackAborted, play_trial
from pinarray.player.simulators import simulation_level
from pinarray.protocol.load import load_protocol
from tests.runs import REPO

from .lab import pulse_train, sim_bus, targets

MS = 1_000_000
PROTOCOLS = REPO / "protocols"


def play(query: str, schedule, trials: int = 2):
    """Play ``schedule`` ``trials`` times on a new bus; everything a run could tell apart."""
    level = query.rpartition("fidelity=")[2]
    try:
        bus = sim_bus(query)
    except PinArrayError as refused:  # the handshake gave up (the port named without level)
        return [("refused", str(refused).replace(f"&fidelity={level}", ""))]
    seen = []
    for _ in range(trials):
        try:
            report = play_trial(bus, schedule, bus.clock, release_at_end=False)
        except PlaybackAborted as stopped:
            seen.append(("aborted", str(stopped).replace(f"&fidelity={level}", ""),
                         bus.clock.now_ns()))
            break
        seen.append((report.delivery, report.sent_ns.tolist(), report.bytes_written,
                     report.bytes_read, report.retries,
                     [(t.pin, t.time_ns.tolist(), t.position_steps.tolist()) for t in report.trace],
                     bus.clock.now_ns()))
    seen.append((bus.stats(), bus.link.counters, bus.sim.packets_received,
                 [(s.goal_steps, s.position_steps, s.torque_enabled)
                  for s in bus.sim.servos.values()]))
    return seen


def test_each_level_is_what_its_url_names_and_packet_is_the_default():
    assert fidelity_of(sim_bus()) is Fidelity.PACKET
    for level in Fidelity:
        assert fidelity_of(sim_bus(f"fidelity={level}")) is level


def test_a_protocols_simulated_array_says_how_closely_it_is_simulated():
    device = load_protocol(PROTOCOLS / "localisation.yaml").device
    said = [simulation_level(open_array(device, None, url, VirtualClock()))
            for url in (None, "sim://?fidelity=wire", "sim://?fidelity=motion")]
    assert said == ["packet level: exchanges computed whole", "wire level: every byte at its time",
                    "motion level: motion samples computed"]
    board = load_protocol(PROTOCOLS / "localisation_pwm.yaml").device
    assert simulation_level(open_array(board, None, None, VirtualClock())) == (
        "every I2C message to the board's registers")


@pytest.mark.parametrize("faults", ["", "drop_writes=0.2&seed=4", "drop=0.05&seed=2",
                                    "corrupt=0.05&seed=1", "late=0.05&late_ms=2&seed=3",
                                    "return_delay_us=0", "baud=115200"])
def test_the_packet_level_plays_a_trial_as_the_wire_does(faults):
    schedule = pulse_train([2, 7, 11], 10, 4)
    wire = play("&".join(filter(None, [faults, "fidelity=wire"])), schedule)
    packet = play("&".join(filter(None, [faults, "fidelity=packet"])), schedule)
    assert packet == wire


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 1000), st.sampled_from(["drop", "drop_writes", "corrupt", "late"]),
       st.sampled_from([0.02, 0.2]), st.lists(st.integers(1, 16), min_size=1, max_size=4,
                                              unique=True), st.sampled_from([3, 10, 40]))
def test_under_any_fault_the_packet_level_is_the_wire(seed, fault, rate, pins, rate_hz):
    schedule = pulse_train(pins, rate_hz, 3)
    query = f"{fault}={rate}&late_ms=3&seed={seed}"
    assert play(f"{query}&fidelity=packet", schedule) == play(f"{query}&fidelity=wire", schedule)


@pytest.mark.parametrize("pins, rate_hz", [([5], 10), ([3, 8, 12, 15], 5), ([1], 40)])
def test_the_motion_level_takes_every_wire_sample_and_judges_the_trial_alike(pins, rate_hz):
    schedule = pulse_train(pins, rate_hz, 6)
    wire, motion = sim_bus("fidelity=wire"), sim_bus("fidelity=motion")
    for _ in range(2):
        sampled = play_trial(wire, schedule, wire.clock, release_at_end=False)
        computed = play_trial(motion, schedule, motion.clock, release_at_end=False)
        assert computed.delivery == sampled.delivery  # every count, lateness, stroke and lag
        assert computed.sent_ns.tolist() == sampled.sent_ns.tolist()
        for taken, worked_out in zip(sampled.trace, computed.trace, strict=True):
            assert taken.pin == worked_out.pin
            where = np.searchsorted(worked_out.time_ns, taken.time_ns)
            assert (worked_out.time_ns[where] == taken.time_ns).all()
            assert (worked_out.position_steps[where] == taken.position_steps).all()
            assert len(worked_out.time_ns) >= len(taken.time_ns)


def test_the_motion_level_on_a_slow_bus_samples_back_to_back():
    # 38400 bit/s: one sample of four servos (44 bytes, four return delays) takes 13.5 ms, more
    # than the sampling period. (Here the wire's own read-backs and samples time out, the
    # sync write still on the wire when they start: its samples come late or not at all,
    # which the motion level, sampling a free wire, does not copy.)
    schedule = targets([(0, 2, 2200), (0, 3, 2200), (0, 4, 2200), (0, 5, 2200),
                        (400 * MS, 2, 2048), (400 * MS, 3, 2048), (400 * MS, 4, 2048),
                        (400 * MS, 5, 2048)], 800 * MS)
    wire, motion = sim_bus("baud=38400&fidelity=wire"), sim_bus("baud=38400&fidelity=motion")
    sampled = play_trial(wire, schedule, wire.clock)
    computed = play_trial(motion, schedule, motion.clock)
    assert replace(computed.delivery, strokes=None) == replace(sampled.delivery, strokes=None)
    assert sampled.delivery.delivered and computed.delivery.delivered
    byte_ns = 1e10 / 38400  # the request, then each servo's delay and answer in turn
    one_exchange_ns = round(12 * byte_ns) + 4 * (500_000 + round(8 * byte_ns))
    before_the_second_frame = computed.trace[0].time_ns[computed.trace[0].time_ns < 400 * MS]
    assert (np.diff(before_the_second_frame) == one_exchange_ns).all()


def test_a_level_that_does_not_exist_or_cannot_do_what_is_asked_is_refused():
    with pytest.raises(PinArrayError, match="fidelity: expected one of wire, packet, motion, "
                                            "found 'bytes'"):
        parse_sim_url("sim://?fidelity=bytes")
    with pytest.raises(PinArrayError, match="motion computes every motion sample and injects "
                                            "no faults"):
        parse_sim_url("sim://?drop=0.1&fidelity=motion")
    with pytest.raises(PinArrayError, match="a pseudo-terminal carries bytes"):
        PtyServer(parse_sim_url("sim://?fidelity=packet"))
    # A seed, or how late a late answer would be, injects nothing by itself.
    for quiet in ("seed=3", "late_ms=5", "seed=3&late_ms=5"):
        assert parse_sim_url(f"sim://?{quiet}&fidelity=motion").fidelity is Fidelity.MOTION
    for fault in ("late=0.1", "missing=3", "vanish_after=100"):
        with pytest.raises(PinArrayError, match="motion computes every motion sample"):
            parse_sim_url(f"sim://?{fault}&fidelity=motion")
