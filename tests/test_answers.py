"""Answer sheets for `pinarray batch --responses`, as labs save them from a spreadsheet: read in
any of Excel's formats, and every answer checked against the protocol before a run exists."""

import codecs
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinarray.cli.answer_sheets import AnswersError, check_answers, load_answers, parse_answers
from pinarray.journal.rows import read_trials
from pinarray.plan import make_plan
from pinarray.protocol.load import load_protocol
from tests.commands import pinarray_here
from tests.strategies import unicode_characters

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
MOTION = PROTOCOLS / "apparent_motion.yaml"  # 13 trials, one of them practice
LOCALISATION = PROTOCOLS / "localisation.yaml"


def motion_sheet(answer="left", header="trial,response", separator=",") -> str:
    rows = [header] + [f"{n}{separator}{answer}" for n in range(1, 14)]
    return "\n".join(rows) + "\n"


def batch(*args: str) -> subprocess.CompletedProcess:
    return pinarray_here("batch", *args)


def test_an_excel_unicode_text_sheet_runs_the_session(tmp_path):
    # Excel's "Unicode text": UTF-16 with a byte-order mark, tab-separated, CRLF, its own header.
    sheet = tmp_path / "answers.txt"
    text = motion_sheet("Right", header="Trial\tResponse\tNotes", separator="\t")
    sheet.write_bytes(text.replace("\n", "\r\n").encode("utf-16"))
    result = batch(str(MOTION), "--subject", "x1", "--responses", str(sheet), "--seed", "3",
                   "--results", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    (beh,) = (tmp_path / "out").rglob("*_beh.tsv")
    assert [r.response for r in read_trials(beh)] == ["right"] * 13


@pytest.mark.parametrize("encode", [
    lambda text: text.encode("utf-8-sig"),  # Excel's "CSV UTF-8"
    lambda text: text.encode("utf-16"),  # Excel's "Unicode text": little-endian, with a mark
    lambda text: codecs.BOM_UTF16_BE + text.encode("utf-16-be"),
    lambda text: text.encode("utf-8"),
])
@pytest.mark.parametrize("separator", [",", ";", "\t"])
def test_sheets_in_excels_encodings_and_separators_read_the_same(tmp_path, encode, separator):
    sheet = tmp_path / "a.csv"
    text = motion_sheet("LEFT", header=f"TRIAL{separator} Response ", separator=separator)
    sheet.write_bytes(encode(text.replace("\n", "\r\n")))
    answers = load_answers(str(sheet), [load_protocol(MOTION)])
    assert answers == {n: "left" for n in range(1, 14)}


def problems_of(text: str, protocol_path=MOTION) -> list[str]:
    with pytest.raises(AnswersError) as caught:
        check_answers(parse_answers(text, "a.csv"), "a.csv", load_protocol(protocol_path))
    return str(caught.value).splitlines()


def test_every_wrong_answer_is_named_by_its_line_before_any_trial_runs():
    text = motion_sheet().replace("4,left", "4,lefft").replace("9,left", "9,")
    assert problems_of(text) == [
        "a.csv:5: trial 4: expected one of none, left, right, unsure, found 'lefft'",
        "a.csv:10: trial 9: expected one of none, left, right, unsure, found nothing",
    ]


def test_a_trial_answered_twice_or_not_in_the_plan_is_refused_at_its_line():
    text = motion_sheet() + "3,right\n14,left\n"
    with pytest.raises(AnswersError) as caught:
        check_answers(parse_answers(text, "a.csv"), "a.csv", load_protocol(MOTION))
    assert str(caught.value) == "a.csv:15: trial 3 is answered twice (first on line 4)"
    lines = problems_of(motion_sheet() + "14,left\n0,none\n")
    assert lines == [f"a.csv:15: no trial 14 in the plan of {MOTION}: expected 1 to 13",
                     f"a.csv:16: no trial 0 in the plan of {MOTION}: expected 1 to 13"]


def test_localisation_answers_are_pins_of_the_grid_or_none():
    count = load_protocol(LOCALISATION).design.trial_count
    rows = [f"{n},{(n % 16) + 1}" for n in range(1, count + 1)]
    rows[0], rows[1], rows[2] = "1,None", "2,07", "3,17"
    lines = problems_of("trial,response\n" + "\n".join(rows) + "\n", LOCALISATION)
    assert lines == ["a.csv:4: trial 3: expected a pin number from 1 to 16 or 'none', found '17'"]
    rows[2] = "3,16"
    answers = check_answers(parse_answers("trial,response\n" + "\n".join(rows), "a.csv"),
                            "a.csv", load_protocol(LOCALISATION))
    assert (answers[1], answers[2]) == ("none", "7")


def test_a_sheet_without_the_two_columns_says_what_its_header_should_be():
    with pytest.raises(AnswersError, match=r"^a\.csv:1: expected a header row naming the columns "
                                           r"trial and response"):
        parse_answers("trial,answer\n1,left\n", "a.csv")
    with pytest.raises(AnswersError, match=r"^a\.csv:2: expected a trial number, found 'one'"):
        parse_answers("trial,response\none,left\n", "a.csv")


def test_a_wrong_answer_leaves_no_run_behind(tmp_path):
    sheet = tmp_path / "a.csv"
    sheet.write_text(motion_sheet().replace("13,left", "13,up"))
    result = batch(str(MOTION), "--subject", "p2", "--responses", str(sheet),
                   "--results", str(tmp_path / "out"))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr == (f"pinarray: {sheet}:14: trial 13: expected one of none, left, "
                             "right, unsure, found 'up'\n")
    assert not (tmp_path / "out").exists()


def test_a_sheet_that_is_not_text_is_one_located_line(tmp_path):
    sheet = tmp_path / "a.csv"
    sheet.write_bytes(b"trial,response\n1,l\xe9ft\n")
    with pytest.raises(AnswersError) as caught:
        load_answers(str(sheet), [load_protocol(MOTION)])
    assert str(caught.value) == f"{sheet}:2: expected UTF-8 text, found byte 0xe9 (save the file as UTF-8)"
    with pytest.raises(AnswersError, match="expected a responses file, found a folder"):
        load_answers(str(tmp_path), [load_protocol(MOTION)])


sheet_texts = st.one_of(
    st.text(unicode_characters, max_size=200),
    st.text(alphabet="0123456789,;\t\r\n\0\"' left", max_size=200).map(lambda t: "trial,response\n" + t),
    st.lists(st.tuples(st.sampled_from(["1", "2", "13", "14", "0", "-1", "x", "", "9" * 30,
                                        "1.0", "٣"]),
                       st.sampled_from(["left", "LEFT", "none", "", "up", "7", '"left"', "a,b"])),
             max_size=20).map(lambda rows: "Trial;Response\n" + "\n".join(f"{t};{r}" for t, r in rows)),
)


@pytest.fixture(scope="module")
def motion():
    """The motion protocol and its trial numbers, read once: every sheet is checked against
    them, and checking changes neither (a frozen protocol)."""
    protocol = load_protocol(MOTION)
    return protocol, list(range(1, len(make_plan(protocol, 0)) + 1))


@settings(max_examples=200, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(text=sheet_texts)
def test_any_sheet_is_read_or_refused_one_line_per_problem(text, motion):
    protocol, trials = motion
    try:
        answers = check_answers(parse_answers(text, "a.csv"), "a.csv", protocol)
    except AnswersError as problem:
        for line in str(problem).splitlines():
            assert line.startswith("a.csv:") and "Traceback" not in line
    else:
        assert sorted(answers) == trials
