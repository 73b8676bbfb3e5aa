"""Which pin moved? The seed's localisation experiment as a lab's own script on pinarray.

    python examples/which_pin.py --subject 01                 # simulated array and subject
    python examples/which_pin.py --subject 01 --keyboard      # you answer at the keyboard
    python examples/which_pin.py --subject 01 --port /dev/ttyUSB0 --keyboard   # real servos

First every pin of the design is checked at its fastest train (does each pin make its
stroke?), then the session runs: every trial presented, answered, written to results/ as
`pinarray batch` writes it, and the share of correct answers per frequency printed at the end.
examples/test_which_pin.py tests it on the simulated array with pinarray's pytest fixture.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pinarray

PROTOCOL = Path(__file__).resolve().parent.parent / "protocols" / "localisation.yaml"


@dataclass(frozen=True)
class PinCheck:
    """One pin's stroke at the design's fastest train."""

    pin: int
    frequency_hz: float
    achieved_steps: int | None
    commanded_steps: int
    delivered: bool
    problem: str


def check_pins(array: pinarray.PinArray) -> list[PinCheck]:
    """Each pin of the design at its fastest frequency: did it make its stroke?"""
    conditions = [c for c in array.protocol.design.conditions
                  if isinstance(c, pinarray.LocalisationCondition)]
    fastest = max(c.frequency_hz for c in conditions)
    checks = []
    for condition in sorted((c for c in conditions if c.frequency_hz == fastest),
                            key=lambda c: c.pin):
        delivery = array.present(condition)
        stroke = delivery.stroke(condition.pin) if delivery.strokes else None
        checks.append(PinCheck(condition.pin, float(fastest),
                               None if stroke is None else stroke.achieved_steps,
                               0 if stroke is None else stroke.commanded_steps,
                               delivery.delivered, delivery.problem))
    return checks


def keyboard_answer(question: pinarray.Question) -> pinarray.Answer:
    """Ask the subject (at this terminal) which pin moved; an empty line: nothing felt."""
    while True:
        text = input(f"trial {question.trial.trial}: which pin moved (1-16, Enter: none)? ")
        if not text.strip():
            return "none"
        if text.strip().isdigit() and 1 <= int(text) <= 16:
            return int(text)
        print("a pin number from 1 to 16, or Enter for nothing felt")


def correct_by_frequency(runs: Sequence[pinarray.LoadedRun]) -> dict[float, float]:
    """The share of counted trials answered with the right pin, per frequency (Hz)."""
    counts: dict[float, list[int]] = defaultdict(lambda: [0, 0])
    for run in runs:
        for record in run.records:
            if isinstance(record, pinarray.LocalisationRecord) and record.counts:
                counts[record.frequency_hz][0] += record.reported_pin == record.pin
                counts[record.frequency_hz][1] += 1
    return {hz: right / total for hz, (right, total) in sorted(counts.items())}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", default=str(PROTOCOL))
    parser.add_argument("--subject", required=True)
    parser.add_argument("--results", default="results")
    parser.add_argument("--port", help="serial device of real servos (default: simulated)")
    parser.add_argument("--sim", help="a sim:// URL, e.g. 'sim://?speed=1500' for slow servos")
    parser.add_argument("--keyboard", action="store_true", help="answer at the keyboard")
    parser.add_argument("--seed", type=int, default=None)
    args = parser.parse_args(argv)

    protocol = pinarray.load_protocol(args.protocol)
    with pinarray.open_array(protocol, port=args.port, sim=args.sim) as array:
        checks = check_pins(array)
    for check in checks:
        print(f"pin {check.pin:2} at {check.frequency_hz:g} Hz: {check.achieved_steps} of "
              f"{check.commanded_steps} steps" + ("" if check.delivered else f"  {check.problem}"))
    if not all(check.delivered for check in checks):
        print("some pins do not make their stroke: no session today", file=sys.stderr)
        return 3

    answer = keyboard_answer if args.keyboard else pinarray.simulated_observer(
        protocol, seed=args.seed)
    run = pinarray.run_session(protocol, answer, subject=args.subject, results=args.results,
                               port=args.port, sim=args.sim, seed=args.seed)
    print(f"{len(run.records)} rows in {run.paths.beh_tsv} ({run.status})")
    for hz, share in correct_by_frequency([run]).items():
        print(f"{hz:g} Hz: {100 * share:.0f} % correct")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
