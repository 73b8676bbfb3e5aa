"""`make examples`' strict type check, with a canary: the examples and one deliberate type error
are checked together, from inside examples/ as a lab's checker runs, and the check passes only
when the examples are clean *and* the error is caught. (examples/tap_count/, a package of its
own, is checked by `make example-paradigm` in its own environment.)

A check that sees pinarray as `Any` passes everything: with pinarray installed in a way mypy
cannot follow (an editable install through an import hook, setuptools' default) and missing
imports ignored, ``x: int = pinarray.load_protocol("a")`` passed. The canary fails then.

    python -m tests.typing_canary
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
CANARY = 'import pinarray\n\nprotocol: int = pinarray.load_protocol("protocols/localisation.yaml")\n'
CAUGHT = ('canary.py:3: error: Incompatible types in assignment (expression has type "Protocol", '
          'variable has type "int")  [assignment]')
FIX = ("mypy saw pinarray as Any: install it so that mypy can follow it (`make` installs it "
       "with editable_mode=compat; an older .venv: rm .venv/.installed && make examples)")


def main() -> int:
    with tempfile.TemporaryDirectory() as folder:
        canary = Path(folder) / "canary.py"
        canary.write_text(CANARY)
        checked = subprocess.run(
            [sys.executable, "-m", "mypy", "--strict", "--no-incremental",
             "--hide-error-context", "--no-error-summary", "--exclude", "tap_count", ".",
             str(canary)],
            cwd=EXAMPLES, capture_output=True, text=True)
    errors = [line.replace(str(canary), "canary.py") for line in checked.stdout.splitlines()
              if ": error:" in line]
    others = [line for line in errors if not line.startswith("canary.py:")]
    if others or checked.returncode not in (0, 1):
        print(checked.stdout + checked.stderr, end="")
        return 1
    if errors != [CAUGHT]:
        print(f"typing canary: the deliberate type error was not caught: {FIX}\n"
              f"mypy said: {errors or 'nothing'}")
        return 1
    print("mypy --strict: the examples are clean, and the deliberate type error was caught")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
