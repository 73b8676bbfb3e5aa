"""`pinarray validate` starts light: it loads the protocol reader and its own command, nothing
else of pinarray and none of the heavy libraries, whichever way the command is started; a
protocol that reads without a problem then has its stimuli played on the simulated array
(`pinarray.player.rehearsal`), which loads the simulator and numpy, and still nothing of the
sessions, results, analysis, UI or plotting.

What a process imports is read from ``-X importtime`` (``PYTHONPROFILEIMPORTTIME`` for the
installed script), so the check sees the whole start-up, the entry point's own imports included.
How long the start-up takes is measured in ``tests/benchmarks/bench_startup.py``, not here.
"""

import argparse
import os
import subprocess
import sys
from importlib import import_module
from pathlib import Path

import pytest

from pinarray.cli import COMMANDS, build_parser
from tests.lab_protocols import short_copy

PROTOCOLS = Path(__file__).resolve().parent.parent / "protocols"
SCRIPT = Path(sys.executable).parent / "pinarray"  # the console script `pip install` wrote

HEAVY = ("numpy", "scipy", "matplotlib", "textual", "serial", "scservo_sdk")
# What validating needs of pinarray: the reader of protocol files and the validate command
# (with the guard on its standard output, `pinarray.cli.output`).
NEEDED = ("pinarray", "pinarray.version", "pinarray.cli", "pinarray.cli.common",
          "pinarray.cli.output", "pinarray.cli.protocols",
          "pinarray.errors", "pinarray.units", "pinarray.grid", "pinarray.text_files",
          "pinarray.protocol", "pinarray.registry", "pinarray.paradigms", "pinarray.paradigms.base")
# ... and of the protocol's paradigm (found by the registry), its room's design alone: not its
# rows, analysis or observer, nor any other room, nor the installed packages' entry points.
ROOM = ("pinarray.paradigms.localisation", "pinarray.paradigms.localisation.design")
# What playing a valid protocol's stimuli on the simulated array needs beside them.
REHEARSAL = ("pinarray.player", "pinarray.hardware", "pinarray.schedule", "pinarray.clock",
             "pinarray.stop")
REHEARSAL_LIBRARIES = ("numpy", "serial")  # the simulated bus is opened as a port is


def imported_by(command: list[str]) -> set[str]:
    """Every module the process running ``command`` imported, as ``-X importtime`` lists them."""
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=60,
        env={**os.environ, "PYTHONPROFILEIMPORTTIME": "1"},
    )
    assert result.returncode in (0, 2), result.stderr[-2000:]
    return {line.rsplit("|", 1)[1].strip() for line in result.stderr.splitlines()
            if line.startswith("import time:") and not line.endswith("imported package")}


