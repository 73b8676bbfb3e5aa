"""End to end: simulated servos on a pseudo-terminal, driven like real hardware via pyserial."""

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import serial

from pinarray.clock import MonotonicClock
from pinarray.hardware.feetech.faults import SimConfig, parse_sim_url
from pinarray.hardware.feetech.registers import BROADCAST_ID, Instruction
from pinarray.hardware.feetech.serve import PtyServer
from pinarray.hardware.feetech.transport import open_bus
from pinarray.player.playback import play_trial
from pinarray.stop import StopRequest, stop_on_signals

from .lab import SignalFromAnotherThread, assert_safe, device_setup, pulse_train
from .raw import packet

# Pseudo-terminals, player processes or the wall clock: run apart from the CPU-bound tests
# (tests/suite.py), so that a busy machine does not starve the simulated servos.
pytestmark = pytest.mark.realtime


def test_a_raw_pyserial_ping_gets_a_status_packet_back():
    server = PtyServer(SimConfig(ids=(1,))).start()
    try:
        with serial.Serial(server.path, 1_000_000, timeout=2) as port:
            port.write(bytes([0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]))
            assert port.read(6) == bytes([0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC])
    finally:
        server.stop()


def test_play_over_the_pseudo_terminal_ends_with_pins_at_rest():
    server = PtyServer(SimConfig(ids=tuple(range(1, 5)))).start()
    try:
        clock = MonotonicClock()
        bus = open_bus(server.path, device_setup(range(1, 5)), clock)
        report = play_trial(bus, pulse_train([1, 2, 3, 4], 10, 3), clock)
        bus.close()
    finally:
        server.stop()
    assert report.frames_sent == 6
    assert report.safe_stop.complete
    bus.sim = server.sim  # the servos live in the server
    assert_safe(bus)


# How long a stopped sim-serve may take to end: a bound against a hang, not a timing claim
# (it ends in milliseconds; a CI machine with the whole suite beside it once took over 10 s).
STOP_BOUND_S = 60


@contextmanager
def sim_serve(*args: str) -> Iterator[tuple[subprocess.Popen, str]]:
    """``pinarray sim-serve ARGS`` in its own process: (process, pseudo-terminal path)."""
    blocked_here = signal.pthread_sigmask(signal.SIG_BLOCK, [])  # what the child inherits
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", *args],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    process.blocked_by_parent = sorted(signal.Signals(number).name for number in blocked_here)
    try:
        yield process, process.stdout.readline().split(" on ")[1].split()[0]
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=STOP_BOUND_S)


def ended(process: subprocess.Popen) -> int:
    """``process``'s exit status once it has ended after a stop signal; a failure naming the
    signals it blocks, ignores and catches (and where it waits) if it has not within the bound.

    (In about 1 of 10 full runs a sim-serve did not end within 60 s of SIGTERM or SIGINT, never
    alone: the message says whether the signal was held back by the process or never sent.)"""
    try:
        return process.wait(timeout=STOP_BOUND_S)
    except subprocess.TimeoutExpired:
        seen = [f"test process blocked {process.blocked_by_parent} at the start"]
        for name in ("status", "wchan"):
            try:
                text = Path(f"/proc/{process.pid}/{name}").read_text()
            except OSError as error:
                text = str(error)
            seen += [line for line in text.splitlines()
                     if name == "wchan" or line.startswith(("SigPnd", "ShdPnd", "SigBlk",
                                                           "SigIgn", "SigCgt", "State"))]
        pytest.fail(f"sim-serve still running {STOP_BOUND_S} s after its stop signal: "
                    + "; ".join(seen))


def test_sim_serve_prints_its_path_serves_a_scan_and_stops_on_sigterm():
    with sim_serve("--ids", "1-3") as (process, path):
        scan = subprocess.run(
            # 200 ms an id, not the pseudo-terminal's 10: a simulator starved of the processor
            # by a busy machine (load 5 here) answered one servo later than 10 and 40 ms.
            [sys.executable, "-m", "pinarray", "scan", "--port", path, "--ids", "1-4",
             "--timeout-ms", "200"],
            capture_output=True, text=True, timeout=60,
        )
        assert "3 servo(s) answered" in scan.stdout, scan.stdout + scan.stderr
        process.send_signal(signal.SIGTERM)
        assert ended(process) == 0


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_sim_serve_stops_cleanly_on_sigterm_sigint_and_sighup(signum):
    with sim_serve("--ids", "1") as (process, path):
        with serial.Serial(path, 1_000_000, timeout=2) as port:
            port.write(packet(1, Instruction.PING))
            assert port.read(6) == bytes.fromhex("ffff010200fc")
        process.send_signal(signum)
        assert ended(process) == 0
        assert "sim-serve stopped" in process.stdout.read()


def test_sim_serve_ignores_a_read_longer_than_a_packet_and_keeps_serving():
    with sim_serve("--ids", "1-2") as (process, path):
        with serial.Serial(path, 1_000_000, timeout=0.2) as port:
            port.write(packet(1, Instruction.READ, bytes([0, 255])))
            port.write(packet(BROADCAST_ID, Instruction.SYNC_READ, bytes([0, 254, 1, 2])))
            assert port.read(300) == b""  # no answer to what no servo can send
            port.timeout = 5
            port.write(packet(1, Instruction.PING))
            assert port.read(6) == bytes.fromhex("ffff010200fc")
            port.write(packet(2, Instruction.READ, bytes([3, 2])))  # model number
            assert port.read(8) == bytes.fromhex("ffff0204000903ed")
        assert process.poll() is None  # still serving
        process.send_signal(signal.SIGTERM)
        assert ended(process) == 0


