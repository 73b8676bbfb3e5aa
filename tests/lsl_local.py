"""LSL kept on this machine: the configuration pinarray ships (machine scope, 127.0.0.1 only).

liblsl's default discovery multicasts and broadcasts on the network. Every test and benchmark
that opens an outlet or an inlet runs with ``LSLAPICFG`` naming
``pinarray/imaging/lsl_machine_only.cfg`` (the test suite sets it for itself and every process it
starts, in ``tests/conftest.py``), so every LSL packet goes to 127.0.0.1.
"""

import os
from pathlib import Path

import pinarray.imaging

MACHINE_ONLY = Path(pinarray.imaging.__file__).parent / "lsl_machine_only.cfg"


def keep_lsl_on_this_machine() -> Path:
    """Point ``LSLAPICFG`` at the machine-only configuration (before any pylsl call: liblsl
    reads its configuration once, at its first use in a process)."""
    os.environ["LSLAPICFG"] = str(MACHINE_ONLY)
    return MACHINE_ONLY
