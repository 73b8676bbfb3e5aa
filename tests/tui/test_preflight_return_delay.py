"""The pre-flight's return-delay check: what each servo waits before answering, and lowering it
(until power-off) without leaving the screen."""

from pathlib import Path

import pytest

from pinarray.clock import MonotonicClock
from pinarray.hardware.feetech.faults import parse_sim_url
from pinarray.hardware.feetech.registers import Register
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.protocol.load import load_protocol
from pinarray.session.sitting import SessionRequest, Sitting
from pinarray.tui.preflight_screen import PreflightScreen
from tests.tui.conftest import LOCALISATION, SIZE, delay_column, fill_start, make_app, settle

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = pytest.mark.realtime

def text(app, selector):
    return str(app.screen.query_one(selector).render())


async def test_the_preflight_shows_factory_delays_and_lowers_them_until_power_off(results):
    app = make_app(results)
    async with app.run_test(size=SIZE) as pilot:
        await fill_start(pilot)
        await pilot.click("#start")
        await settle(pilot)
        assert isinstance(app.screen, PreflightScreen)
        assert delay_column(app) == ["500"] * 16
        assert ("Servo(s) 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16 wait longer "
                "before answering than a read-back takes on the wire (160 µs)"
                in text(app, "#preflight-status"))

        await pilot.click("#lower-delay")
        await settle(pilot)
        assert delay_column(app) == ["0"] * 16
        status = text(app, "#preflight-status")
        assert "wait longer" not in status
        assert "(return delay 0 µs until power-off on 16 servo(s))" in status
        assert not app.screen.query_one("#begin").disabled
        sim = app.sitting.connected().bus.sim  # the same simulated servos: not connected again
        assert all(s.return_delay_ns == 0 and s.get(Register.LOCK) == 1
                   for s in sim.servos.values())
        assert all(s.torque_enabled for s in sim.servos.values())  # still ready to run
        sim.power_cycle()  # nothing was saved in EEPROM
        assert all(s.return_delay_ns == 500_000 for s in sim.servos.values())
        await pilot.press("escape")
        await settle(pilot)


def test_a_rig_with_a_player_process_is_connected_again_with_the_lowered_delays(tmp_path):
    server = PtyServer(parse_sim_url("sim://?ids=1-16")).start()
    lab = Sitting(Path(tmp_path), clock_factory=lambda port: MonotonicClock())
    request = SessionRequest(load_protocol(LOCALISATION), "01", "1", "", server.path, None,
                             1, False)
    try:
        first = lab.connect(request)
        assert first.isolated
        assert set(first.bus.link.return_delay_ns.values()) == {500_000}
        changes, failures = lab.lower_return_delay(0)
        assert failures == () and [c.after_us for c in changes] == [0] * 16
        again = lab.connected()
        assert again is not first and again.isolated
        assert set(again.bus.link.return_delay_ns.values()) == {0}  # read by its handshake
    finally:
        lab.release()
        server.stop()
    assert not any(s.torque_enabled for s in server.sim.servos.values())
