"""The pre-flight's "Rest + torque off": the experimenter lets go of the array without leaving."""

from pinarray.player.rig import Rig
from pinarray.tui.preflight_screen import PreflightScreen
from pinarray.tui.run_screen import RunScreen
from tests.tui.conftest import SIZE, delay_column, make_app, settle, to_preflight


def text(app, selector):
    return str(app.screen.query_one(selector).render())


async def test_rest_and_torque_off_lets_go_of_every_pin_until_connect_again_which_shows_the_delay_lowered_before_it(
        results):
    """One pre-flight: it says which basis feasibility used; the return delay lowered, then
    the array released (pins at rest, torque off, port closed) and connected again (the delay
    still lowered: torque off and a closed port leave servos as they were until power-off,
    simulated too), then the run begins."""
    rigs = []

    def rig_factory(*args, **kwargs):
        rigs.append(Rig(*args, **kwargs))
        return rigs[-1]

    app = make_app(results, rig_factory=rig_factory)
    async with app.run_test(size=SIZE) as pilot:
        await to_preflight(pilot)
        assert isinstance(app.screen, PreflightScreen)
        assert "Which trains the pins can follow: datasheet figures (3000 steps/s, " \
               "acceleration unlimited)." in " ".join(text(app, "#preflight-status").split())
        await pilot.click("#lower-delay")
        await settle(pilot)
        assert delay_column(app) == ["0"] * 16
        await pilot.click("#release")
        await settle(pilot)
        assert text(app, "#preflight-status") == (
            "Released: 16 servo(s) at rest, 16 released, port closed. Connect again to go on.")
        assert app.sitting.rig is None
        assert app.screen.query_one("#begin").disabled and app.screen.query_one("#release").disabled
        servos = rigs[0].bus.sim.servos.values()
        assert not any(s.torque_enabled for s in servos), "a servo still holds torque"
        assert all(abs(s.position_steps - 2048) <= 4 for s in servos), "a pin not at rest"
        await pilot.click("#reconnect")
        await settle(pilot)
        assert len(rigs) == 2 and not app.screen.query_one("#begin").disabled
        assert text(app, "#preflight-status").startswith(
            "Connected to the simulated array: 16 of 16 servos answer")
        assert delay_column(app) == ["0"] * 16, "the delay lowered before the release"
        assert "wait longer" not in text(app, "#preflight-status")
        await pilot.press("b")
        await settle(pilot)
        assert isinstance(app.screen, RunScreen)
        await pilot.press("q")
        await settle(pilot)
