"""The other ways out, and the stimulus after a stop: what the attack on issue 44 asked for.

The servos are `pinarray sim-serve --arrivals` on a pseudo-terminal, in a process of its own,
as in bench_stop (whose `Server` and long train this uses): a figure is when the last servo's
torque-off write arrived, as the servos stamp it, minus the moment of the event. Each round
measures, in turn:

- the reference: `PinArray.stop()` of an array holding its pins at rest (bench_stop's);
- a script SIGKILLed mid-stimulus while a helper it forked lives on (the bar: 0.5 s);
- `stop()` mid-stimulus while the player process is frozen (SIGSTOP; the bar: 0.5 s);
- a script suspended (SIGTSTP, Ctrl-Z) mid-stimulus: its stimulus cut, as decided then.

Then, in ms of the call: `arm()` of a stimulus right after a `stop()` (torque comes back
first), beside `arm()` of the same stimulus on an array still holding its pins (the bar: the
stimulus after a stop starts when it is due, like any other: well within the array's
`lead_ns`); and, in s, `open_array` on a port where no servo answers, beside `open_array`
where all 16 do (the bar: a few seconds, not 46).

Printed, never asserted: min / median / max over the rounds, each row's median over its
reference's.
"""

from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pinarray
from pinarray.hardware.feetech.faults import SimConfig
from pinarray.hardware.feetech.serve import PtyServer
from tests.benchmarks.bench_stop import PLAYING_S, PROTOCOL, ROUNDS, Server, last_off_ms

FORKING_SCRIPT = """\
import os, sys, time, pinarray
protocol = pinarray.load_protocol(sys.argv[1])
array = pinarray.open_array(protocol, port=sys.argv[2])
helper = os.fork()
if helper == 0:
    time.sleep(600)
    os._exit(0)
array.arm(pinarray.find_condition(protocol, pin=6), at_ns=array.now_ns() + 10**8)
print(helper, flush=True)
time.sleep(600)
"""

PRESENTING_SCRIPT = """\
import sys, pinarray
protocol = pinarray.load_protocol(sys.argv[1])
with pinarray.open_array(protocol, port=sys.argv[2]) as array:
    print("open", flush=True)
    array.present(pinarray.find_condition(protocol, pin=6))
"""


def _script(folder: Path, text: str, protocol: pinarray.Protocol, server: Server
            ) -> subprocess.Popen[str]:
    script = folder / "script.py"
    script.write_text(text)
    return subprocess.Popen([sys.executable, str(script), str(protocol.source), server.path],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)


def _end(*pids: int) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def released(folder: Path, protocol: pinarray.Protocol) -> dict[str, float]:
    """ms from each event to the last servo's torque-off, one of each way in turn."""
    figures: dict[str, float] = {}
    condition = pinarray.find_condition(protocol, pin=6)
    for way in ("reference", "frozen"):
        server = Server(folder)
        try:
            array = pinarray.open_array(protocol, port=server.path)
            if way == "frozen":
                array.arm(condition, at_ns=array.now_ns() + 50_000_000)
                time.sleep(PLAYING_S)
                player = array._rig.player
                assert player is not None
                os.kill(player.process.pid, signal.SIGSTOP)
            asked_ns = time.monotonic_ns()
            array.stop()
            array.close()
        finally:
            figures[way] = last_off_ms(server.torque_offs(), asked_ns)
    server = Server(folder)
    process = _script(folder, FORKING_SCRIPT, protocol, server)
    helper = int(process.stdout.readline())  # type: ignore[union-attr]
    try:
        time.sleep(PLAYING_S)
        asked_ns = time.monotonic_ns()
        process.kill()
        process.wait(timeout=60)
        time.sleep(1)  # the release has come by now, or is late: the figure says which
    finally:
        _end(process.pid, helper)
        figures["forked"] = last_off_ms(server.torque_offs(), asked_ns)
    server = Server(folder)
    process = _script(folder, PRESENTING_SCRIPT, protocol, server)
    try:
        process.stdout.readline()  # type: ignore[union-attr]
        time.sleep(PLAYING_S)
        asked_ns = time.monotonic_ns()
        process.send_signal(signal.SIGSTOP)  # as Ctrl-Z; never dropped (see test_library_safety)
        time.sleep(1)
    finally:
        _end(process.pid)
        process.wait(timeout=60)
        figures["suspended"] = last_off_ms(server.torque_offs(), asked_ns)
    return figures


