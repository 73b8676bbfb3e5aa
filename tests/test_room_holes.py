"""The holes a hostile pass found in the paradigm seam (issue 45), each tested as the pass
found it: results edited by hand or emptied, protocols that validated and could not run, a
simulated subject that overflowed, plug-ins that broke or exited, an answer pad whose keys
were not its answers."""

import re
import signal
from pathlib import Path

import pytest

from pinarray import registry
from pinarray.analysis.load import DamagedResults, load_runs
from pinarray.cli import main
from pinarray.errors import PinArrayError, ResultsError
from pinarray.grid import Grid
from pinarray.journal.physio import motion_recording_path
from pinarray.journal.rows import read_trials
from pinarray.journal.writer import RunWriter
from pinarray.paradigms.two_point.observer import TwoPointObserverModel
from pinarray.protocol.seam import DesignDefaults
from pinarray.stop import StopRequest, stop_on_signals
from tests.lab_protocols import PROTOCOLS, short_copy
from tests.test_motion_results import localisation, samples, start_paths, three_trials
from tests.test_paradigm_holes import edited, run_cut_short
from tests.test_two_point import designed, problems


@pytest.fixture(scope="module")
def cut_short(tmp_path_factory):
    """A run of each shortened protocol stopped after three answers (made once): copy it
    before editing (`copy_of`)."""
    made: dict[str, Path] = {}

    def run(name: str) -> Path:
        if name not in made:
            folder = tmp_path_factory.mktemp(name)
            run_cut_short(short_copy(name, folder), folder / "results")
            made[name] = folder
        return made[name]
    return run


def copy_of(cut_short, name: str, into: Path) -> tuple[Path, Path, Path]:
    """A fresh copy of ``name``'s cut-short run: (its protocol, its results, its beh.tsv)."""
    import shutil

    shutil.copytree(cut_short(name), into, dirs_exist_ok=True)
    (beh,) = (into / "results").rglob("*_beh.tsv")
    return into / f"{name}.yaml", into / "results", beh


def refusal(results: Path) -> str:
    with pytest.raises((DamagedResults, ResultsError)) as raised:
        load_runs([results])
    problem = raised.value
    return str(problem.damaged[0].reason) if isinstance(problem, DamagedResults) else str(problem)


# -- 0. a temporal-order file cut before its own column ---------------------------------

def test_a_temporal_order_file_without_its_soa_column_is_refused_at_its_header(
        cut_short, tmp_path):
    _, results, beh = copy_of(cut_short, "toj", tmp_path)
    beh.write_text("".join(line.rsplit("\t", 1)[0] + "\n"
                           for line in beh.read_text().splitlines()))
    said = refusal(results)
    assert said.startswith(f"{beh}:1: expected the column 'soa'"), said


# -- 1. a two-point pitch too small to tell its distances apart --------------------------

@pytest.mark.parametrize(("pitch", "said"), [
    ("0.00001", "p.yaml:11:11: expected pins at least 0.01 mm apart (the grid's pitch_mm), "
                "found pins 6 and 7 0 mm apart at a pitch of 1e-05 mm"),
    ("1e-9", "p.yaml:11:11: expected pins at least 0.01 mm apart"),
    ("0.01", "p.yaml:11:19: expected distances 0.01 mm apart or more (the grid's pitch_mm), "
             "found pins 6 and 11 0.0141 mm apart beside pins 6 and 7 0.01 mm apart"),
])
def test_a_two_point_pitch_whose_distances_rows_cannot_tell_apart_is_refused_at_validate(
        pitch, said):
    found = problems(designed("  stimulus: press\n  pairs: [[6, 7], [6, 11]]\n", pitch))
    assert found[0].startswith(said), found


# -- 2. a simulated two-point subject with a steep slope or a far threshold ---------------

@pytest.mark.parametrize(("threshold_mm", "slope"), [
    (0.01, 200), (3, 1e90), (0.0001, 1000), (1e300, 1e10), (1e-300, 50), (3, 1e-300)])
