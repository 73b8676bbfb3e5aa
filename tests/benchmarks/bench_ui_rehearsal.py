"""The UI rehearsal as a new user meets it: Begin pressed at once, then Space; how long from
Space to the answer prompt, over the stimulus's scheduled time (its stretch).

The experimenter's UI (headless, through Textual's pilot) on the simulated array at ``--speed``
1 and 20, with the pre-flight's real timing check: Begin is pressed as soon as the servos show
(the run begins when the check ends), then each trial is presented once its inter-trial
interval is over and answered at once. The reference, in the same run, is the same trials
presented by a bare `Rig` at the same speed (no UI). Target: stretch at most 1.1x.
"""

from __future__ import annotations

import asyncio
import statistics
import tempfile
import time
from pathlib import Path

from pinarray.clock import ScaledClock
from pinarray.plan import make_plan
from pinarray.player.rig import Rig
from pinarray.protocol.load import load_protocol
from pinarray.schedule import compile_trial
from tests.benchmarks._timing import SPREAD_HEADER, ratio, spread
from tests.runs import REPO

PROTOCOL = REPO / "protocols" / "localisation.yaml"
SEED = 5
TRIALS = {1.0: 3, 20.0: 6}  # trials measured at each speed (10 s stimuli at speed 1)
STRETCH_TARGET = 1.1


class Prompted:
    """When the session last asked for an answer (its ``on_change``, passed on to the UI's)."""

    def __init__(self) -> None:
        self.at_s = 0.0
        self.event = asyncio.Event()

    def watching(self, on_change, loop: asyncio.AbstractEventLoop):
        from pinarray.session.trials import Phase

        def changed(session) -> None:
            if session.phase is Phase.RESPONSE:
                self.at_s = time.monotonic()
                loop.call_soon_threadsafe(self.event.set)
            on_change(session)

        return changed


async def _ui_stretches(speed: float, trials: int) -> tuple[list[float], float, str]:
    """Each trial's Space-to-prompt over its scheduled time, Begin-to-run-screen seconds, and
    what the timing check said if Begin had to be confirmed."""
    from pinarray.session.trials import Phase
    from pinarray.tui.app import PinArrayApp, TuiOptions
    from pinarray.tui.confirm import Confirm
    from pinarray.tui.preflight_screen import PreflightScreen
    from pinarray.tui.response_pad import ResponsePad
    from pinarray.tui.run_screen import RunScreen

    protocol = load_protocol(PROTOCOL)
    interval_s = protocol.design.inter_trial_interval_ns / 1e9 / speed
    with tempfile.TemporaryDirectory() as results:
        options = TuiOptions(protocol_path=PROTOCOL, protocols_dir=PROTOCOL.parent,
                             results_root=Path(results), time_scale=speed, seed=SEED,
                             subject="bench")
        app = PinArrayApp(options, list_ports=lambda: [])
        async with app.run_test(size=(120, 40)) as pilot:

            async def until(condition, limit_s: float = 120.0) -> None:
                give_up = time.monotonic() + limit_s
                while not condition():
                    if time.monotonic() > give_up:
                        raise TimeoutError("the UI never got there")
                    await asyncio.sleep(0.002)

            await pilot.click("#start")
            await until(lambda: isinstance(app.screen, PreflightScreen) and app.screen.connected)
            begun, doubt = time.monotonic(), "OK"
            await pilot.press("b")
            await until(lambda: isinstance(app.screen, RunScreen | Confirm))
            if isinstance(app.screen, Confirm):  # a busy machine: begin although NOT OK
                doubt = "verdict not OK"
                await pilot.press("y")
                await until(lambda: isinstance(app.screen, RunScreen))
            waited_s = time.monotonic() - begun
            session = app.screen.session
            # The answer prompt's moment, taken where the session says so (polling for it
            # would itself keep the interpreter busy beside the stimulus).
            loop, prompted = asyncio.get_running_loop(), Prompted()
            # The run screen sets its own on_change when mounted (sets `clock` first): after it.
            await until(lambda: getattr(app.screen, "clock", None) is not None)
            pad = app.screen.query_one(ResponsePad)
            session.on_change = prompted.watching(session.on_change, loop)
            await pilot.press("space")  # the instructions are given
            await until(lambda: session.phase is Phase.READY)
            stretches = []
            for _ in range(trials):
                length_s = session.current_schedule().end_ns / 1e9 / speed
                prompted.event = asyncio.Event()
                pressed = time.monotonic()
                await pilot.press("space")
                await prompted.event.wait()
                stretches.append((prompted.at_s - pressed) / length_s)
                await until(lambda: pad.accepting)  # the screen has caught up with the session
                await pilot.press("1", "enter")
                await until(lambda: session.phase is Phase.READY)
                await asyncio.sleep(interval_s + 0.05)  # the inter-trial interval is over
            await pilot.press("q")
    return stretches, waited_s, doubt


def _bare_stretches(speed: float, trials: int) -> list[float]:
    protocol = load_protocol(PROTOCOL)
    plan = make_plan(protocol, SEED)
    stretches = []
    with Rig(protocol, None, None, ScaledClock(speed)) as rig:
        for planned in plan.trials[:trials]:
            schedule = compile_trial(protocol, planned)
            started = time.monotonic()
            rig.present(schedule)
            stretches.append((time.monotonic() - started) / (schedule.end_ns / 1e9 / speed))
    return stretches


def run() -> None:
    print("Space to the answer prompt over the stimulus's scheduled time, Begin pressed at once "
          f"(the pre-flight's timing check on); {PROTOCOL.name}, seed {SEED}")
    print(f"{'':<30} {'trials':>6} {SPREAD_HEADER} {'ratio':>7}  Begin to run screen")
    for speed, trials in TRIALS.items():
        ui, waited_s, said = asyncio.run(_ui_stretches(speed, trials))
        bare = _bare_stretches(speed, trials)
        met = "met" if statistics.median(ui) <= STRETCH_TARGET else "NOT met"
        print(f"{f'UI at --speed {speed:g}':<30} {len(ui):>6} {spread(ui, 1, 3)} "
              f"{ratio(ui, bare):>7}  {waited_s:.1f} s (the check: {said})")
        print(f"{f'reference: bare rig, {speed:g}x':<30} {len(bare):>6} {spread(bare, 1, 3)} "
              f"{'1.00x':>7}")
        print(f"target: stretch at most {STRETCH_TARGET:g}x (median): {met}")


if __name__ == "__main__":
    run()