def armed_after_stop(protocol: pinarray.Protocol) -> dict[str, float]:
    """ms of one `arm()` on an array holding its pins after a stimulus played, and of one right
    after a `stop()`, on servos answering after the factory's return delay (500 us) and after
    none; whether each stimulus started when due (`Played`, not `NotStarted`)."""
    condition = pinarray.find_condition(protocol, pin=6)
    figures: dict[str, float] = {}
    for delay_us in (500, 0):
        server = PtyServer(SimConfig(ids=tuple(range(1, 17)), return_delay_us=delay_us)).start()
        try:
            with pinarray.open_array(protocol, port=server.path) as array:
                array.present(condition)  # the first stimulus starts the thread that plays
                for way in ("held", "after a stop"):
                    if way == "after a stop":
                        array.stop()
                    started = time.perf_counter()
                    armed = array.arm(condition, at_ns=array.now_ns() + array.lead_ns + 10**6)
                    figures[f"{way} {delay_us}"] = (time.perf_counter() - started) * 1e3
                    ending = armed.result().ending
                    figures[f"{way} {delay_us} on time"] = isinstance(ending, pinarray.Played)
        finally:
            server.stop()
    return figures


def opened(protocol: pinarray.Protocol) -> dict[str, float]:
    """s `open_array` takes to connect where all 16 servos answer, and to fail where none do."""
    figures: dict[str, float] = {}
    for way, ids in (("all answer", tuple(range(1, 17))), ("none answers", (200,))):
        server = PtyServer(SimConfig(ids=ids)).start()
        try:
            started = time.perf_counter()
            try:
                pinarray.open_array(protocol, port=server.path).close()
            except pinarray.BusError:
                pass
            figures[way] = time.perf_counter() - started
        finally:
            server.stop()
    return figures


def table(title: str, unit: str, rounds: list[dict[str, float]],
          rows: list[tuple[str, str]], reference: str) -> None:
    base = statistics.median(r[reference] for r in rounds)
    print(f"\n{title}, {len(rounds)} rounds; ratio: median / median of the reference")
    print(f"{'':<70} {'min':>8} {'median':>8} {'max':>8} {'ratio':>7}")
    for name, key in rows:
        values = [r[key] for r in rounds]
        print(f"{name + f' ({unit})':<70} {min(values):>8.1f} {statistics.median(values):>8.1f} "
              f"{max(values):>8.1f} {statistics.median(values) / base:>6.2f}x")


def run() -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "long_train.yaml"
        path.write_text(PROTOCOL)
        protocol = pinarray.load_protocol(path)
        table("From the event to the last torque-off at the servo; sim-serve on a "
              "pseudo-terminal, the player process playing", "ms",
              [released(Path(folder), protocol) for _ in range(ROUNDS)],
              [("stop() of an idle array (reference)", "reference"),
               ("script SIGKILLed mid-stimulus, a forked helper alive", "forked"),
               ("stop() mid-stimulus, the player process frozen (SIGSTOP)", "frozen"),
               ("script suspended (Ctrl-Z) mid-stimulus", "suspended")], "reference")
        short = Path(folder) / "short_train.yaml"
        short.write_text(PROTOCOL.replace("duration_s: 10", "duration_s: 0.4"))
        rounds = [armed_after_stop(pinarray.load_protocol(short)) for _ in range(ROUNDS)]
        table("arm() of a 0.4 s stimulus lead_ns + 1 ms ahead, the call", "ms", rounds,
              [("on an array holding its pins, return delay 500 us (reference)", "held 500"),
               ("right after a stop(), return delay 500 us (factory)", "after a stop 500"),
               ("on an array holding its pins, return delay 0", "held 0"),
               ("right after a stop(), return delay 0 (servos return-delay)", "after a stop 0")],
              "held 500")
        ways = ("held 500", "after a stop 500", "held 0", "after a stop 0")
        print("started when due (Played): "
              + "; ".join(f"{way} {sum(r[f'{way} on time'] for r in rounds)} of {len(rounds)}"
                          for way in ways))
        table("open_array, until connected or refused", "s",
              [opened(protocol) for _ in range(ROUNDS)],
              [("all 16 servos answer (reference)", "all answer"),
               ("no servo answers (every id named)", "none answers")], "all answer")


if __name__ == "__main__":
    run()
