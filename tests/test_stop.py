"""One way to stop: signals set a request, and what must finish once begun finishes."""

import os
import signal

import pytest

from pinarray.stop import (
    STOP_SIGNALS,
    Stopped,
    StopRequest,
    deferred_signals,
    stop_on_signals,
)


def test_every_stop_signal_sets_the_request_instead_of_ending_the_process():
    for number in STOP_SIGNALS:
        with stop_on_signals(StopRequest()) as stop:
            os.kill(os.getpid(), number)
            assert stop.requested and stop.signal_number == number
            assert stop.reason == f"stopped by {signal.Signals(number).name}"


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


def test_a_deferred_signal_waits_even_when_another_thread_could_take_it():
    # With a second thread (numpy starts one) the kernel may give the signal to that thread;
    # Python still runs the handler in the main thread, in the middle of the block. In a
    # process of its own: the test suite's other threads must not change which thread gets it.
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", DEFERRED_WITH_A_SECOND_THREAD],
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "rest / torque off / test stopped by SIGUSR1", done.stderr
