"""The PsychoPy plugin's tests: one window for the session (a display is needed: xvfb.py)."""

from collections.abc import Iterator
from pathlib import Path

import pytest
from psychopy import plugins, visual

REPO = Path(__file__).resolve().parents[2]
APPARENT_MOTION = REPO / "protocols" / "apparent_motion.yaml"

plugins.activatePlugins()  # as a Builder script begins


@pytest.fixture(scope="session")
def win() -> Iterator[visual.Window]:
    window = visual.Window(size=(400, 300), units="height", color="grey")
    yield window
    window.close()
