"""Stimuli built in code: a square, a sweep of frames and a travelling wave, no YAML written.

    python examples/stimuli_in_code.py                          # the simulated array
    python examples/stimuli_in_code.py --port /dev/ttyUSB0 --protocol protocols/localisation.yaml

Each stimulus is checked on the open array before anything moves (its pins on the array's
grid, each pin's stroke and the servos' speed, the servo bus), presented, and written as one
row of ``--log`` (a CSV): what was presented, in full, whether it was delivered, and the
strokes measured. A stimulus the servo bus cannot carry is refused first, to show how.
Real servos need the protocol that calibrates them (``--protocol``); without one, the
simulated array plays with pinarray's default device. tests/test_stimuli_in_code_example.py
runs it on the simulator and through a serial port.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections.abc import Sequence
from pathlib import Path

import pinarray


def stimuli() -> list[pinarray.Presentable]:
    """What the script presents, built in code: the values a protocol's stimuli would hold."""
    tap = pinarray.Train(frequency_hz=5, duration_s=1)  # the seed's pulses: 2 ms up, 1.5 down
    short = pinarray.Train(frequency_hz=5, duration_s=0.4, duty_cycle=0.4)
    square = pinarray.Pattern(pins=[6, 7, 10, 11], train=tap)
    letter_l = pinarray.Pattern(pins="""
        # . . .
        # . . .
        # . . .
        # # # #
    """, train=short)
    bottom, top = (pinarray.Pattern(pins=[1 + 4 * row, 2 + 4 * row], train=short)
                   for row in (0, 3))
    return [
        square,
        letter_l,
        pinarray.Frames(frames=[bottom, top], soa_ms=400),
        pinarray.Wave("rightwards", row=2, train=short, soa_ms=150),
    ]


def too_much_for_the_bus() -> pinarray.Pattern:
    """Every pin at once, 80 times a second: more frames than the servo bus can write and read
    back (on most rigs the servos could not follow it either)."""
    return pinarray.Pattern(pins=list(range(1, 17)),
                            train=pinarray.Train(frequency_hz=80, duration_s=0.2,
                                                 pulses_per_cycle=2))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", help="the protocol whose device to play on (the rig's "
                                           "calibration; needed for real servos)")
    parser.add_argument("--port", help="serial device of real servos (default: simulated)")
    parser.add_argument("--log", default="stimuli_in_code.csv", help="the CSV written")
    args = parser.parse_args(argv)

    protocol = None if args.protocol is None else pinarray.load_protocol(args.protocol)
    delivered = 0
    with pinarray.open_array(protocol, port=args.port) as array, \
            Path(args.log).open("w", newline="", encoding="utf-8") as log:
        rows = csv.writer(log)
        rows.writerow(["stimulus", "delivered", "problem", "onset_ns", "strokes_steps"])
        try:
            array.present(too_much_for_the_bus())
        except pinarray.PinArrayError as refused:
            print(f"refused, nothing moved: {refused}")
        for stimulus in stimuli():
            delivery = array.present(stimulus)
            strokes = " ".join(f"{s.pin}:{s.achieved_steps}" for s in delivery.strokes)
            rows.writerow([delivery.stimulus, delivery.delivered, delivery.problem,
                           delivery.onset_ns, strokes])
            log.flush()
            delivered += delivery.delivered
            print(f"{'delivered' if delivery.delivered else 'NOT delivered'}: "
                  f"{delivery.stimulus}" + (f" ({delivery.problem})" if delivery.problem else ""))
    print(f"{delivered} of {len(stimuli())} delivered; rows in {args.log}")
    return 0 if delivered == len(stimuli()) else 1


if __name__ == "__main__":
    sys.exit(main())
