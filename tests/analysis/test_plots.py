"""The figures as a reader sees them: every label readable, none drawn over the data.

matplotlib (and the figures' modules, which import it) are imported by the tests that draw,
not as this file is collected: every test process of `make test` collects every file, and
matplotlib cost each of them 0.6 s of processor before its first test (tests/suite.py)."""

import numpy as np
import pytest

from pinarray.analysis.load import load_runs, select_runs
from pinarray.analysis.study import study
from tests.analysis.conftest import keep_figures, localisation_row, write_results


@pytest.fixture
def drawn(monkeypatch):
    """Keep each figure, by name, laid out with its caption as the real `save` lays it out
    (writing its files adds nothing to where its labels fall), to inspect."""
    return keep_figures(monkeypatch, composed=True)


def bar_labels_and_the_data_they_must_not_cover(figure):
    """Each bar's label (the text naming its subjects) and every data artist of the axes,
    each as its rendered extent in display pixels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Text

    canvas = FigureCanvasAgg(figure)  # `save` closed the figure: draw it on a canvas again
    canvas.draw()
    renderer = canvas.get_renderer()
    axes = figure.axes[0]
    labels = [t for t in figure.findobj(Text) if "subj." in t.get_text() and t.get_visible()]
    data = [*axes.lines, *axes.collections, *axes.patches]  # subject lines and dots,
    if axes.get_legend():                                      # error bars, chance, bars
        data.append(axes.get_legend())
    return ([(t.get_text(), t.get_window_extent(renderer)) for t in labels],
            [(a, extent(a, axes, renderer)) for a in data])


def extent(artist, axes, renderer):
    """Where ``artist`` draws, in display pixels, its line width and marker size included."""
    from matplotlib.collections import Collection, PathCollection
    from matplotlib.lines import Line2D

    points = axes.figure.dpi / 72  # pixels per point
    if isinstance(artist, Collection):
        # A collection's window extent is empty when its offsets are in data coordinates:
        # take its data limits through the data transform instead.
        box = artist.get_datalim(axes.transData).transformed(axes.transData)
        sizes = artist.get_sizes() if isinstance(artist, PathCollection) else [0]
        reach = max(max(np.sqrt(sizes)) / 2, max(artist.get_linewidths()) / 2)
        return box.padded(reach * points)
    if isinstance(artist, Line2D):
        return artist.get_window_extent(renderer).padded(artist.get_linewidth() / 2 * points)
    return artist.get_window_extent(renderer)


def assert_labels_clear(figure, bars):
    labels, data = bar_labels_and_the_data_they_must_not_cover(figure)
    assert len(labels) == bars
    for text, box in labels:
        assert [a for a, extent in data if box.overlaps(extent)] == [], text
    for i, (text, box) in enumerate(labels):
        assert [other for other, b in labels[i + 1:] if box.overlaps(b)] == [], text


def test_bar_labels_cover_no_subject_line_dot_error_bar_or_bar(tmp_path, drawn):
    from pinarray.paradigms.localisation.figures import plot_correct_by_frequency

    # Subject B's line falls from 50 % at 3 Hz to 0 % at 10 Hz, across where a label on
    # the bar stood.
    result = study(select_runs(load_runs([write_results(tmp_path / "results")])))
    plot_correct_by_frequency(result.of("localisation"), tmp_path / "correct")
    result.of("apparent_motion").figures(tmp_path)
    assert_labels_clear(drawn["correct"], bars=2)
    assert_labels_clear(drawn["motion"], bars=3)


def test_six_frequencies_keep_their_labels_apart_and_off_the_data(tmp_path, write_run,
                                                                   drawn):
    from pinarray.paradigms.localisation.figures import plot_correct_by_frequency

    root = tmp_path / "results"
    frequencies = (2.0, 3.0, 5.0, 10.0, 20.0, 40.0)
    for n, subject in enumerate(("A", "B", "C")):
        # Each subject zig-zags between 0 and 100 % so lines cross every bar low and high.
        rows = [localisation_row(trial, 4, "4" if (trial + n) % 2 else "none", frequency_hz=f)
                for trial, f in enumerate(frequencies, start=1)]
        write_run(root, subject, "localisation", rows)
    result = study(select_runs(load_runs([root])))
    plot_correct_by_frequency(result.of("localisation"), tmp_path / "correct")
    assert_labels_clear(drawn["correct"], bars=6)