def test_sim_serve_logs_the_arrival_of_every_instruction_packet(tmp_path):
    log = tmp_path / "arrivals.tsv"
    with sim_serve("--ids", "1-2", "--arrivals", str(log)) as (process, path):
        with serial.Serial(path, 1_000_000, timeout=2) as port:
            before_ns = time.monotonic_ns()
            port.write(packet(1, Instruction.PING))
            port.read(6)
            goals = bytes([42, 2, 1, 0x34, 0x08, 2, 0xD0, 0x07])  # servo 1: 2100, 2: 2000
            port.write(packet(BROADCAST_ID, Instruction.SYNC_WRITE, goals))
            port.write(packet(2, Instruction.READ, bytes([56, 2])))
            port.read(8)
            after_ns = time.monotonic_ns()
        process.send_signal(signal.SIGTERM)
        assert ended(process) == 0
    header, *rows = [line.split("\t") for line in log.read_text().splitlines()]
    assert header == ["arrival_ns", "servo_id", "instruction", "address", "data_hex", "delivered"]
    assert [row[1:] for row in rows] == [
        ["1", "PING", "", "", "1"],
        ["254", "SYNC_WRITE", "42", "0201340802d007", "1"],
        ["2", "READ", "56", "02", "1"],
    ]
    arrivals = [int(row[0]) for row in rows]
    assert before_ns <= arrivals[0] <= arrivals[1] <= arrivals[2] <= after_ns


def test_a_lost_write_is_logged_as_not_delivered():
    server = PtyServer(parse_sim_url("sim://?ids=1&drop_writes=1"), record_arrivals=True).start()
    try:
        with serial.Serial(server.path, 1_000_000, timeout=0.2) as port:
            port.write(packet(1, Instruction.WRITE, bytes([40, 1])))
            assert port.read(6) == b""  # a lost write gets no answer
            port.write(packet(1, Instruction.READ, bytes([40, 1])))
            assert port.read(7) == bytes.fromhex("ffff01030000fb")  # torque still 0
    finally:
        server.stop()
    assert [(a.instruction, a.delivered) for a in server.arrivals] == [(3, False), (2, True)]


def test_answers_never_come_before_the_wire_and_return_delays_allow():
    # 24-byte sync read, then 16 answers of 8 bytes, each after a 500 us return delay.
    server = PtyServer(SimConfig(ids=tuple(range(1, 17)))).start()
    try:
        with serial.Serial(server.path, 1_000_000, timeout=2) as port:
            request = packet(BROADCAST_ID, Instruction.SYNC_READ, bytes([56, 2, *range(1, 17)]))
            sent_ns = time.monotonic_ns()
            port.write(request)
            answers = port.read(16 * 8)
            elapsed_ns = time.monotonic_ns() - sent_ns
    finally:
        server.stop()
    assert len(answers) == 128
    assert elapsed_ns >= (24 + 16 * 8) * 10_000 + 16 * 500_000


def test_a_client_at_another_speed_than_the_servos_gets_no_answer():
    server = PtyServer(SimConfig(ids=(1,))).start()
    try:
        with serial.Serial(server.path, 115_200, timeout=0.2) as port:
            port.write(packet(1, Instruction.PING))
            assert port.read(6) == b""
            port.baudrate = 1_000_000
            port.write(packet(1, Instruction.PING))
            assert port.read(6) == bytes.fromhex("ffff010200fc")
    finally:
        server.stop()


def test_a_late_answer_arrives_after_late_ms_on_the_pseudo_terminal():
    server = PtyServer(parse_sim_url("sim://?ids=1&late=1&late_ms=300")).start()
    try:
        with serial.Serial(server.path, 1_000_000, timeout=0.05) as port:
            port.write(packet(1, Instruction.PING))
            assert port.read(6) == b""  # not within a host's usual timeout
            port.timeout = 5
            assert port.read(6) == bytes.fromhex("ffff010200fc")
    finally:
        server.stop()


def test_a_stop_signal_taken_by_another_thread_stops_a_server_waiting_for_bytes():
    # The kernel may give a process's signal to any of its threads, and Python runs the
    # handler only when its main thread next runs: a server blocked waiting for bytes (as
    # `sim-serve` is, between packets) must still wake. (A sim-serve once stayed up 60 s after
    # SIGTERM, its handler installed, nothing blocked, nothing pending.) Here the signal goes
    # to a thread of this process that is not the main one, while the server waits.
    server = PtyServer(SimConfig(ids=(1,)))
    with stop_on_signals(StopRequest()) as stop:
        stop.when_requested(server.request_stop)
        with SignalFromAnotherThread(server.request_stop) as signalled:
            server.serve_forever()
    assert stop.requested and "SIGTERM" in stop.reason
    assert not signalled.slept_through, "the server slept through the signal until stopped otherwise"