def test_a_two_point_subject_answers_for_any_legal_slope_and_threshold(threshold_mm, slope):
    model = TwoPointObserverModel(threshold_mm=threshold_mm, slope=slope, subject_sd=0)
    for distance_mm in (0.01, 2.0, 2.8284, 6.0, 1e6):
        p = model.p_two(distance_mm)
        assert model.false_alarm <= p <= 1 - model.lapse, (distance_mm, p)
    far, near = model.p_two(1e6), model.p_two(0.01)
    assert far >= near  # further apart is never felt as two less often


def test_a_batch_run_with_a_steep_two_point_subject_ends_in_its_rows(tmp_path):
    results = tmp_path / "results"
    assert main(["batch", str(short_copy("two_point", tmp_path)), "--subject", "01",
                 "--observer", "threshold_mm=0.01,slope=200", "--seed", "2",
                 "--results", str(results)]) == 0
    assert next(results.rglob("*_beh.tsv")).read_text().count("\n") > 1


# -- 3 and 4. a lab's package that cannot be loaded, or exits as it is ------------------

PLUG_INS = {
    "missing": "pinarray_no_such_module:PARADIGM",
    "exits": "room_holes_exits:PARADIGM",
    "interrupts": "room_holes_interrupts:PARADIGM",
}


@pytest.fixture
def broken_plug_ins(tmp_path, monkeypatch):
    """Installed plug-ins that cannot be loaded: one names no module, one's module raises
    SystemExit(0) as it is imported, one KeyboardInterrupt."""
    (tmp_path / "room_holes_exits.py").write_text("raise SystemExit(0)\n")
    (tmp_path / "room_holes_interrupts.py").write_text("raise KeyboardInterrupt\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_plug_ins", lambda: dict(PLUG_INS))
    registry.room.cache_clear()
    yield
    registry.room.cache_clear()


def test_results_of_pinarrays_own_paradigms_are_read_beside_a_broken_plug_in(
        broken_plug_ins, cut_short, tmp_path, monkeypatch):
    broken = {name: PLUG_INS[name] for name in ("missing", "exits")}
    monkeypatch.setattr(registry, "_plug_ins", lambda: broken)
    _, _, beh = copy_of(cut_short, "two_point", tmp_path)
    read = read_trials(beh)  # handed over alone: no manifest says whose rows they are
    assert len(read) == 4 and {r.paradigm for r in read} == {"two_point"}
    header, *rows = beh.read_text().splitlines()
    beh.write_text("\n".join([header + "\textra", *(row + "\tx" for row in rows)]) + "\n")
    with pytest.raises(ResultsError) as raised:
        read_trials(beh)  # no paradigm writes these columns: the file may be a plug-in's
    said = str(raised.value)
    assert said.startswith(f"{beh}:1: expected the columns ") and "\n" not in said
    assert all(f"paradigm {name!r}: its package" in said for name in broken)


