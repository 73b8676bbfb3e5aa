"""The paradigm seam, for every paradigm alike: each room implements it, the registry finds
it (a lab's by its entry point), and the promises are kept once for all: every condition is
checked against the servo bus at validate, every cell read back is checked, every estimate
carries its status, and a killed run resumes to the same trials and the same simulated
answers."""

import importlib
import math
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pinarray import plan_trials, registry
from pinarray.analysis.fits import placed
from pinarray.analysis.seam import (
    AnalysisDefaults,
    Estimate,
    EstimateStatus,
    analysis_of,
    observer_of,
)
from pinarray.api.sessions import Question, run_session, simulated_observer
from pinarray.errors import PinArrayError, ProtocolErrors
from pinarray.journal.seam import rows_of
from pinarray.paradigms.base import Paradigm, missing_faces
from pinarray.protocol.load import load_protocol, parse_protocol
from pinarray.protocol.seam import paradigm_named
from tests.lab_protocols import short_copy

# One shipped protocol of each paradigm (shortened: tests/lab_protocols.py).
SHIPPED = {"localisation": "localisation", "apparent_motion": "apparent_motion",
           "identification": "shapes", "two_interval": "flutter_2ifc", "temporal_order": "toj",
           "two_point": "two_point"}


def test_every_paradigm_is_one_room_that_implements_the_whole_seam():
    assert set(registry.names()) >= set(SHIPPED)
    for name in registry.names():
        room = registry.room(name)
        assert isinstance(room, Paradigm) and missing_faces(room) == [], name
        assert room.name == room.rows.name == room.analysis.name == name
        # ... and each layer finds it by name, checked against its own part of the seam.
        assert paradigm_named(name) is room and rows_of(name) is room.rows
        assert analysis_of(name) is room.analysis
        if name in registry.BUILT_IN:  # (a lab's own, if installed, lives in its package)
            assert type(room).__module__.startswith(f"pinarray.paradigms.{name}")


def test_each_of_pinarray_s_own_simulated_subjects_is_its_room_s_observer_module_s():
    # observer_of takes them from there without importing the rooms' analyses (a batch needs
    # none): right while none of those analyses makes its subject another way.
    for name, package in registry.BUILT_IN.items():
        assert type(analysis_of(name)).observer is AnalysisDefaults.observer, name
        assert observer_of(name) is importlib.import_module(f"{package}.observer").observer


def test_a_protocol_naming_no_paradigm_is_told_every_one_there_is():
    text = "protocol: p\nstimuli:\n  t: {frequency_hz: 5, duration_s: 1}\ndesign:\n  paradigm: tow_point\n"
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "p.yaml")
    (problem,) = raised.value.errors
    assert (problem.line, problem.col) == (5, 13)
    assert all(name in problem.message for name in registry.names())


class _NotARoom:
    name = "half"


NOT_A_ROOM = _NotARoom()


def test_a_plug_in_is_found_by_its_entry_point_and_one_that_is_no_room_is_said_in_one_line(
        monkeypatch):
    monkeypatch.setattr(registry, "_plug_ins",
                        lambda: {"half": f"{__name__}:NOT_A_ROOM", "broken": "no_such_module:X"})
    registry.room.cache_clear()
    try:
        assert registry.names()[-2:] == ("half", "broken") and registry.is_known("half")
        with pytest.raises(PinArrayError, match="paradigm 'half' does not implement the "
                                                "paradigm seam: _NotARoom lacks adapt, "):
            paradigm_named("half")
        with pytest.raises(PinArrayError, match=r"paradigm 'broken': its package "
                                                r"\(no_such_module:X, entry point group "
                                                r"pinarray.paradigms\) cannot be loaded: "
                                                r"ModuleNotFoundError"):
            registry.room("broken")
    finally:
        registry.room.cache_clear()


