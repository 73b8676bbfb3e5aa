"""Bring-up as a lab does it on new servos, on the simulated bus in virtual time."""

import pytest

from pinarray.clock import VirtualClock
from pinarray.errors import BusError, PinArrayError
from pinarray.hardware.driver import ServoSetup
from pinarray.hardware.feetech import bringup, scan
from pinarray.hardware.feetech import jog as jog_module
from pinarray.hardware.feetech.base import BusSetup
from pinarray.hardware.feetech.link import Latency
from pinarray.hardware.feetech.registers import Register, to_bytes
from pinarray.hardware.feetech.transport import open_bus
from pinarray.stop import StoppableClock, Stopped, StopRequest


def bare_bus(query: str = "ids=1"):
    """Simulated servos, opened as the bring-up commands open them: no handshake."""
    return open_bus(f"sim://?{query}", clock=VirtualClock())


def answering(bus) -> list[int]:
    return sorted(bus.sim.servos)


# -- scan --------------------------------------------------------------------------------------


def test_a_lone_new_servo_is_found_by_a_broadcast_ping_asked_twice():
    bus = bare_bus("ids=1")
    broadcast_ping, asked = bus.broadcast_ping, []
    bus.broadcast_ping = lambda patience=1: asked.append(patience) or broadcast_ping(patience)
    result = scan.scan(bus)
    assert asked == [1, 4]  # the second time listening four times longer, to believe it
    assert result.method is scan.ScanMethod.BROADCAST
    (servo,) = result.found
    assert (servo.servo_id, servo.model_number, servo.return_delay_us) == (1, 777, 500)
    assert servo.telemetry.position_steps == 2048 and result.swept_ids == ()


def test_a_lone_servo_answering_past_the_first_wait_is_found_by_a_second_broadcast_ping():
    # Its answer 60 ms late, past the 34 ms an adapter of unknown latency is first allowed (a
    # busy host can hold it so long): heard when asked again, listening longer; no sweep.
    bus = bare_bus("ids=1&late=1&late_ms=60")
    bus.link.latency = Latency(timer_ms=None)
    result = scan.scan(bus)
    assert result.method is scan.ScanMethod.BROADCAST and result.servo_ids == (1,)
    assert result.swept_ids == ()


def test_a_servo_whose_answer_to_the_broadcast_came_late_is_not_hidden_by_the_others_clean_one():
    # Servo 1's answer late, servo 2's clean: on main "1 servo(s) answered a broadcast ping".
    # Asked again, the two answer together: several servos, so every id is swept.
    bus = bare_bus("ids=1,2")
    bus.sim.late_next = 1
    result = scan.scan(bus)
    assert result.servo_ids == (1, 2) and result.method is scan.ScanMethod.SWEEP


@pytest.mark.parametrize("seed", [1, 3, 8])  # on main, each found one servo, by broadcast
def test_answers_to_the_broadcast_that_come_late_at_random_hide_no_servo(seed):
    # Half the answers 100 ms late: past the 34 ms a first broadcast ping listens on an
    # adapter of unknown latency, within the 136 ms of the one that asks again.
    bus = bare_bus(f"ids=1,2&late=0.5&seed={seed}")
    bus.link.latency = Latency(timer_ms=None)
    assert scan.scan(bus).servo_ids == (1, 2)


def test_a_servo_the_broadcast_heard_is_kept_though_no_ping_of_its_id_is_answered():
    # Heard at the broadcast ping, then every PING of its own id lost: it is there, unreadable.
    bus = bare_bus("ids=5")
    real_ping = bus.ping
    bus.ping = lambda servo_id, retry=True: None if servo_id == 5 else real_ping(servo_id, retry)
    result = scan.scan(bus)
    assert result.method is scan.ScanMethod.BROADCAST and result.found == ()
    (failure,) = result.unreadable
    assert failure == bringup.ServoFailure(5, "answered a broadcast ping, but no PING of its id")


def test_several_servos_collide_on_a_broadcast_ping_so_every_id_is_swept_in_turn():
    bus = bare_bus("ids=3,9,40")
    seen = []
    result = scan.scan(bus, progress=lambda i, last, found: seen.append((i, last, found)))
    assert result.method is scan.ScanMethod.SWEEP
    assert "collided" in result.sweep_reason
    assert result.servo_ids == (3, 9, 40)
    assert [i for i, _, _ in seen] == list(range(253)) and seen[-1][1] == 252
    assert seen[8][2] == (3,) and seen[-1][2] == (3, 9, 40)


