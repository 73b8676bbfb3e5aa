"""The timing check says in words whether a lost-then-healed goal still arrives in time."""

from pinarray.player.timing import PortFigures, WakeUps, judge

MS = 1_000_000


def test_wake_ups_summarise_lateness_by_percentile():
    wake_ups = WakeUps.of([0] * 98 + [2 * MS, 5 * MS])
    assert (wake_ups.samples, wake_ups.p50_ns, wake_ups.p99_ns, wake_ups.max_ns) == (100, 0, 5 * MS, 5 * MS)


def test_a_quiet_machine_with_a_fast_adapter_can_deliver():
    verdict = judge(WakeUps.of([10_000, 80_000]), "", PortFigures("/dev/ttyUSB0", 1, 2 * MS, 1), 10 * MS)
    assert verdict.deliverable and verdict.worst_case_ns == 2 * MS + 80_000
    assert verdict.lines[-1].startswith("OK: stimuli can be delivered as scheduled")


def test_a_late_waking_machine_is_told_to_grant_real_time_priority():
    problem = "real-time priority not granted (Operation not permitted): ..."
    verdict = judge(WakeUps.of([1 * MS, 12 * MS]), problem, PortFigures("/dev/ttyUSB0", 1, 2 * MS, 1), 10 * MS)
    assert not verdict.deliverable
    assert "NOT OK" in verdict.lines[2] and f"to fix: {problem}" in verdict.lines


def test_an_adapter_left_at_16_ms_is_told_to_lower_its_latency_timer():
    verdict = judge(WakeUps.of([50_000]), "", PortFigures("/dev/ttyUSB0", 16, 34 * MS, 16), 10 * MS)
    assert not verdict.deliverable
    assert any("latency timer to 1 ms" in line and "it is 16 ms" in line for line in verdict.lines)
    assert "reading back the 16 goals of the protocol's busiest frame" in verdict.lines[1]