@pytest.fixture
def installed_plug_ins(tmp_path, monkeypatch):
    """A package installed with three paradigm entry points the registry leaves out: one
    taking a name pinarray ships, one that is no paradigm's name, one another package gives
    first (its own ``tap_count``); its entry points are read afresh."""
    for package, points in (("pinarray-first", "tap_count = first_room:PARADIGM\n"),
                            ("pinarray-clash", "two_point = clash_room:PARADIGM\n"
                                               "Bad-Name = clash_room:PARADIGM\n"
                                               "tap_count = clash_room:PARADIGM\n")):
        info = tmp_path / package / f"{package.replace('-', '_')}-0.1.dist-info"
        info.mkdir(parents=True)
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {package}\nVersion: 0.1\n")
        (info / "entry_points.txt").write_text(f"[pinarray.paradigms]\n{points}")
        monkeypatch.syspath_prepend(str(tmp_path / package))
    monkeypatch.syspath_prepend(str(tmp_path / "pinarray-first"))  # found first
    registry._entry_points.cache_clear()
    registry.room.cache_clear()
    yield
    registry._entry_points.cache_clear()
    registry.room.cache_clear()


def test_an_installed_plug_in_left_out_is_named_and_a_protocol_asking_for_it_told_why(
        installed_plug_ins, tmp_path, capsys):
    from pinarray.cli import main

    warnings = [
        "pinarray: warning: paradigm plug-in two_point from pinarray-clash ignored: pinarray "
        "ships a paradigm of that name, which a package cannot replace; rename the entry point",
        "pinarray: warning: paradigm plug-in Bad-Name from pinarray-clash ignored: expected a "
        "paradigm's name (a lowercase letter, then at most 31 lowercase letters, digits or _), "
        "found 'Bad-Name'",
        "pinarray: warning: paradigm plug-in tap_count from pinarray-clash ignored: "
        "pinarray-first gives a paradigm of that name too, and was found first"]
    text = (Path(__file__).parent.parent / "protocols" / "two_point.yaml").read_text()
    capsys.readouterr()
    for name, said in (("Bad-Name", f"expected a paradigm ({', '.join(registry.LISTED)}, "
                                    f"tap_count), found 'Bad-Name': the {warnings[1][19:]}"),
                       ("tow_point", "expected the paradigm to be one of ")):
        asking = tmp_path / f"{name}.yaml"
        asking.write_text(text.replace("paradigm: two_point", f"paradigm: {name}"))
        assert main(["validate", str(asking)]) == 2
        refusal, *rest = capsys.readouterr().err.splitlines()
        assert refusal.startswith(f"{asking}:33:13: {said}"), refusal
        assert sorted(rest) == sorted(warnings)  # each once, whatever order they were found in
    # entry points not read (a shipped paradigm's protocol: test_startup): nothing to say
    registry._entry_points.cache_clear()
    assert registry.ignored() == ()


# -- every condition checked against the bus at validate -------------------------------------

@pytest.mark.parametrize("paradigm", sorted(SHIPPED))
def test_every_paradigms_conditions_are_checked_against_the_servo_bus_at_validate(
        paradigm, tmp_path):
    # A delivery tolerance shorter than one goal's frame on the wire: no condition of any
    # paradigm can be delivered, and validate says so (where the stimulus or the design
    # writes it).
    path = short_copy(SHIPPED[paradigm], tmp_path)
    text = path.read_text()
    text = text.replace("stimuli:", "device:\n  delivery_tolerance_ms: 0.000001\n\nstimuli:", 1) \
        if "\ndevice:" not in text else text.replace(
            "\ndevice:\n", "\ndevice:\n  delivery_tolerance_ms: 0.000001\n", 1)
    with pytest.raises(ProtocolErrors) as raised:
        parse_protocol(text, "p.yaml")
    problems = raised.value.errors
    assert problems and all("the servo bus cannot deliver it" in p.message for p in problems)


# -- every estimate carries its status ------------------------------------------------------

finite = st.floats(-1e6, 1e6, allow_nan=False)


@given(value=finite, low=finite, high=finite, has_low=st.booleans(), has_high=st.booleans())
def test_an_estimate_holds_only_the_numbers_its_status_allows(value, low, high, has_low,
                                                               has_high):
    e = placed(value, low, high, has_low=has_low, has_high=has_high, words="w")
    assert e.status is (EstimateStatus.ESTIMATED if has_low and has_high else
                        EstimateStatus.BOUNDED if has_low or has_high else
                        EstimateStatus.NOT_RESOLVED)
    assert math.isnan(e.value) is (e.status is not EstimateStatus.ESTIMATED)
    assert math.isnan(e.ci_low) is (not has_low) and math.isnan(e.ci_high) is (not has_high)