def test_one_servo_whose_broadcast_answer_came_garbled_is_not_said_to_collide_with_others():
    bus = bare_bus("ids=4")
    bus.sim.corrupt_next = 1  # its answer to the broadcast ping damaged on the wire
    result = scan.scan(bus)
    assert result.servo_ids == (4,) and result.sweep_reason is scan.SweepReason.GARBLED
    assert "one servo's answers damaged, or several servos' colliding" in result.sweep_reason


def test_a_full_sweep_looks_twice_more_beside_what_answered_and_says_who_answered_at_last():
    # Servo 16's first two answers lost (a host so busy it held them past each wait): the
    # sweep looks again at the ids beside those that answered, longer, then longer still.
    bus = bare_bus("ids=1-16")  # their answers to a broadcast ping collide: a sweep
    lost, waits_ns = {16: 2}, {}
    ping_within = bus.ping_within

    def losing(servo_id, timeout_ns):
        waits_ns.setdefault(servo_id, []).append(timeout_ns)
        if lost.get(servo_id):
            lost[servo_id] -= 1
            return None
        return ping_within(servo_id, timeout_ns)

    bus.ping_within = losing
    seen = []
    result = scan.scan(bus, timeout_ns=10**7,
                          progress=lambda i, last, found: seen.append((i, found)))
    assert result.servo_ids == tuple(range(1, 17))
    assert seen[252] == (252, tuple(range(1, 16))) and seen[-1] == (252, tuple(range(1, 17)))
    assert len(seen) == 254  # its last word said once more, when 16 answered at last
    assert waits_ns[16] == [10**7, 4 * 10**7, 16 * 10**7]
    # Id 0 again, longer still, since the last look found someone (a busy host).
    assert waits_ns[0] == [10**7, 4 * 10**7, 16 * 10**7, 64 * 10**7]
    # 17, beside 16 once it answered, looked at then; 200, never beside those that answered.
    assert waits_ns[17] == [10**7, 64 * 10**7] and waits_ns[200] == [10**7]


def test_a_full_sweep_looks_longer_still_while_looking_again_finds_someone():
    # Six of sixteen lost in the first pass, five of those again, four the time after: too many
    # to be an array's ends, but each look finds someone, so the host is busy, not they absent.
    bus = bare_bus("ids=1-16")
    lost = {i: 1 for i in range(2, 8)} | {i: 2 for i in range(3, 8)} \
        | {i: 3 for i in range(4, 8)}
    ping_within = bus.ping_within

    def losing(servo_id, timeout_ns):
        if lost.get(servo_id):
            lost[servo_id] -= 1
            return None
        return ping_within(servo_id, timeout_ns)

    bus.ping_within = losing
    assert scan.scan(bus, timeout_ns=10**7).servo_ids == tuple(range(1, 17))


def test_servos_lost_at_the_end_of_an_array_are_found_as_those_beside_them_answer():
    # 15 and 16 lost in the first pass: 15 is beside 14, and once it answers, 16 beside it.
    bus = bare_bus("ids=1-16")
    lost = {15: 1, 16: 1}
    ping_within = bus.ping_within

    def losing(servo_id, timeout_ns):
        if lost.get(servo_id):
            lost[servo_id] -= 1
            return None
        return ping_within(servo_id, timeout_ns)

    bus.ping_within = losing
    assert scan.scan(bus, timeout_ns=10**7).servo_ids == tuple(range(1, 17))


def test_a_sparse_full_sweep_looks_once_at_the_gaps_where_nobody_answers():
    bus = bare_bus("ids=3,9,40")
    waits_ns = {}
    ping_within = bus.ping_within

    def counted(servo_id, timeout_ns):
        waits_ns.setdefault(servo_id, []).append(timeout_ns)
        return ping_within(servo_id, timeout_ns)

    bus.ping_within = counted
    assert scan.scan(bus, timeout_ns=10**7).servo_ids == (3, 9, 40)
    assert waits_ns[2] == waits_ns[20] == waits_ns[41] == [10**7, 4 * 10**7]
    assert waits_ns[42] == [10**7]


