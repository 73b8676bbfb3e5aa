"""One way to stop: signals set a request, and what must finish once begun finishes."""

import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

from pinarray.stop import (
    STOP_SIGNALS,
    Stopped,
    StopRequest,
    deferred_signals,
    signal_name,
    stop_on_signals,
)


def test_every_stop_signal_sets_the_request_instead_of_ending_the_process():
    for number in STOP_SIGNALS:
        with stop_on_signals(StopRequest()) as stop:
            os.kill(os.getpid(), number)
            assert stop.requested and stop.signal_number == number
            assert stop.reason == f"stopped by {signal_name(number)}"


def test_real_time_signals_are_named_as_kill_names_them():
    numbers = range(signal.SIGRTMIN, signal.SIGRTMAX + 1)
    if shutil.which("bash") is None:
        pytest.skip("no bash to ask")
    listed = subprocess.run(["bash", "-c", 'for n in "$@"; do kill -l "$n"; done', "bash",
                             *map(str, numbers)], capture_output=True, text=True, check=True)
    assert [signal_name(number) for number in numbers] == [
        f"SIG{name}" for name in listed.stdout.split()]


def test_a_second_signal_raises_at_once_unless_something_must_finish_first():
    with stop_on_signals(StopRequest()):
        os.kill(os.getpid(), signal.SIGTERM)
        done = []
        with pytest.raises(Stopped, match="again"):
            with deferred_signals():
                os.kill(os.getpid(), signal.SIGTERM)
                done.append("the safe stop finished")
        assert done == ["the safe stop finished"]


DEFERRED_WITH_A_SECOND_THREAD = """
import os, signal, threading
from pinarray.stop import Stopped, deferred_signals, raise_on_signals
idle = threading.Event()
helper = threading.Thread(target=idle.wait, args=(10,))
helper.start()
steps = []
try:
    with raise_on_signals("test"):
        with deferred_signals():
            steps.append("rest")
            os.kill(os.getpid(), signal.SIGUSR1)
            for _ in range(100_000):  # give a handler every chance to run in here
                pass
            steps.append("torque off")
except Stopped as stopped:
    steps.append(str(stopped))
idle.set()
helper.join()
print(" / ".join(steps))
"""


A_SCRIPTS_OWN_HANDLERS = """
import os, select, signal, threading
from pinarray.stop import deferred_signals

class Watchdog(Exception):
    pass

def watchdog(signum, frame):
    raise Watchdog("too slow")

signal.signal(signal.SIGALRM, watchdog)
# Ctrl-C as Python sets it up in a terminal (a shell starting us in the background ignores it)
signal.signal(signal.SIGINT, signal.default_int_handler)
arrived, wake = os.pipe()  # a byte each time a signal is taken, by whichever thread
os.set_blocking(wake, False)
signal.set_wakeup_fd(wake)
idle = threading.Event()
helper = threading.Thread(target=idle.wait, args=(30,))
helper.start()
for number, expected in ((signal.SIGINT, KeyboardInterrupt), (signal.SIGALRM, Watchdog)):
    steps = []
    try:
        with deferred_signals():
            steps.append("rest")
            for tap in range(2):  # twice
                signal.pthread_kill(helper.ident, number)  # the thread OpenBLAS would be
                assert select.select([arrived], [], [], 20)[0], "the signal never came"
                os.read(arrived, 1)
            for _ in range(100_000):  # give a handler every chance to run in here
                pass
            steps.append("torque off")
    except expected:
        steps.append(expected.__name__)
    print(" / ".join(steps))
idle.set()
helper.join()
"""


def test_a_scripts_ctrl_c_and_its_watchdogs_exception_wait_for_the_safe_stop_whichever_thread_takes_them():
    # A lab's script keeps Python's Ctrl-C (KeyboardInterrupt) and sets its own handlers (a
    # watchdog on SIGALRM). Given to another thread, as the kernel may, the handler still ran
    # in the main thread in the middle of the rest: the goals sent, torque never switched off.
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", A_SCRIPTS_OWN_HANDLERS],
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.splitlines() == ["rest / torque off / KeyboardInterrupt",
                                        "rest / torque off / Watchdog"], done.stderr


