"""A resume looks at every file of the run before it writes one (issue 46, hostile re-run,
finding 5): a file that is no results file (a folder, a FIFO, a device, a link to nothing),
or a manifest that cannot be read (not UTF-8, nested without end, a key missing), is refused
in one line naming it, and every file of the run is left byte for byte as it was."""

import hashlib
import json
import os
from pathlib import Path

import pytest

import pinarray
from pinarray.errors import ResultsError
from tests.commands import pinarray_forked
from tests.lab_protocols import short_copy
from tests.test_paradigm_holes import RESUME_TIMEOUT_S, edited, run_cut_short


def snapshot(results: Path) -> dict[str, str]:
    """Every entry under ``results`` (its run's locks aside, which a resume takes and gives
    back): a regular file's SHA-256, a link's target, any other kind by its mode."""
    found = {}
    for folder, _, names in os.walk(results):
        for name in names:
            path = Path(folder, name)
            if name.endswith(".lock"):
                continue
            if path.is_symlink():
                found[str(path)] = "-> " + os.readlink(path)
            elif path.is_file():
                found[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
            else:
                found[str(path)] = oct(path.stat().st_mode)
    return found


def replaced(path: Path, by) -> None:
    path.unlink()
    by(path)


def recording(beh: Path) -> Path:
    return beh.with_name(beh.name.replace("_beh.tsv", "_recording-motion_physio.tsv.gz"))


DAMAGE = {
    "manifest a folder": ("manifest", lambda m: replaced(m, os.mkdir), "found a folder"),
    "manifest a link to /dev/zero": ("manifest", lambda m: replaced(
        m, lambda p: os.symlink("/dev/zero", p)), "found a character device"),
    "manifest not UTF-8": ("manifest", lambda m: m.write_bytes(b'{"seed": "\xe9"}'),
                           ":1:11: expected UTF-8 text, found byte 0xe9"),
    "manifest nested 100 000 deep": ("manifest", lambda m: m.write_text(
        "[" * 100_000 + "]" * 100_000), "found JSON nested deeper than any pinarray writes"),
    "manifest without its plan": ("manifest", lambda m: m.write_text(json.dumps(
        {k: v for k, v in json.loads(m.read_text()).items() if k != "plan"})),
        "expected a pinarray run manifest, found one without the key 'plan'"),
    "beh.tsv a link to nothing": ("beh", lambda b: replaced(
        b, lambda p: os.symlink("/nonexistent/beh.tsv", p)),
        "expected a results file, found a link to /nonexistent/beh.tsv, which does not exist"),
    "events.tsv a folder": ("events", lambda e: replaced(e, os.mkdir), "found a folder"),
    "beh.json a folder": ("beh.json", lambda j: replaced(j, os.mkdir), "found a folder"),
    "motion recording a folder": ("recording", lambda r: replaced(r, os.mkdir),
                                  "found a folder"),
}


def damaged_run(tmp_path: Path, where: str, damage) -> tuple[Path, Path]:
    """A toj run cut short after 3 answers, its ``where`` file damaged: (protocol, results)."""
    results = tmp_path / "results"
    protocol_path = short_copy("toj", tmp_path)
    beh = run_cut_short(protocol_path, results)
    (manifest,) = results.rglob("*_manifest.json")
    files = {"manifest": manifest, "beh": beh, "events": beh.with_name(
        beh.name.replace("_beh.tsv", "_events.tsv")), "beh.json": beh.with_suffix(".json"),
        "recording": recording(beh)}
    assert files[where].exists()
    damage(files[where])
    return protocol_path, results


@pytest.mark.parametrize("kind", DAMAGE)
def test_a_resume_refused_for_a_damaged_file_leaves_every_file_as_it_was(tmp_path, kind):
    where, damage, said = DAMAGE[kind]
    protocol_path, results = damaged_run(tmp_path, where, damage)
    before = snapshot(results)
    protocol = pinarray.load_protocol(protocol_path)
    with pytest.raises(ResultsError) as refused:
        pinarray.run_session(protocol, pinarray.simulated_observer(protocol, "default", seed=1),
                             subject="01", results=results, resume=True)
    message = str(refused.value)
    assert said in message and str(results) in message and "\n" not in message
    assert snapshot(results) == before


# A FIFO in a results file's place made the resume wait in open() for ever (and SIGTERM, whose
# handler only asks the run to stop, did not end it): run where a hang fails the test.
@pytest.mark.parametrize("where", ["events", "manifest", "recording"])
def test_a_fifo_in_a_results_files_place_is_refused_not_waited_on(tmp_path, where):
    protocol_path, results = damaged_run(tmp_path, where, lambda p: replaced(p, os.mkfifo))
    before = snapshot(results)
    result = pinarray_forked(tmp_path / "resume", "batch", protocol_path, "--subject", "01",
                             "--observer", "default", "--results", results, "--resume",
                             timeout=RESUME_TIMEOUT_S)
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.endswith("file, found a FIFO (named pipe)") and str(results) in line
    assert snapshot(results) == before


# A cell longer than Python's csv module reads (131,072 characters) leaked its words, with no
# line (hostile pass on issue 45, finding 11b): said at its row and column, by both readers.
def test_a_results_cell_too_long_to_read_is_refused_at_its_row_by_analyse_and_resume(
        tmp_path, capsys):
    from pinarray.cli import main

    protocol_path, results = damaged_run(tmp_path, "beh", lambda beh: edited(
        beh, "response", "1" * 200_000))
    (beh,) = results.rglob("*_beh.tsv")
    column = beh.read_text().splitlines()[2].index("1" * 200_000) + 1
    said = (f"{beh}:3:{column}: expected cells of at most 131,072 characters, found one of "
            "200,000")
    before = snapshot(results)
    capsys.readouterr()
    assert main(["analyse", str(results), "--out", str(tmp_path / "analysis")]) == 2
    first, *rest = capsys.readouterr().err.splitlines()
    assert first == f"pinarray: {said}" and all(str(beh) not in line for line in rest)
    assert main(["batch", str(protocol_path), "--subject", "01", "--observer", "default",
                 "--results", str(results), "--resume"]) == 2
    assert capsys.readouterr().err.splitlines() == [f"pinarray: {said}"]
    assert snapshot(results) == before and not (tmp_path / "analysis").exists()