# Fourteen servos spread over the ids, not an array's run: their gaps are most of 0-252.
SPARSE_IDS = "3,9,20,40,55,70,90,110,130,150,170,190,210,240"


def counting_waits(bus) -> list[tuple[int, int]]:
    """(servo id, wait in ns) of every PING of one id the bus is asked for, in order."""
    pings = []
    ping_within = bus.ping_within

    def counted(servo_id, timeout_ns):
        pings.append((servo_id, timeout_ns))
        return ping_within(servo_id, timeout_ns)

    bus.ping_within = counted
    return pings


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_looking_again_under_heavy_loss_waits_at_most_twice_as_long_as_the_sweep(seed):
    # 60 % of the instructions lost: every look again finds someone, so on main it went on,
    # 4, 16 and 64 times longer, over every silent id among those found (98 s on a pty).
    bus = bare_bus(f"ids={SPARSE_IDS}&drop=0.6&seed={seed}")
    pings = counting_waits(bus)
    result = scan.scan(bus, timeout_ns=10**7)
    sweep, again = pings[:253], pings[253:]
    assert [i for i, _ in sweep] == list(range(253)) and {w for _, w in sweep} == {10**7}
    assert again, "nobody looked at again"
    assert sum(w for _, w in again) <= 2 * 253 * 10**7
    assert 0 < len(result.servo_ids) <= 14


def test_a_lone_servo_the_sweep_missed_is_looked_for_again_when_the_broadcast_heard_someone():
    # Its answer to the broadcast ping garbled (a loose contact), its PING in the sweep lost:
    # nobody answered the sweep, yet someone answered the broadcast, so every id is looked at
    # again (on main none was: nobody had answered beside it).
    bus = bare_bus("ids=200")
    bus.sim.corrupt_next = 1
    pings = counting_waits(bus)
    ping_within = bus.ping_within
    lost = {200: 1}

    def losing(servo_id, timeout_ns):
        if lost.get(servo_id):
            lost[servo_id] -= 1
            ping_within(servo_id, timeout_ns)  # asked, the answer lost
            return None
        return ping_within(servo_id, timeout_ns)

    bus.ping_within = losing
    result = scan.scan(bus, timeout_ns=10**7)
    assert result.method is scan.ScanMethod.SWEEP and result.servo_ids == (200,)
    assert [i for i, _ in pings[253:506]] == list(range(253))  # every id, in turn
    assert sum(w for _, w in pings[253:]) <= 2 * 253 * 10**7
    # A bus where the broadcast ping heard nothing either is swept once: nobody is there.
    bus = bare_bus("ids=200&missing=200")
    pings = counting_waits(bus)
    assert scan.scan(bus, timeout_ns=10**7).servo_ids == () and len(pings) == 253


def test_servos_that_answer_no_ping_are_told_apart_from_those_connected():
    bus = bare_bus("ids=1-3,6&missing=2")
    assert bringup.silent_ids(bus, range(1, 8)) == (2, 4, 5, 7)


def test_a_sweep_waits_a_bounded_time_per_silent_id():
    bus = bare_bus("ids=1&missing=1")  # nothing answers: every id costs its whole wait
    # An adapter whose latency nobody knows: a single exchange would wait 34 ms, as the SDK does.
    bus.link.latency = Latency(timer_ms=None)
    bus.broadcast_ping()
    start_ns = bus.clock.now_ns()
    result = scan.scan(bus, ids=range(253), timeout_ns=3_000_000)
    spent_ns = bus.clock.now_ns() - start_ns
    assert result.found == ()
    assert 253 * 3_000_000 <= spent_ns <= 253 * 3_100_000


def test_a_silent_bus_is_swept_after_a_broadcast_ping_nobody_answers():
    result = scan.scan(bare_bus("ids=1&missing=1"))
    assert result.found == () and result.sweep_reason == "nothing answered a broadcast ping"
    assert result.swept_ids == tuple(range(253))


def test_given_ids_are_swept_without_a_broadcast():
    bus = bare_bus("ids=1-3")
    result = scan.scan(bus, ids=(2, 3, 4))
    assert result.method is scan.ScanMethod.SWEEP and result.sweep_reason == ""
    assert result.servo_ids == (2, 3) and result.swept_ids == (2, 3, 4)