def test_the_handlers_are_back_after_a_deferral():
    def lab_handler(signum, frame):
        pass

    ctrl_c = signal.getsignal(signal.SIGINT)
    previous = signal.signal(signal.SIGUSR2, lab_handler)
    try:
        with deferred_signals():
            with deferred_signals():
                assert signal.getsignal(signal.SIGUSR2) is not lab_handler
        assert signal.getsignal(signal.SIGUSR2) is lab_handler
        assert signal.getsignal(signal.SIGINT) is ctrl_c
    finally:
        signal.signal(signal.SIGUSR2, previous)


def test_a_deferred_signal_waits_even_when_another_thread_could_take_it():
    # With a second thread (numpy starts one) the kernel may give the signal to that thread;
    # Python still runs the handler in the main thread, in the middle of the block. In a
    # process of its own: the test suite's other threads must not change which thread gets it.
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", DEFERRED_WITH_A_SECOND_THREAD],
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "rest / torque off / test stopped by SIGUSR1", done.stderr


# -- Ctrl-C as a command starts ------------------------------------------------------------------

def files_under(folder):
    return {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()}


def interrupting(original):
    """``original``, called after Ctrl-C reaches the process (Python's own handler, as in a
    command that has installed none yet): the interrupt lands inside it, at a known point."""
    def interrupted(*args, **kwargs):
        signal.signal(signal.SIGINT, signal.default_int_handler)
        os.kill(os.getpid(), signal.SIGINT)
        return original(*args, **kwargs)
    return interrupted


@pytest.mark.parametrize("moment", ["as the parser is built", "as the arguments are read"])
def test_ctrl_c_as_a_command_starts_ends_in_one_line_with_the_results_untouched(
        moment, tmp_path, monkeypatch):
    # The issue 46 re-run: Ctrl-C in the first 0.1-0.2 s of `batch --resume` was a traceback.
    import argparse

    from pinarray.cli import batch
    from tests.commands import pinarray_forked
    from tests.lab_protocols import short_copy
    from tests.test_paradigm_holes import run_cut_short

    results = tmp_path / "results"
    protocol = short_copy("toj", tmp_path)
    run_cut_short(protocol, results)  # an aborted run, to resume
    before = files_under(results)
    # Changed here, before the fork: only the forked command calls them.
    if moment == "as the parser is built":
        monkeypatch.setattr(batch, "register", interrupting(batch.register))
    else:
        monkeypatch.setattr(argparse.ArgumentParser, "parse_args",
                            interrupting(argparse.ArgumentParser.parse_args))
    done = pinarray_forked(tmp_path / "out", "batch", protocol, "--subject", "01", "--observer",
                           "default", "--speed", "0", "--results", results, "--resume",
                           timeout=60)
    assert (done.returncode, done.stderr, done.stdout) == (130, "pinarray: interrupted\n", "")
    assert files_under(results) == before


# -- Ctrl-C as the command loads, and as it ends -------------------------------------------------

# The console script's shape (a file named pinarray that imports `pinarray.cli.main` and exits
# with its status), held at one moment where a Ctrl-C lands: deterministic, not raced.
CONSOLE_SCRIPT = """\
import atexit, os, signal, sys
{before}
from pinarray.cli import main
status = main()
{after}
sys.exit(status)
"""
CTRL_C = "os.kill(os.getpid(), signal.SIGINT)"
MOMENTS = {
    # Issue 46's fourth pass: a traceback inside the package's imports (rc 1 or -2).
    "as the package loads": ("import pinarray\n" + CTRL_C, ""),
    # ... and, after the command's work, death by the signal with nothing said (rc -2).
    "as the command ends": ("", CTRL_C),
    "as the interpreter ends": (f"atexit.register(lambda: {CTRL_C})", ""),
}


