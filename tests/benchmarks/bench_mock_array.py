"""The mock array a lab's tests hold: how long a 10 s stimulus takes in virtual time.

A test presents the seed's 10 s train on pin 6 at 10 Hz on `pinarray.testing`'s simulated
array (every goal change read back, the moving pin sampled, the strokes measured), beside a
bare compile of the same schedule in the same rounds; opening an array (the handshake, pins
to rest) is timed too. Printed, never asserted.
"""

from pathlib import Path

import pinarray
from pinarray.protocol.drives import trial_drives
from pinarray.schedule import compile_drives
from pinarray.testing import ArrayOpener
from tests.benchmarks._timing import SPREAD_HEADER, interleaved_seconds, ratio, spread

LOCALISATION = Path(__file__).resolve().parents[2] / "protocols" / "localisation.yaml"


def run() -> None:
    protocol = pinarray.load_protocol(LOCALISATION)
    condition = pinarray.find_condition(protocol, pin=6, frequency_hz=10)
    with ArrayOpener() as opener:
        array = opener(protocol)

        def open_and_close() -> None:
            with ArrayOpener() as another:
                another(protocol)

        times = interleaved_seconds({
            "compile the schedule (reference)":
                lambda: compile_drives(trial_drives(protocol, condition), protocol.device),
            "present it on the mock array": lambda: array.present(condition),
            "open and close the mock array": open_and_close,
        })
    reference = times["compile the schedule (reference)"]
    print("the seed's 10 s train on pin 6 at 10 Hz; ms; ratio: median / median of the reference")
    print(f"{'':<36} {SPREAD_HEADER} {'ratio':>7}")
    for name, seconds in times.items():
        print(f"{name:<36} {spread(seconds)} {ratio(seconds, reference):>7}")