def test_a_stop_requested_during_a_sweep_ends_it():
    bus = bare_bus("ids=1-2")
    stop = StopRequest()

    def progress(servo_id, last_id, found):
        if servo_id == 10:
            stop.request("stopped by SIGINT", 2)
        stop.raise_if_requested()

    with pytest.raises(Stopped):
        scan.scan(bus, progress=progress)



def test_a_stop_requested_while_looking_again_at_silent_ids_ends_the_scan_at_the_next_ping():
    # Ids 0 and 252 collide on a broadcast, so every id is swept; then every id between them
    # is looked at again, longer: nobody answers, so no progress is said (attack: Ctrl-C was
    # ignored for a whole look, and when nobody answered, swallowed: the scan ended with 0).
    bus = bare_bus("ids=0,252")
    stop = StopRequest()
    pinged_after_stop = []
    ping_within = bus.ping_within

    def counted(servo_id, timeout_ns):
        if stop.requested:
            pinged_after_stop.append(servo_id)
        return ping_within(servo_id, timeout_ns)

    looks = []

    def still_wanted():
        looks.append(1)
        if len(looks) == 5:
            stop.request("stopped by SIGINT", 2)
        stop.raise_if_requested()

    bus.ping_within = counted
    with pytest.raises(Stopped):
        scan.scan(bus, progress=lambda *found: stop.raise_if_requested(),
                     still_wanted=still_wanted)
    assert len(looks) == 5 and pinged_after_stop == []

# -- set-id ------------------------------------------------------------------------------------


def test_a_fresh_servo_is_renumbered_for_good_and_no_longer_answers_at_1():
    bus = bare_bus("ids=1")
    done = bringup.set_id(bus, 1, 7)
    assert done == bringup.Renumbered(1, 7, 777, acknowledged=True)
    assert bus.ping(7) == 777 and bus.ping(1) is None
    servo = bus.sim.servos[7]
    assert servo.get(Register.ID) == 7 and servo.get(Register.LOCK) == 1
    assert [register for register, _ in servo.eeprom_writes] == [Register.ID]
    bus.sim.power_cycle()
    assert answering(bus) == [7]


def test_set_id_refuses_an_id_another_servo_answers_at_and_writes_nothing():
    bus = bare_bus("ids=1,5")
    with pytest.raises(BusError, match="servo id 5 is already taken.*servo 1 the same id"):
        bringup.set_id(bus, 1, 5)
    assert all(s.eeprom_writes == [] for s in bus.sim.all_servos())
    assert answering(bus) == [1, 5]


def test_set_id_names_the_id_nothing_answers_at():
    bus = bare_bus("ids=1")
    with pytest.raises(BusError, match="no servo answers at id 4 on sim://"):
        bringup.set_id(bus, 4, 9)


def test_two_new_servos_on_id_1_are_told_to_be_connected_one_at_a_time():
    bus = bare_bus("ids=1")
    second = bus.sim.plug_in()  # a second factory-fresh servo, also at id 1
    # Its horn sits elsewhere (the PING answers of the two are the same bytes; positions not).
    second.write(Register.GOAL_POSITION.address, to_bytes(1000, 2), bus.clock.now_ns())
    bus.clock.sleep_until_ns(bus.clock.now_ns() + 1_000_000_000)
    with pytest.raises(BusError, match="several servos share id 1.*connect one new servo at a"):
        bringup.set_id(bus, 1, 2)
    assert all(s.eeprom_writes == [] for s in bus.sim.all_servos())


def test_set_id_refuses_a_servo_that_acknowledges_no_writes():
    bus = bare_bus("ids=1")
    bus.sim.servos[1].table[Register.STATUS_RETURN_LEVEL.address] = 0
    with pytest.raises(BusError, match=r"STATUS_RETURN_LEVEL \(address 8\) is 0"):
        bringup.set_id(bus, 1, 2)


@pytest.mark.parametrize("old, new", [(1, 253), (-1, 2), (1, 1)])
def test_set_id_refuses_ids_no_servo_can_have(old, new):
    with pytest.raises(PinArrayError):
        bringup.set_id(bare_bus("ids=1"), old, new)