@pytest.mark.parametrize("moment", MOMENTS)
def test_ctrl_c_as_the_command_loads_or_ends_is_one_line_with_a_defined_status(moment, tmp_path):
    import subprocess
    import sys

    before, after = MOMENTS[moment]
    script = tmp_path / "pinarray"
    script.write_text(CONSOLE_SCRIPT.format(before=before, after=after))
    protocol = str(Path(__file__).resolve().parent.parent / "protocols" / "toj.yaml")
    done = subprocess.run([sys.executable, str(script), "validate", protocol],
                          capture_output=True, text=True, timeout=60)
    if moment == "as the package loads":  # nothing done yet: interrupted
        assert (done.returncode, done.stderr, done.stdout) == (130, "pinarray: interrupted\n", "")
        return
    # The work was done: its status and output stand, and the Ctrl-C is said, or (once the
    # interpreter is ending, past the last word) waits blocked and dies with the process.
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"{protocol}: ok")
    late = "pinarray: interrupted as the command ended; its result stands\n"
    assert done.stderr == (late if moment == "as the command ends" else "")


def test_a_handler_that_installs_its_successor_is_followed_when_the_signals_are_handed_over():
    # The usual two-stage Ctrl-C: the first finishes the trial and installs a handler that
    # aborts at the second. Both taps held back by a safe stop: the second reaches the second.
    stages = []

    def abort(signum, frame):
        stages.append("abort")

    def finish(signum, frame):
        stages.append("finish")
        signal.signal(signal.SIGUSR2, abort)

    previous = signal.signal(signal.SIGUSR2, finish)
    try:
        with deferred_signals():
            os.kill(os.getpid(), signal.SIGUSR2)
            os.kill(os.getpid(), signal.SIGUSR2)
            assert stages == []
        assert stages == ["finish", "abort"]
    finally:
        signal.signal(signal.SIGUSR2, previous)


class Watchdog(Exception):
    pass


@pytest.mark.parametrize("when", ["putting them aside", "putting them back"])
def test_an_exception_landing_as_the_handlers_are_swapped_leaves_every_handler_as_it_was(
        monkeypatch, when):
    # Stranger attack 12: a watchdog's exception landing between two swaps left the others
    # swapped for good: the script's Ctrl-C was noted, never raised, for the rest of its run.
    # Here it lands at the swap of the second of the script's handlers.
    def lab_handler(signum, frame):
        pass

    labs = (signal.SIGUSR1, signal.SIGUSR2, signal.SIGALRM)
    previous = {number: signal.signal(number, lab_handler) for number in labs}
    before = {number: signal.getsignal(number) for number in signal.valid_signals()}
    swap, calls = signal.signal, []

    def landing(number, handler):
        if number in labs and (handler is lab_handler) == (when == "putting them back"):
            calls.append(number)
            if len(calls) == 2:
                raise Watchdog("too slow")
        return swap(number, handler)

    try:
        monkeypatch.setattr(signal, "signal", landing)
        with pytest.raises(Watchdog):
            with deferred_signals():
                pass
        monkeypatch.undo()
        assert {number: signal.getsignal(number) for number in signal.valid_signals()} == before
    finally:
        monkeypatch.undo()
        for number, handler in previous.items():
            signal.signal(number, handler)


def test_counting_handlers_see_every_signal_held_back_once_in_the_order_they_came():
    # Stranger attack 12: the stop signals were also masked, and the kernel merged each
    # signal's repeats and gave them after the others: USR1 ALRM USR1 USR2 ALRM USR1 reached
    # the script's handlers as ALRM ALRM USR1 USR2.
    seen = []

    def count(signum, frame):
        seen.append(signal.Signals(signum).name)

    sent = (signal.SIGUSR1, signal.SIGALRM, signal.SIGUSR1, signal.SIGUSR2, signal.SIGALRM,
            signal.SIGUSR1)
    previous = {number: signal.signal(number, count) for number in set(sent)}
    try:
        with deferred_signals():
            for number in sent:
                os.kill(os.getpid(), number)
            for _ in range(10_000):  # give a handler every chance to run in here
                pass
            assert seen == []
        assert seen == [signal.Signals(number).name for number in sent]
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


