"""A rehearsal on the simulated array is never spoiled by a busy host.

On the in-process simulator the UI, its redraws and the lab PC's other programs share the
interpreter and the CPU with the simulated servos. A host held up for tens of milliseconds
must not make a rehearsal's stimulus late where real servos, in a player process of their
own, would have had it in time: each stimulus plays in the simulator's own time.
"""

import threading
import time

import pytest

from pinarray.clock import MonotonicClock, ScaledClock
from pinarray.plan import make_plan
from pinarray.player.rig import Rig
from pinarray.protocol.load import parse_protocol
from pinarray.schedule import compile_trial
from tests.runs import REPO

# The seed's localisation train, 0.3 s long, so that a trial takes little wall time.
SHORT = (REPO / "protocols" / "localisation.yaml").read_text().replace(
    "duration_s: 10\n", "duration_s: 0.3\n")


class BusyHost(MonotonicClock):
    """The wall clock of a host that now and then does something else for 40 ms: every 7th
    look at the time finds it 40 ms later than the look before (no real time passes)."""

    def __init__(self):
        super().__init__()
        self.looks = 0
        self.lost_ns = 0

    def now_ns(self):
        self.looks += 1
        if self.looks % 7 == 0:
            self.lost_ns += 40_000_000
        return super().now_ns() + self.lost_ns

    # Its waits are on its own time line, the one its readings are on.
    def sleep_until_ns(self, deadline_ns):
        super().sleep_until_ns(deadline_ns - self.lost_ns)

    def doze_until_ns(self, deadline_ns):
        super().doze_until_ns(deadline_ns - self.lost_ns)


def present_all(clock, trials=4):
    protocol = parse_protocol(SHORT, "short.yaml")
    assert "duration_s: 0.3\n" in SHORT  # the replacement took
    plan = make_plan(protocol, 5)
    with Rig(protocol, None, None, clock) as rig:
        return [rig.present(compile_trial(protocol, planned)).delivery
                for planned in plan.trials[:trials]]


@pytest.mark.realtime
def test_a_host_held_up_for_40_ms_again_and_again_spoils_no_rehearsal_stimulus():
    host = BusyHost()
    deliveries = present_all(ScaledClock(1.0, base=host))
    assert host.lost_ns >= 10 * 40_000_000  # the host really was held up, many times
    assert all(d.delivered for d in deliveries), [d.problem for d in deliveries]
    assert all(d.worst_lateness_ns <= d.tolerance_ns for d in deliveries)


@pytest.mark.realtime
def test_the_time_after_a_stimulus_follows_the_wall_clock_again_and_never_goes_back():
    host = BusyHost()
    clock = ScaledClock(1.0, base=host)
    before = clock.now_ns()
    present_all(clock, trials=1)
    after = clock.now_ns()
    assert after >= before
    # Back on the wall clock: within a few host hiccups of it, not behind by the stimulus.
    wall = round(host.now_ns() - clock._start_ns)
    assert abs(clock.now_ns() - wall) <= 2 * 40_000_000


def test_another_thread_waiting_through_a_stimulus_leaves_the_clock_running():
    # The UI's thread dozes on the clock while the player's thread plays in the simulator's
    # own time; when the stimulus ends first, time still follows the wall clock.
    clock = ScaledClock(1.0)
    dozing = threading.Thread(target=lambda: clock.doze_until_ns(clock.now_ns() + 60_000_000))
    with clock.own_time():
        dozing.start()
        clock.sleep_until_ns(clock.now_ns() + 10_000_000)
    dozing.join()
    before = clock.now_ns()
    time.sleep(0.05)
    assert clock.now_ns() - before >= 40_000_000  # moving with the wall clock again


def test_one_stimulus_plays_in_own_time_at_a_time():
    clock = ScaledClock(1.0)
    with clock.own_time(), pytest.raises(RuntimeError, match="one stimulus plays at a time"):
        with clock.own_time():
            pass
    assert clock.now_ns() >= 0  # the clock still reads after the refused block
