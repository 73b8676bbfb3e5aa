"""Any keys at any moment: bursts, repeats and keys while a stimulus plays never crash the run
screen, and what is on disk stays one consistent record of the run."""

import asyncio
import tempfile
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinarray.journal.manifest import RunStatus, read_manifest
from pinarray.journal.records import TrialStatus
from pinarray.journal.rows import read_trials
from pinarray.tui.outcome import Crashed
from tests.tui.conftest import SIZE, make_app, settle, to_run_screen, write_short_localisation

# The run screen's keys (begin/present, pause/resume, redo, retry, abort and the dialog's
# answers), answer keys, and keys that mean nothing there. q ends every sequence.
KEYS = ["space", "p", "d", "t", "a", "y", "n", "escape", "0", "1", "5", "9", "enter",
        "backspace", "x", "tab"]

# A burst: keys pressed with no pause between them (they land while a stimulus is presented);
# between bursts the app settles (the participant answers, the experimenter looks up).
# Three sessions of 8 to 24 bursts rather than eight of 1 to 8: as many bursts and keys in all
# (about 41 and 122 on average over Hypothesis's draws, against 34 and 115; measured), each
# session going further into its run, at three app starts of eight (an app start is most of a
# short session's cost).
bursts = st.lists(st.lists(st.sampled_from(KEYS), min_size=1, max_size=6), min_size=8,
                  max_size=24)


async def play(results: Path, sequence: list[list[str]]):
    app = make_app(results, protocol=write_short_localisation(results.parent))
    async with app.run_test(size=SIZE) as pilot:
        await to_run_screen(pilot)
        for burst in sequence:
            await pilot.press(*burst)
            await settle(pilot)
        await pilot.press("q", "y")  # mid-run, q asks first
        await settle(pilot)
    return app


@pytest.mark.long
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sequence=bursts)
def test_random_key_bursts_never_crash_the_run_screen_nor_garble_the_results(sequence):
    with tempfile.TemporaryDirectory() as folder:
        results = Path(folder) / "results"
        app = asyncio.run(play(results, sequence))

        assert not isinstance(app.ending, Crashed), app.ending
        status, line = app.outcome()
        assert status in (0, 4) and "\n" not in line
        (manifest_path,) = results.rglob("*_manifest.json")  # the run opened at Begin run
        manifest = read_manifest(manifest_path)
        assert manifest.status in (RunStatus.ABORTED, RunStatus.COMPLETED)
        (beh,) = results.rglob("*_beh.tsv")
        rows = read_trials(beh)
        planned = {(entry.trial, entry.practice) for entry in manifest.plan}
        assert all(row.key in planned for row in rows)
        # A trial is finished (ok) at most once; every other row says why it was not.
        finished = Counter(row.key for row in rows if row.status is TrialStatus.OK)
        assert all(count == 1 for count in finished.values())
        assert all(row.status in set(TrialStatus) for row in rows)
        assert all(row.status_reason for row in rows
                   if row.status in (TrialStatus.ABORTED, TrialStatus.INVALID))