def commands_in(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def commands_of(register) -> list[str]:
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    return list(commands_in(parser))


@pytest.mark.parametrize("entry", ["python -m pinarray", "installed script"])
@pytest.mark.parametrize("protocol", ["localisation.yaml", "a broken one"])
def test_validate_loads_the_protocol_reader_and_nothing_else_of_pinarray_nor_heavy_libraries(
    entry, protocol, tmp_path
):
    path = PROTOCOLS / protocol
    if protocol == "a broken one":
        path = tmp_path / "broken.yaml"
        path.write_text((PROTOCOLS / "localisation.yaml").read_text().replace("pins:", "pinz:"))
    if entry == "installed script" and not SCRIPT.exists():
        pytest.skip(f"no console script beside {sys.executable}")
    start = [sys.executable, "-m", "pinarray"] if entry.startswith("python") else [str(SCRIPT)]
    modules = imported_by([*start, "validate", str(path)])

    assert "pinarray.protocol.load" in modules  # the listing is read right: it did validate
    played = protocol != "a broken one"
    assert ("pinarray.player.rehearsal" in modules) is played
    allowed = REHEARSAL_LIBRARIES if played else ()
    assert sorted(m for m in modules if m.split(".")[0] in HEAVY
                  and m.split(".")[0] not in allowed) == []
    parts = ("pinarray.protocol", *(REHEARSAL if played else ()))
    others = {m for m in modules if m.split(".")[0] == "pinarray" and m not in ROOM
              and m not in NEEDED and not any(m == p or m.startswith(p + ".") for p in parts)}
    assert sorted(others) == []
    assert "importlib.metadata" not in modules  # a shipped paradigm: no entry points read


# What the player process (`python -m pinarray.player.child`, one per array a lab opens) must not
# load as it starts: it plays prepared trials on the descriptor it inherits, and reads no
# protocol, plans nothing, writes no results and simulates nothing itself; nor numpy (its
# reports' arrays are made in the process that asked: `pinarray.player.playback`), nor the
# multiprocessing package its channel does without (`pinarray.player.channel`). What it loads
# while it plays is looked at in tests/hardware/test_player_process.py.
PLAYER_NEVER = ("pinarray.protocol", "pinarray.plan", "pinarray.session", "pinarray.journal",
                "pinarray.analysis", "pinarray.api", "pinarray.paradigms", "pinarray.imaging",
                "pinarray.tui", "pinarray.cli", "pinarray.hardware.feetech.sim",
                "pinarray.hardware.pca9685.sim", "pinarray.schedule", "yaml", "numpy", "scipy",
                "matplotlib", "textual", "multiprocessing")


def test_the_player_process_loads_playback_once_given_servos_and_nothing_of_numpy_protocols_sessions_or_simulators():
    # As it starts (a timing check's player goes no further: it only measures wake-ups), and
    # once a Hello hands it servos (what it loads then, before it answers Ready).
    starting = imported_by([sys.executable, "-c", "import pinarray.player.child"])
    playing = imported_by([sys.executable, "-c",
                           "from pinarray.player.child import load_playback; load_playback()"])

    assert "pinarray.player.child" in starting  # the listing is read right: it did load
    assert "pinarray.player.playback" not in starting
    assert "pinarray.player.playback" in playing
    assert sorted(m for m in starting | playing
                  if any(m == part or m.startswith(part + ".") for part in PLAYER_NEVER)) == []


def test_a_servo_bring_up_command_loads_no_numpy():
    # `pinarray servos` talks to servos one packet at a time: it opens the Feetech bus the
    # player plays on (which names the samples a trial's motion is measured from) but measures
    # nothing, and should start as fast as a lab renumbering servos expects.
    modules = imported_by([sys.executable, "-m", "pinarray", "servos", "scan", "--sim",
                           "sim://?ids=1"])

    assert "pinarray.hardware.feetech.feetech" in modules  # it did open the bus
    assert sorted(m for m in modules if m.split(".")[0] == "numpy") == []


# What a batch of a fixed design answered by a simulated subject, with no scanner and no LSL
# markers (most batches), has no use for: the analyses beyond the subject, the adaptive
# procedures, the scanner's and the markers' modules.
BATCH_NEVER = ("pinarray.adaptive", "pinarray.procedures", "pinarray.session.procedures",
               "pinarray.imaging.scanner", "pinarray.imaging.markers", "pinarray.imaging.triggers",
               "pinarray.analysis.load", "pinarray.analysis.tables", "pinarray.analysis.power",
               "pinarray.analysis.stats", "pinarray.paradigms.localisation.stats")


def test_a_fixed_design_s_batch_answered_by_a_simulated_subject_loads_no_analysis_adaptive_procedure_or_scanner(
        tmp_path):
    protocol = short_copy("localisation", tmp_path)
    modules = imported_by([sys.executable, "-m", "pinarray", "batch", str(protocol), "--observer",
                           "default", "--subject", "01", "--seed", "7",
                           "--results", str(tmp_path / "results")])

    # the listing is read right: it wrote rows, answered by the simulated subject (its room's
    # observer, imported by name, is not listed; the models it is built from are)
    assert {"pinarray.journal.writer", "pinarray.analysis.observers"} <= modules
    assert sorted(m for m in modules
                  if any(m == part or m.startswith(part + ".") for part in BATCH_NEVER)) == []


def parts_loaded_by(code: str) -> list[str]:
    """pinarray's modules loaded once ``code`` has run (a public name's home is imported by
    `importlib.import_module`, which ``-X importtime`` does not list)."""
    shown = "import sys; print(*sorted(m for m in sys.modules if m.split('.')[0] == 'pinarray'))"
    result = subprocess.run([sys.executable, "-c", f"{code}; {shown}"], capture_output=True,
                            text=True, timeout=60, check=True)
    return result.stdout.split()


def test_importing_pinarray_loads_its_version_and_no_other_part_until_a_public_name_is_used():
    assert parts_loaded_by("import pinarray") == ["pinarray", "pinarray.version"]
    used = parts_loaded_by("import pinarray; pinarray.load_protocol")
    assert "pinarray.api.protocols" in used and "pinarray.api.array" not in used


def test_the_command_table_names_the_module_that_registers_each_command():
    for module, words in COMMANDS.items():
        assert commands_of(import_module(f"pinarray.cli.{module}").register) == list(words)
    assert list(commands_in(build_parser())) == [w for words in COMMANDS.values() for w in words]


@pytest.mark.parametrize("word", [word for words in COMMANDS.values() for word in words])
def test_a_command_built_alone_is_the_command_the_whole_parser_holds(word):
    alone, whole = commands_in(build_parser(word))[word], commands_in(build_parser())[word]
    assert alone.format_help() == whole.format_help()
    assert [a.option_strings or a.dest for a in alone._actions] == \
        [a.option_strings or a.dest for a in whole._actions]
