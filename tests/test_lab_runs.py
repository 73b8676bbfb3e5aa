"""The lab's paradigms run as a lab runs them: batch with a simulated observer or an answer
sheet, every row on disk with its pattern, interval order or SOA (described in the sidecar),
resumed exactly, and read back beside older results."""

import json

import pytest

from pinarray.analysis.load import load_run
from pinarray.api.sessions import run_session, simulated_observer
from pinarray.cli import main
from pinarray.journal.records import LEGACY_LAYOUT
from pinarray.journal.rows import read_trials
from pinarray.paradigms.identification.rows import IdentificationRecord
from pinarray.paradigms.temporal_order.rows import TemporalOrderRecord
from pinarray.paradigms.two_interval.design import IntervalOrder
from pinarray.paradigms.two_interval.rows import TwoIntervalRecord
from pinarray.protocol.load import load_protocol
from tests.lab_protocols import short_copy

RECORD = {"shapes": IdentificationRecord, "flutter_2ifc": TwoIntervalRecord,
          "toj": TemporalOrderRecord}


def beh(results, task):
    (path,) = results.glob(f"sub-*/ses-1/beh/*task-{task}_run-1_beh.tsv")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Each ready protocol (shortened) run once by batch with the simulated observer."""
    folder = tmp_path_factory.mktemp("lab")
    results = folder / "results"
    files = [str(short_copy(name, folder)) for name in RECORD]
    assert main(["batch", *files, "--subject", "01", "--observer", "default", "--seed", "3",
                 "--results", str(results)]) == 0
    return results


@pytest.mark.parametrize(("name", "task"), [("shapes", "shapes"),
                                            ("flutter_2ifc", "flutter2ifc"), ("toj", "toj")])
def test_batch_runs_each_ready_protocol_with_a_simulated_observer(runs, name, task):
    run = load_run(beh(runs, task))
    assert run.status == "completed" and not run.unfinished
    assert {type(r) for r in run.records} == {RECORD[name]}
    assert all(r.response is not None and r.delivery.missing == 0 for r in run.records)


def test_the_rows_keep_the_pattern_the_interval_order_and_the_soa(runs):
    shapes = read_trials(beh(runs, "shapes"))
    assert {r.pattern for r in shapes} <= {"across", "upright", "rising", "falling", "L", "T",
                                           "square"}
    flutter = read_trials(beh(runs, "flutter2ifc"))
    assert {r.interval_order for r in flutter} == set(IntervalOrder)
    assert {(r.compared, r.standard) for r in flutter} == {("frequency_hz", 10.0)}
    order = read_trials(beh(runs, "toj"))
    assert {r.soa_ns for r in order if not r.practice} == {
        ms * 1_000_000 for ms in (-120, -60, -30, -15, 15, 30, 60, 120)}
    header, row = beh(runs, "toj").read_text().splitlines()[:2]
    cells = dict(zip(header.split("\t"), row.split("\t"), strict=True))
    assert cells["pins"] == "6 7" and cells["pattern"] == "n/a" and cells["pin"] == "n/a"
    # The new columns come after every column older files hold (0.2.2's motion_samples last).
    assert LEGACY_LAYOUT.index("pattern") == LEGACY_LAYOUT.index("motion_samples") + 1


def test_the_sidecar_describes_the_new_columns_with_levels_and_units(runs):
    shapes = json.loads(beh(runs, "shapes").with_suffix(".json").read_text())
    assert shapes["pattern"]["Levels"]["L"] == "pins 1 2 3 5 9 13"
    assert shapes["response"]["Levels"]["square"] == "named pattern square"
    flutter = json.loads(beh(runs, "flutter2ifc").with_suffix(".json").read_text())
    assert set(flutter["interval_order"]["Levels"]) == {"standard_first", "comparison_first"}
    assert "which vibrated faster?" in flutter["response"]["Levels"]["first"]
    order = json.loads(beh(runs, "toj").with_suffix(".json").read_text())
    assert order["soa"]["Units"] == "s"
    assert order["response"]["Levels"] == {"6": "pin 6 (left) came first",
                                           "7": "pin 7 (right) came first"}
    assert "which came first: the left or the right one" in order["Instructions"]


def test_an_answer_sheet_may_name_the_pin_first_by_its_place(tmp_path):
    protocol = short_copy("toj", tmp_path)
    sheet = tmp_path / "answers.csv"
    sheet.write_text("trial,response\n" + "".join(
        f"{n},{'left' if n % 2 else 'Right'}\n" for n in range(1, 10)))
    assert main(["batch", str(protocol), "--subject", "02", "--responses", str(sheet),
                 "--results", str(tmp_path / "results")]) == 0
    rows = read_trials(beh(tmp_path / "results", "toj"))
    assert [r.response for r in rows] == ["6" if n % 2 else "7" for n in range(1, 10)]


def test_an_answer_sheet_with_a_wrong_answer_is_refused_before_anything_plays(tmp_path,
                                                                             capsys):
    protocol = short_copy("flutter_2ifc", tmp_path)
    sheet = tmp_path / "answers.csv"
    sheet.write_text("trial,response\n1,third\n" + "".join(f"{n},2\n" for n in range(2, 14)))
    assert main(["batch", str(protocol), "--subject", "02", "--responses", str(sheet),
                 "--results", str(tmp_path / "results")]) == 2
    assert f"{sheet}:2: trial 1: expected one of first, second, found 'third'" in (
        capsys.readouterr().err)
    assert not (tmp_path / "results").exists()


def test_a_run_stopped_half_way_resumes_with_exactly_the_trials_left(tmp_path):
    protocol = load_protocol(short_copy("toj", tmp_path))
    results = tmp_path / "results"
    answer = simulated_observer(protocol, "default", seed=4)
    asked = []

    def stopping(question):
        if len(asked) == 5:
            raise KeyboardInterrupt  # the experimenter's Ctrl-C after five answers
        asked.append(question.trial.trial)
        return answer(question)

    with pytest.raises(KeyboardInterrupt):
        run_session(protocol, stopping, subject="03", results=results, seed=8)
    first = read_trials(beh(results, "toj"))
    run = run_session(protocol, lambda q: asked.append(q.trial.trial) or answer(q),
                      subject="03", results=results, resume=True)
    assert run.status == "completed"
    assert asked == list(range(1, 10))  # each trial of the plan answered once, in plan order
    assert [r.trial for r in run.records if r.status.value == "ok"] == list(range(1, 10))
    assert run.records[:len(first)] == tuple(first)


ADAPTIVE_TOJ = """\
protocol: toj_up
stimuli:
  tap: {frequency_hz: 10, duration_s: 0.1}
