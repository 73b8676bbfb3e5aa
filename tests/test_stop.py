"""One way to stop: signals set a request, and what must finish once begun finishes."""

import os
import signal
import threading

import pytest

from pinarray.stop import (
    STOP_SIGNALS,
    Stopped,
    StopRequest,
    deferred_signals,
    raise_on_signals,
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


def test_a_deferred_signal_waits_even_when_another_thread_could_take_it():
    # With a second thread (numpy starts one) the kernel may give the signal to that thread;
    # Python still runs the handler in the main thread, in the middle of the block.
    idle = threading.Event()
    helper = threading.Thread(target=idle.wait, args=(10,))
    helper.start()
    steps = []
    try:
        with raise_on_signals("test"), pytest.raises(Stopped, match="SIGUSR1"):
            with deferred_signals():
                steps.append("rest")
                os.kill(os.getpid(), signal.SIGUSR1)
                for _ in range(1000):  # give a handler every chance to run in here
                    pass
                steps.append("torque off")
    finally:
        idle.set()
        helper.join()
    assert steps == ["rest", "torque off"]