def test_a_plug_in_that_exits_as_it_is_imported_is_said_in_one_line_exit_2(
        broken_plug_ins, tmp_path, capsys):
    protocol = (PROTOCOLS / "two_point.yaml").read_text().replace(
        "paradigm: two_point", "paradigm: exits")
    (tmp_path / "p.yaml").write_text(protocol)
    assert main(["validate", str(tmp_path / "p.yaml")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "paradigm 'exits': its package (room_holes_exits:PARADIGM" in line
    assert "SystemExit" in line


def test_a_plug_ins_keyboard_interrupt_is_its_fault_where_ctrl_c_cannot_raise_one(
        broken_plug_ins):
    # Ctrl-C at Python's own handler, as in a command that installs none (whatever a test
    # before this one in the same process left: an event loop's handler lasts until it closes).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        a_plug_ins_keyboard_interrupt()
    finally:
        signal.signal(signal.SIGINT, previous)


def a_plug_ins_keyboard_interrupt() -> None:
    # A run takes Ctrl-C through its stop request: the interrupt can only be the package's.
    with stop_on_signals(StopRequest()), pytest.raises(
            PinArrayError, match="paradigm 'interrupts': its package .* KeyboardInterrupt"):
        registry.room("interrupts")
    # Where Ctrl-C raises KeyboardInterrupt (validate, plan, analyse), it is let through: it
    # may be the person at the keyboard, and Ctrl-C must stop any command.
    with pytest.raises(KeyboardInterrupt):
        registry.room("interrupts")


# -- 5. the answer pad a paradigm need not draw -----------------------------------------

class _Counting(DesignDefaults):
    """A design whose answers are counts, as a lab's tap counting is (2 to 5), and a word."""

    name = "counting"

    def answers(self, design, pin_count):
        return ("2", "3", "4", "5", "many")


class _Asked:
    """What the default pad asks of a design: its answers."""

    def answers(self, pin_count):
        return _Counting().answers(self, pin_count)


def test_the_default_pad_gives_a_digit_answer_its_own_key():
    pad = _Counting().pad(_Asked(), Grid())  # type: ignore[arg-type]
    keys = {choice.answer: choice.keys for choice in pad.choices}
    # The subject says three, the experimenter presses 3: the row records 3.
    assert keys == {"2": ("2",), "3": ("3",), "4": ("4",), "5": ("5",), "many": ("1",)}
    assert [c.label for c in pad.choices] == ["2", "3", "4", "5", "many (1)"]


# -- 6 and 7. rows read back hold what the run presented and what the design asks -------

def test_a_two_interval_row_whose_pins_were_edited_is_refused(cut_short, tmp_path):
    _, results, beh = copy_of(cut_short, "flutter_2ifc", tmp_path)
    edited(beh, "pins", "16")
    assert refusal(results).startswith(f"{beh}:3: trial ") and \
        "the run's other trials play pins 6 7 10 11, the row says 16" in refusal(results)


def test_an_apparent_motion_answer_that_is_no_direction_of_the_run_is_refused(
        cut_short, tmp_path):
    _, results, beh = copy_of(cut_short, "apparent_motion", tmp_path)
    # The derived cells as a banana would make them: felt motion, in a wrong direction.
    for column, value in (("response", "banana"), ("perceived_motion", "true"),
                          ("direction_correct", "false")):
        edited(beh, column, value)
    said = refusal(results)
    assert said.startswith(f"{beh}:3: trial ") and "expected an answer the design offered (" \
        in said and "found 'banana'" in said, said


# -- 8. the cells every row has, read back -----------------------------------------------

@pytest.mark.parametrize(("column", "value", "said"), [
    ("goals_missing", "3", "expected status invalid for a trial with goal changes missing"),
    ("goals_confirmed", "999", "expected at most the 4 goal change(s) scheduled to be "
                               "confirmed, healed or missing, found 1002"),
    ("block", "7", "expected the plan's block 1, found 7"),
    ("stimulus_onset", "-5", "expected stimulus_onset of at least 0, found -5 s"),
    ("response_time", "-0.5", "expected response_time of at least 0, found -0.5 s"),
    ("stroke_achieved", "-40", "expected stroke_achieved of at least 0, found -40 steps"),
])
@pytest.mark.parametrize("name", ["two_point", "toj"])
def test_a_common_cell_edited_beyond_what_a_trial_can_hold_is_refused(
        cut_short, tmp_path, name, column, value, said):
    _, results, beh = copy_of(cut_short, name, tmp_path)
    header, _, second, *_ = beh.read_text().splitlines()
    cells = dict(zip(header.split("\t"), second.split("\t"), strict=True))
    if column == "goals_confirmed":  # what 999 makes with the row's other counts
        said = said.replace("1002", str(999 + int(cells["goals_healed"])
                                        + int(cells["goals_missing"])))
        said = said.replace("the 4 ", f"the {cells['goals_scheduled']} ")
    edited(beh, column, value)
    got = refusal(results)
    assert got.startswith(f"{beh}:3: ") and said in got and "\n" not in got, got


# -- 9. a resume of a run whose rows were emptied ----------------------------------------

@pytest.mark.parametrize("emptied", ["to nothing", "to its header"])
def test_a_run_whose_rows_were_emptied_is_not_presented_again_on_resume(tmp_path, emptied):
    writer = three_trials(tmp_path)
    for trial in (1, 2, 3):
        writer.write_trial(localisation(trial), samples(trial))
    writer.close()
    beh = writer.paths.beh_tsv
    beh.write_text("" if emptied == "to nothing" else beh.read_text().splitlines()[0] + "\n")
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    with pytest.raises(ResultsError) as refused:
        RunWriter.resume(start_paths(tmp_path))
    said = str(refused.value)
    assert said.startswith(f"{motion_recording_path(writer.paths)}: holds samples of trials "
                           "1, 2, 3 that no row of the run's beh.tsv claims"), said
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_rows_moved_are_said_as_moved_not_as_a_recording_that_holds_what_they_claim(tmp_path):
    writer = three_trials(tmp_path)
    for trial in (1, 2, 3):
        writer.write_trial(localisation(trial), samples(trial))
    writer.close()
    beh = writer.paths.beh_tsv
    header, one, two, three = beh.read_text().splitlines()
    beh.write_text("\n".join([header, two, one, three]) + "\n")
    with pytest.raises(ResultsError, match="holds trial 1's samples where the rows of the run's "
                                           "beh.tsv, in their order, put trial 2's: rows were "
                                           "deleted or moved"):
        RunWriter.resume(start_paths(tmp_path))


# -- 10. a grid with more pins than one bus carries -------------------------------------

@pytest.mark.parametrize(("rows", "columns"), [(16, 16), (17, 5)])
def test_a_grid_of_more_pins_than_one_bus_carries_is_refused_where_it_is_written(rows, columns):
    # 17 x 5 reached validate's rehearsal and ended in a traceback: the start-up's SYNC WRITE
    # of 85 servos' acceleration does not fit a packet (found by fuzzing validate).
    text = (PROTOCOLS / "localisation.yaml").read_text()
    assert "grid: {rows: 4, columns: 4" in text
    found = problems(text.replace("grid: {rows: 4, columns: 4",
                                  f"grid: {{rows: {rows}, columns: {columns}"))
    (line,) = [p for p in found if "servo bus" in p]
    assert re.fullmatch(r"p\.yaml:\d+:\d+: expected a grid of at most 60 pins on one servo bus "
                        r"\(one SYNC WRITE sets them all, in a packet of at most 250 bytes\), "
                        rf"found {rows * columns}", line), found


def test_the_largest_grid_a_protocol_takes_is_one_the_bus_can_start_and_move(tmp_path):
    from pinarray.hardware.feetech import packets
    from pinarray.hardware.feetech.registers import Register
    from pinarray.protocol.device import MAX_BUS_SERVOS

    def acceleration_write(servos: int) -> bytes:
        return packets.sync_write(Register.ACCELERATION.address, 3,
                                  ((i, bytes(3)) for i in range(1, servos + 1)))

    assert len(acceleration_write(MAX_BUS_SERVOS)) <= packets.MAX_PACKET_BYTES
    with pytest.raises(ValueError):
        acceleration_write(MAX_BUS_SERVOS + 1)
    # A protocol on that many pins is validated whole: its start-up and stimuli rehearsed.
    protocol = tmp_path / "sixty.yaml"
    protocol.write_text((PROTOCOLS / "localisation.yaml").read_text().replace(
        "grid: {rows: 4, columns: 4", "grid: {rows: 6, columns: 10"))
    assert main(["validate", str(protocol)]) == 0


# -- 11. small slips -----------------------------------------------------------------------

def test_an_attribute_named_twice_in_no_repeat_is_refused_where_it_is_written_again():
    found = problems(designed("  stimulus: press\n  pairs: [[6, 7]]\n"
                              "  constraints: {no_repeat: [pins, pins]}\n"))
    assert found == ["p.yaml:12:35: expected each attribute once in no_repeat, found 'pins' "
                     "again"], found
