"""A hand-built results set whose every number is worked out by hand in the tests."""

from collections.abc import Callable

import pytest

from pinarray.paradigms.apparent_motion.rows import MotionRecord
from pinarray.paradigms.localisation.rows import LocalisationRecord
from tests.runs import plan_of, start_run

S = 1_000_000_000  # ns per s
# (subject, frequency_hz, stimulated pin, response, status, practice)
LOCALISATION = [
    ("A", 3.0, 10, "10", "ok", False),    # correct
    ("A", 3.0, 10, "9", "ok", False),     # A: left neighbour on the same row
    ("A", 3.0, 10, "5", "ok", False),     # B: diagonal neighbour
    ("A", 3.0, 10, "none", "ok", False),  # nothing felt
    ("A", 10.0, 4, "4", "ok", False),     # correct
    ("A", 10.0, 4, "4", "ok", False),     # correct
    ("A", 10.0, 4, "8", "ok", False),     # A: the pin above
    ("A", 10.0, 10, "16", "ok", False),   # D
    ("A", 10.0, 1, "1", "ok", True),      # practice: not counted
    ("A", 10.0, 1, "2", "redone", False),  # redone: not counted
    ("B", 3.0, 1, "3", "ok", False),      # C: same row, two along
    ("B", 3.0, 1, "1", "ok", False),      # correct
    ("B", 10.0, 4, "3", "ok", False),     # A
]
# (subject, wave direction, response)
MOTION = [
    ("A", "left", "left"), ("A", "left", "right"), ("A", "right", "none"),
    ("A", "right", "unsure"), ("A", "none", "none"), ("A", "none", "left"),
    ("B", "left", "left"), ("B", "right", "right"),
]


def _write(root, subject, task, records, status="completed"):
    # The plan holds the trials the rows finish: a completed run finished every planned trial.
    writer = start_run(root, subject, task, plan_of([r for r in records if r.status == "ok"]))
    for record in records:
        writer.write_trial(record)
    writer.finish(status)
    return writer.paths


def localisation_row(trial, pin, response, frequency_hz=10.0, **fields):
    """A main localisation trial row, status ok unless ``fields`` say otherwise."""
    return LocalisationRecord(trial=trial, block=1, task="localisation", onset_ns=12 * S * trial,
                              duration_ns=10 * S, response=response, pin=pin,
                              frequency_hz=frequency_hz, **fields)


@pytest.fixture
def write_run():
    """Write one run: ``write_run(root, subject, task, records, status="completed")``."""
    return _write


@pytest.fixture
def results_root(tmp_path):
    return write_results(tmp_path / "results")


def write_results(root):
    """Two subjects' localisation and motion runs, the numbers the tests count by hand."""
    for subject in ("A", "B"):
        localisation = [
            LocalisationRecord(trial=n, block=1, task="localisation", onset_ns=12 * S * n,
                               duration_ns=10 * S, status=status, response=response, pin=pin,
                               frequency_hz=frequency, practice=practice)
            for n, (_, frequency, pin, response, status, practice) in enumerate(
                (row for row in LOCALISATION if row[0] == subject), start=1)
        ]
        motion = [
            MotionRecord(trial=n, block=1, task="motion", onset_ns=4 * S * n, duration_ns=3 * S,
                         response=response, row=1, direction=direction)
            for n, (_, direction, response) in enumerate(
                (row for row in MOTION if row[0] == subject), start=1)
        ]
        _write(root, subject, "localisation", localisation)
        _write(root, subject, "motion", motion)
    return root


def keep_figures(monkeypatch, draw: bool | Callable[[str], bool] = False,
                 composed: bool = False) -> dict:
    """Keep each figure analyse draws, by name, to inspect: every module that saves one saves
    it through `pinarray.analysis.figures.save`, which this replaces wherever it was imported
    and calls as well, when ``draw`` (or ``draw(name)``). A figure not drawn is not written
    (most of analyse's time) but, when ``composed``, laid out with its caption as `save` lays
    it out; the files it would have been written to are handed back as written, so that the
    page names and captions it as analyse's does."""
    from pinarray.analysis import figures as drawing
    from pinarray.analysis import plots
    from pinarray.paradigms.identification import figures as identification
    from pinarray.paradigms.localisation import figures as localisation

    figures: dict = {}
    save = drawing.save

    def keep(figure, stem, caption):
        figures[stem.name] = figure
        if draw is True or (callable(draw) and draw(stem.name)):
            return save(figure, stem, caption)
        if composed:
            drawing.compose(figure, caption)
        drawing.plt.close(figure)
        return [stem.with_suffix(f".{ext}") for ext in drawing.FORMATS]

    for module in (drawing, plots, identification, localisation):
        monkeypatch.setattr(module, "save", keep)
    return figures