@given(value=finite, low=finite)
def test_an_estimate_whose_numbers_contradict_its_status_is_refused(value, low):
    with pytest.raises(PinArrayError, match="cannot hold"):
        Estimate(value, low, math.nan, EstimateStatus.BOUNDED, "below the lowest value tested")
    with pytest.raises(PinArrayError, match="cannot hold"):
        Estimate(math.nan, low, math.nan, EstimateStatus.NOT_RESOLVED, "not estimable")
    with pytest.raises(PinArrayError, match="cannot hold"):
        Estimate(math.nan, low, low, EstimateStatus.ESTIMATED, "estimated")


# -- a killed run resumes to the same trials and the same answers ---------------------------

def _stopped_after(answer, count, asked):
    def stopping(question):
        if len(asked) == count:
            raise KeyboardInterrupt  # the run dies after ``count`` answers
        asked.append(question.trial.trial)
        return answer(question)
    return stopping


# Shorter still where a run of the short copy is long: two intervals of 4 pins each trial, 13
# trials (1.3 s of processor for the three runs, against 0.2-0.3 s for the other paradigms).
FEWER = {"two_interval": (("duration_s: 0.5\n", "duration_s: 0.2\n"),
                          ("comparisons: [7, 8, 9, 11, 12, 13]", "comparisons: [7, 13]"))}


@pytest.mark.parametrize("paradigm", sorted(SHIPPED))
def test_a_run_stopped_and_resumed_answers_as_one_that_ran_through(paradigm, tmp_path):
    protocol = load_protocol(short_copy(SHIPPED[paradigm], tmp_path, *FEWER.get(paradigm, ())))
    whole = run_session(protocol, simulated_observer(protocol, "default", seed=5),
                        subject="01", results=tmp_path / "whole", seed=8)
    asked: list[int] = []
    with pytest.raises(KeyboardInterrupt):
        run_session(protocol, _stopped_after(simulated_observer(protocol, "default", seed=5),
                                             2, asked),
                    subject="01", results=tmp_path / "cut", seed=8)
    # A new process would build its observer anew: so does this resume.
    resumed = run_session(protocol, simulated_observer(protocol, "default", seed=5),
                          subject="01", results=tmp_path / "cut", resume=True)
    ok = [r for r in resumed.records if r.status.value == "ok"]
    assert [(r.trial, r.response) for r in ok] == [(r.trial, r.response) for r in whole.records]
    assert [r.trial for r in ok if not r.resumed] == asked


def test_the_simulated_answers_depend_on_the_seed_and_the_trial_alone(tmp_path):
    protocol = load_protocol(short_copy("toj", tmp_path))
    plan = {t.trial: t for t in plan_trials(protocol, seed=3).trials}

    def asked(order):
        answer = simulated_observer(protocol, "default", seed=11)
        return {n: answer(Question(plan[n])) for n in order}

    assert asked(sorted(plan)) == asked(sorted(plan, reverse=True))


# -- a paradigm is named in its own room, and only there ------------------------------------

PACKAGE = Path(__file__).resolve().parents[1] / "pinarray"
# Where a paradigm may be named outside its room: the public face, the API module that names
# its public types, and the registry that finds it.
NAMERS = ("__init__.py", "api/paradigms.py", "registry.py")


def test_each_paradigm_is_named_in_its_own_room_and_only_the_face_the_api_and_the_registry():
    import pinarray.api.paradigms as api

    # Each file read once; the pattern searched only in a file that holds one of its words as
    # text (a match holds its word: the search alone decides, 10 times faster over the package).
    texts = {str(path.relative_to(PACKAGE)): path.read_text(encoding="utf-8")
             for path in PACKAGE.rglob("*.py")}
    found = {}
    for name in registry.BUILT_IN:
        room = f"pinarray.paradigms.{name}"
        types = [t for t in api.__all__ if getattr(api, t).__module__.startswith(room + ".")]
        words = [f'"{name}"', room, *types]
        pattern = re.compile("|".join([rf'"{name}"', re.escape(room), *(rf"\b{t}\b" for t in types)]))
        found[name] = sorted(
            where for where, text in texts.items()
            if not where.startswith(f"paradigms/{name}/") and where not in NAMERS
            and any(word in text for word in words) and pattern.search(text))
    assert found == {name: [] for name in registry.BUILT_IN}
