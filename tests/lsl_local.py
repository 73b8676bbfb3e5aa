"""LSL kept on this machine: a liblsl configuration with machine scope and 127.0.0.1 only.

liblsl's default discovery multicasts and broadcasts on the network. Every test and benchmark
that opens an outlet or an inlet runs with ``LSLAPICFG`` naming this file (the test suite sets
it for itself and every process it starts, in ``tests/conftest.py``), so every LSL packet goes
to 127.0.0.1.
"""

import os
import tempfile
from pathlib import Path

MACHINE_ONLY = """\
[ports]
IPv6 = disable
[multicast]
ResolveScope = machine
ListenAddress = 127.0.0.1
MachineAddresses = {127.0.0.1}
LinkAddresses = {}
SiteAddresses = {}
OrganizationAddresses = {}
GlobalAddresses = {}
[lab]
KnownPeers = {}
[log]
level = -3

liblsl's log keeps fatal messages only; an inlet still open when its outlet closes (the end
of a batch run) logs "Stream transmission broke off" on stderr all the same: that is the end
of a run here, not a fault.
"""


def keep_lsl_on_this_machine() -> Path:
    """Write the configuration to a fresh folder and point ``LSLAPICFG`` at it (before any
    pylsl call: liblsl reads its configuration once, at its first use in a process)."""
    path = Path(tempfile.mkdtemp(prefix="pinarray-lsl-")) / "lsl_api.cfg"
    path.write_text(MACHINE_ONLY)
    os.environ["LSLAPICFG"] = str(path)
    return path