ENDED_BY_DEFAULT = """
import os, select, signal, sys, threading
from pinarray.stop import deferred_signals

signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a lab script that handles nothing
arrived, wake = os.pipe()  # a byte when the signal is taken, by whichever thread
os.set_blocking(wake, False)
signal.set_wakeup_fd(wake)
idle = threading.Event()
helper = threading.Thread(target=idle.wait, args=(30,), daemon=True)
helper.start()
with deferred_signals():
    print("rest", flush=True)
    signal.pthread_kill(helper.ident, signal.SIGTERM)  # the thread OpenBLAS would be
    select.select([arrived], [], [], 20)
    for _ in range(100_000):
        pass
    print("torque off", flush=True)
print("went on", flush=True)
"""


def test_a_signal_whose_default_ends_the_script_ends_it_once_torque_is_off():
    # Stranger attack 13: a script with no handler of its own (SIGTERM, SIGHUP at their
    # default) was ended by the kernel in the middle of close()'s rest, when the signal went
    # to numpy's thread: the masking held it back from the main thread only. Torque stayed on.
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", ENDED_BY_DEFAULT], capture_output=True,
                          text=True, timeout=60)
    assert done.stdout.splitlines() == ["rest", "torque off"], done.stderr
    assert done.returncode == -signal.SIGTERM


@pytest.mark.realtime
def test_a_command_whose_terminal_closed_with_its_hang_up_ends_by_the_signal_not_a_crash():
    # Stranger attack (attack-stop): an SSH session closing sends SIGHUP and takes the terminal
    # with it. The stop's one line, printed into the closed terminal after the handlers were
    # put back, raised an OSError out of the command: exit status 1, a traceback for nobody,
    # instead of 128 + the signal. A pseudo-terminal, as an SSH session's: once its other side
    # is closed every write to it fails (EIO), and no SIGPIPE comes to end the command instead.
    import pty
    import subprocess
    import sys

    demo = Path(__file__).resolve().parent.parent / "protocols" / "demo.yaml"
    terminal, its_device = pty.openpty()
    process = subprocess.Popen([sys.executable, "-m", "pinarray", "play", str(demo), "--sim",
                                "--speed", "1"], stdout=its_device, stderr=its_device)
    os.close(its_device)
    try:
        shown = b""
        while b"demo: 16 trial(s)" not in shown:  # playing now
            shown += os.read(terminal, 4096)
        os.close(terminal)  # the session is gone...
        process.send_signal(signal.SIGHUP)  # ...with its hang-up
        process.wait(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + signal.SIGHUP


@pytest.mark.realtime
@pytest.mark.parametrize("ignored", [signal.SIGHUP, signal.SIGINT], ids=["nohup", "background"])
def test_a_command_started_with_nohup_outlives_the_hang_up_and_stops_on_the_next_signal(ignored):
    # Stranger attack (attack-launch): `nohup pinarray batch ... &` sets SIGHUP to be ignored so
    # that the run outlives the SSH session; the command took it back and the run was aborted
    # as the session closed ("stopped by SIGHUP", exit 129). A script's background job has
    # SIGINT ignored the same way (review: the command's first line took it back).
    import subprocess
    import sys

    demo = Path(__file__).resolve().parent.parent / "protocols" / "demo.yaml"
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "play", str(demo), "--sim", "--speed", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        preexec_fn=lambda: signal.signal(ignored, signal.SIG_IGN))  # as nohup does
    try:
        assert process.stdout.readline().startswith(b"demo: 16 trial(s)")  # playing now
        process.send_signal(ignored)  # the session closes
        with pytest.raises(subprocess.TimeoutExpired):
            process.wait(timeout=1)  # still playing
        process.send_signal(signal.SIGTERM)
        err = process.communicate(timeout=60)[1].decode()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + signal.SIGTERM, err
    assert err.splitlines()[-1] == "pinarray: stopped by SIGTERM", err