def test_the_driver_writes_eeprom_only_through_its_eeprom_methods():
    bus = bare_bus("ids=1")
    with pytest.raises(BusError, match="refusing to write ID"):
        bus.write(1, Register.ID, 3)
    with pytest.raises(BusError, match="TORQUE_ENABLE .* is a RAM register"):
        bus.write_eeprom(1, Register.TORQUE_ENABLE, 0)
    assert bus.sim.servos[1].eeprom_writes == []


# -- return delay ------------------------------------------------------------------------------


def test_a_lowered_return_delay_answers_at_once_and_is_gone_after_power_off():
    bus = bare_bus("ids=1-2")  # factory servos power on with LOCK 0: a plain write would stay
    changes, failures = bringup.set_return_delay(bus, (1, 2), 0, save=False)
    assert failures == ()
    assert changes == (bringup.ReturnDelayChange(1, 500, 0, False),
                       bringup.ReturnDelayChange(2, 500, 0, False))
    assert all(s.return_delay_ns == 0 for s in bus.sim.servos.values())
    assert bus.link.return_delay_ns[1] == 0
    bus.sim.power_cycle()
    assert all(s.return_delay_ns == 500_000 for s in bus.sim.servos.values())


def test_a_saved_return_delay_survives_power_off_and_leaves_the_eeprom_locked():
    bus = bare_bus("ids=1")
    changes, _ = bringup.set_return_delay(bus, (1,), 20, save=True)
    assert changes == (bringup.ReturnDelayChange(1, 500, 20, True),)
    assert bus.sim.servos[1].get(Register.LOCK) == 1
    bus.sim.power_cycle()
    assert bus.sim.servos[1].return_delay_ns == 20_000


def test_a_silent_servo_does_not_keep_the_others_from_their_new_return_delay():
    bus = bare_bus("ids=1-3&missing=2")
    changes, failures = bringup.set_return_delay(bus, (1, 2, 3), 0, save=False)
    assert [c.servo_id for c in changes] == [1, 3]
    (failure,) = failures
    assert failure.servo_id == 2 and "RETURN_DELAY_TIME (address 7)" in failure.problem


def after_the_lock(bus, fault) -> None:
    """``fault(sim)`` acts on the simulated bus right after the LOCK write, before the
    RETURN_DELAY_TIME write that follows it."""
    lock = bus.lock_eeprom

    def lock_then_fault(servo_id: int) -> None:
        lock(servo_id)
        fault(bus.sim)

    bus.lock_eeprom = lock_then_fault


def hold_up_one_answer(sim) -> None:
    sim.late_next, sim.late_ns = 1, 200_000_000


def lose_one_instruction(sim) -> None:
    sim.drop_next = 1


@pytest.mark.parametrize("fault", [hold_up_one_answer, lose_one_instruction],
                         ids=["taken, acknowledgement held up", "lost on the wire"])
def test_a_return_delay_write_whose_acknowledgement_is_missed_is_read_back_and_written_again(
        fault):
    # A busy host can miss the acknowledgement of a write the servo took, or the write can be
    # lost: the read-back tells which, and the servo ends with its new delay either way.
    bus = bare_bus("ids=1")
    after_the_lock(bus, fault)
    changes, failures = bringup.set_return_delay(bus, (1,), 0, save=False)
    assert (changes, failures) == ((bringup.ReturnDelayChange(1, 500, 0, False),), ())
    assert bus.sim.servos[1].return_delay_ns == 0


@pytest.mark.parametrize("delay_us", [-2, 3, 510])
def test_a_return_delay_the_register_cannot_hold_is_refused(delay_us):
    with pytest.raises(PinArrayError, match="RETURN_DELAY_TIME, address 7"):
        bringup.set_return_delay(bare_bus(), (1,), delay_us, save=False)


# -- torque off, rest --------------------------------------------------------------------------


def test_torque_off_names_the_servos_that_did_not_answer():
    bus = bare_bus("ids=1-4&missing=3")
    for servo in bus.sim.servos.values():
        servo.write(Register.TORQUE_ENABLE.address, b"\x01", bus.clock.now_ns())
    released, failures = bringup.torque_off(bus, (1, 2, 3, 4))
    assert released == (1, 2, 4) and [f.servo_id for f in failures] == [3]
    assert not any(s.torque_enabled for i, s in bus.sim.servos.items() if i != 3)


