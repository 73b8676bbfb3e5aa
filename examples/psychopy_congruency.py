"""Same or different? A visuo-tactile congruency task in PsychoPy, on the pin array.

Each trial flashes a square on the left or the right of the screen and, on the same flip, runs
a wave along a row of pins to the left or the right (protocols/apparent_motion.yaml); the
subject says whether they went the same way. PsychoPy's data file gets, beside the answer,
what the pins did: the tactile onset from the flip, the delivery verdict, each pin's stroke.

    python examples/psychopy_congruency.py --subject 01                  # simulated array, keyboard
    python examples/psychopy_congruency.py --subject 01 --observer       # a simulated subject too
    python examples/psychopy_congruency.py --subject 01 --port /dev/ttyUSB0

Needs ``pip install 'pinarray[psychopy]'`` and a display (``make psychopy`` runs it under a
virtual one). Keys: S same, D different, Escape quits (a wave still playing is cut, the pins
rest, torque off: so does Ctrl-C). Should the array fail (the port lost mid-run), the run ends
with one line saying why, exit status 2; the data written so far stay, the failed trial's
row marked not delivered.
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from psychopy import core, data, event, logging, plugins, visual
from psychopy.hardware.manager import DeviceManager

import pinarray

plugins.activatePlugins()  # as PsychoPy's Builder scripts begin: pinarray's device, by entry point

PROTOCOL = Path(__file__).resolve().parent.parent / "protocols" / "apparent_motion.yaml"
SIDES = ("left", "right")
WAVE_OF_SIDE = {"left": "leftwards", "right": "rightwards"}  # the protocol's stimuli
FLASH_S = 0.1
FIXATION_S = 0.5
KEYS = {"s": "same", "d": "different"}


def trial_list(repetitions: int, seed: int | None) -> list[dict[str, Any]]:
    """Every flash side with every wave direction, ``repetitions`` times, shuffled."""
    trials = [{"flash": flash, "wave": wave, "congruent": flash == wave}
              for _ in range(repetitions) for flash in SIDES for wave in SIDES]
    random.Random(seed).shuffle(trials)
    return trials


def simulated_answer(congruent: bool, rng: random.Random, correct: float = 0.9) -> str:
    """A subject who answers right ``correct`` of the time."""
    right = "same" if congruent else "different"
    return right if rng.random() < correct else ("different" if congruent else "same")


def show(win: visual.Window, stimuli: Sequence[Any], seconds: float) -> None:
    """Show ``stimuli`` from the next flip for ``seconds``: still pictures need no redrawing,
    and a wait that sleeps leaves the processor to the simulated servos, which play in this
    process (where the display has no vertical sync, as a virtual one, a loop of flips would
    spin)."""
    for stimulus in stimuli:
        stimulus.draw()
    win.flip()
    core.wait(seconds, hogCPUperiod=0)


def run(args: argparse.Namespace) -> Path:
    """The whole task; the data file written."""
    results = Path(args.results)
    results.mkdir(parents=True, exist_ok=True)
    data_file = results / f"sub-{args.subject}_congruency"
    experiment = data.ExperimentHandler(name="congruency", extraInfo={"subject": args.subject},
                                        dataFileName=str(data_file), savePickle=False)
    logging.LogFile(str(data_file) + ".log", level=logging.EXP)
    win = visual.Window(size=(800, 600), fullscr=args.fullscreen, units="height", color="grey")
    fixation = visual.TextStim(win, "+", height=0.05)
    flashes = {side: visual.Rect(win, size=0.1, pos=(-0.3 if side == "left" else 0.3, 0),
                                 fillColor="white") for side in SIDES}
    question = visual.TextStim(win, "same or different?  (S / D)", height=0.04)
    for stimulus in (fixation, question, *flashes.values()):  # draw once before timing counts
        stimulus.draw()
    win.flip()

    # --8<-- [start:run]
    device_settings = {"port": args.port} if args.port else {"sim": args.sim or "sim://"}
    tactile = DeviceManager.addDevice("pinarray", "touch", protocol=args.protocol,
                                      **device_settings)
    rng = random.Random(args.seed)
    try:
        for trial in trial_list(args.repetitions, args.seed):
            wave = pinarray.find_condition(tactile.protocol, stimulus=WAVE_OF_SIDE[trial["wave"]])
            show(win, [fixation], FIXATION_S)
            touch = tactile.armOnFlip(wave, win)  # returns at once: the next flip starts it
            show(win, [flashes[trial["flash"]], fixation], FLASH_S)  # the flash and the wave
            show(win, [question], 0)
            if args.observer:
                answer = simulated_answer(trial["congruent"], rng)
            else:
                keys = event.waitKeys(keyList=[*KEYS, "escape"])
                if "escape" in keys:
                    break
                answer = KEYS[keys[0]]
            for name, value in trial.items():
                experiment.addData(name, value)
            experiment.addData("answer", answer)
            experiment.addData("correct", answer == ("same" if trial["congruent"] else "different"))
            touch.addData(experiment)  # waits for the wave to end: onset from flip, delivery
            experiment.nextEntry()
    finally:
        DeviceManager.removeDevice("touch")  # a wave still playing cut, pins to rest, torque off
    # --8<-- [end:run]
        win.close()
        # Every row so far, however the run ended (a row whose touch failed says so).
        experiment.saveAsWideText(str(data_file) + ".csv", delim=",")
    return Path(str(data_file) + ".csv")


def summary(csv_file: Path) -> str:
    """How far the tactile onsets lay from their flips, and how many were delivered."""
    import csv

    with csv_file.open(newline="") as rows:
        trials = [row for row in csv.DictReader(rows) if row.get("touch.onset_from_flip_ms")]
    from_flip = [float(row["touch.onset_from_flip_ms"]) for row in trials]
    delivered = sum(row["touch.delivered"] == "True" for row in trials)
    if not from_flip:
        return f"no trials in {csv_file}"
    return (f"{len(trials)} trials in {csv_file}: tactile onset from its flip "
            f"{min(from_flip):+.2f} / {statistics.median(from_flip):+.2f} / "
            f"{max(from_flip):+.2f} ms (min / median / max); {delivered} delivered as scheduled")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", required=True)
    parser.add_argument("--protocol", default=str(PROTOCOL))
    parser.add_argument("--results", default="results")
    parser.add_argument("--port", help="serial device of real servos (default: simulated)")
    parser.add_argument("--sim", help="a sim:// URL, e.g. 'sim://?drop_writes=0.1&seed=3'")
    parser.add_argument("--repetitions", type=int, default=5, help="of each of the 4 pairings")
    parser.add_argument("--observer", action="store_true", help="a simulated subject answers")
    parser.add_argument("--fullscreen", action="store_true")
    parser.add_argument("--seed", type=int, default=None)
    args = parser.parse_args(argv)
    try:
        print(summary(run(args)))
    except pinarray.PinArrayError as error:  # the array failed (the port lost): one line
        print(f"psychopy_congruency: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
