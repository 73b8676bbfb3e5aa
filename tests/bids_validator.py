"""The official BIDS validator (``bids-validator-deno``, from the dev extra), run on a dataset.

Deno, which runs it, reads nothing under /dev without every permission (``NotCapable:
Requires all access``), and `make test` keeps the tests' folders on a RAM file system where
there is one (/dev/shm, tests/suite.py): a dataset there is validated from a copy in the
system's temporary folder.
"""

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

VALIDATOR = Path(sys.executable).parent / "bids-validator-deno"


def validate(root: Path, *options: str) -> tuple[dict | None, subprocess.CompletedProcess]:
    """The validator's JSON report on the dataset at ``root`` (None if it gave none), and the
    finished process."""
    with tempfile.TemporaryDirectory(prefix="pinarray-bids-") as folder:
        if root.resolve().parts[:2] == ("/", "dev"):
            root = Path(shutil.copytree(root, Path(folder) / root.name))
        done = subprocess.run([str(VALIDATOR), "--format", "json", *options, str(root)],
                              capture_output=True, text=True, timeout=300, cwd=root.parent)
    try:
        return json.loads(done.stdout), done
    except json.JSONDecodeError:
        return None, done