def test_rest_sends_every_answering_pin_to_rest_then_releases_it():
    bus = bare_bus("ids=1-3&missing=2&backlash_deg=0")
    for servo in bus.sim.servos.values():
        servo.write(Register.GOAL_POSITION.address, to_bytes(2300, 2), bus.clock.now_ns())
    bus.clock.sleep_until_ns(bus.clock.now_ns() + 1_000_000_000)
    setup = BusSetup(tuple(ServoSetup(i, i, 2000, 1900, 2400) for i in (1, 2, 3)),
                     speed_steps_per_s=1000)
    safe = bringup.rest(bus, setup)
    assert (safe.at_rest_ids, safe.released_ids, safe.silent_ids) == ((1, 3), (1, 3), (2,))
    for servo_id in (1, 3):
        servo = bus.sim.servos[servo_id]
        assert not servo.torque_enabled and abs(servo.position_steps - 2000) <= 4
        assert servo.get(Register.GOAL_SPEED) == 1000


# -- jogging -----------------------------------------------------------------------------------


def jog_bus(query: str = "ids=6&backlash_deg=0"):
    bus = bare_bus(query)
    jog = jog_module.Jog(bus, ServoSetup(6, 6, 2048, 2000, 2200), 777, speed_steps_per_s=3000)
    return bus, jog


def test_jogging_holds_the_horn_where_it_is_then_moves_it_by_steps():
    bus, jog = jog_bus()
    servo = bus.sim.servos[6]
    servo.write(Register.GOAL_POSITION.address, to_bytes(2100, 2), bus.clock.now_ns())
    bus.clock.sleep_until_ns(bus.clock.now_ns() + 1_000_000_000)
    servo.write(Register.TORQUE_ENABLE.address, b"\x00", bus.clock.now_ns())  # limp at 2100
    start = jog.start()
    assert (start.goal_steps, start.present_steps, start.arrived) == (2100, 2100, True)
    assert servo.torque_enabled and servo.get(Register.GOAL_SPEED) == jog_module.JOG_SPEED_STEPS_PER_S
    assert jog.move_by(-30).present_steps == 2070
    reading = jog.move_to(2150)
    assert (reading.goal_steps, reading.present_steps, reading.arrived) == (2150, 2150, True)


def test_jogging_stays_within_the_servos_angle_limits():
    bus, jog = jog_bus()
    address = Register.MAX_ANGLE_LIMIT.address
    bus.sim.servos[6].table[address:address + 2] = to_bytes(3000, 2)
    jog.start()
    assert jog.bounds == (0, 3000)
    with pytest.raises(BusError, match=r"pin 6 \(servo 6\): GOAL_POSITION 3001 steps is outside "
                                       r"the servo's angle limits 0..3000 \(MIN/MAX_ANGLE_LIMIT"):
        jog.move_to(3001)


def test_a_jog_wait_ends_on_a_stop_request():
    bus, _ = jog_bus()
    stop = StopRequest()
    jog = jog_module.Jog(bus, ServoSetup(6, 6, 2048, 2000, 2200), 777, 100,
                      clock=StoppableClock(bus.clock, stop))
    jog.start()
    stop.request("stopped by SIGINT", 2)
    with pytest.raises(Stopped):
        jog.move_to(3000)  # 10 s at 100 steps/s


def test_releasing_a_jogged_pin_puts_it_at_rest_with_torque_off():
    bus, jog = jog_bus()
    jog.start()
    jog.move_to(2190)
    safe = jog.release(2040)
    servo = bus.sim.servos[6]
    assert safe.complete and not servo.torque_enabled and abs(servo.position_steps - 2040) <= 4


def test_a_jog_of_a_servo_that_is_not_there_names_the_pin_and_servo():
    bus, jog = jog_bus("ids=5")
    with pytest.raises(BusError, match=r"pin 6 \(servo 6\) does not answer on sim://"):
        jog.start()


def test_a_servo_whose_answer_a_busy_host_held_up_is_still_found_among_an_arrays_ids():
    # Every answer comes 20 ms late (past the sweep's 10 ms wait): a look again, four times
    # longer, at the ids that were silent finds them.
    bus = bare_bus("ids=1-3&late=1&late_ms=20")
    result = scan.scan(bus, ids=(1, 2, 3, 4), timeout_ns=10_000_000)
    assert result.servo_ids == (1, 2, 3)