design:
  paradigm: temporal_order
  stimulus: tap
  pins: [6, 10]
  adaptive:
    parameter: soa_ms
    values: {from: 10, to: 160, step: 10}
    task: order
    procedures:
      quest: {method: quest_plus, stop_after_trials: 24, threshold_prior: {mean: 60, sd: 40}}
"""


def test_an_adaptive_temporal_order_run_moves_its_soa_and_keeps_which_pin_went_first(tmp_path):
    path = tmp_path / "toj_up.yaml"
    path.write_text(ADAPTIVE_TOJ)
    protocol = load_protocol(path)
    assert protocol.design.judgement.places == ("lower", "upper")
    run = run_session(protocol, simulated_observer(protocol, "threshold=40,slope=2"),
                      subject="04", results=tmp_path / "results", seed=2)
    rows = [r for r in run.records if r.counts]
    assert len(rows) == 24 and {r.adaptive.procedure for r in rows} == {"quest"}
    assert all(abs(r.soa_ns) == r.adaptive.intensity * 1_000_000 for r in rows)
    assert {r.soa_ns > 0 for r in rows} == {True, False}  # either pin first
    assert all(r.adaptive.correct == r.correct for r in rows)


def test_results_written_before_the_lab_s_columns_still_read(tmp_path):
    older = tmp_path / "older_beh.tsv"
    cut = LEGACY_LAYOUT.index("pattern")
    row = ["1", "1", "loc", "4", "n/a", "n/a", "10", "4", "correct", "n/a", "n/a", "0", "10",
           "n/a", "ok", "false", "false"]
    older.write_text("\t".join(LEGACY_LAYOUT[:cut]) + "\n"
                     + "\t".join(row + ["n/a"] * (cut - len(row))) + "\n")
    (record,) = read_trials(older)
    assert (type(record).__name__, record.pin, record.response) == ("LocalisationRecord", 4, "4")


def test_analyse_turns_the_three_runs_into_their_tables_figures_and_summary(runs, tmp_path):
    out = tmp_path / "analysis"
    assert main(["analyse", str(runs), "--out", str(out), "--bootstrap-resamples", "100"]) == 0
    for name in ("identification.csv", "identification_confusion.csv", "two_interval.csv",
                 "temporal_order.csv", "identification_shapes.png", "two_interval_flutter2ifc.pdf",
                 "temporal_order_toj.png"):
        assert (out / name).exists(), name
    summary = (out / "summary.md").read_text()
    for said in ("## Identification", "biased upward when there are few trials per cell",
                 "## Two intervals", "Weber fraction", "## Temporal order", "PSS", "JND"):
        assert said in summary
    confusion = (out / "identification_confusion.csv").read_text().splitlines()
    assert confusion[0] == "task,presented,answered,n_trials,percent_of_presented"
    assert len(confusion) - 1 == 7 * 7  # every pattern against every answer
